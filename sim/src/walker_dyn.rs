//! walker-dyn, the family's declaration: the planar walker (`planar.rs`, on either plant
//! through `legged.rs`) under randomised body dynamics ([`WalkerDynamics`]).

use crate::dynamics::WalkerDynamics;
use crate::kinds::Task;
use crate::spec::{EvalDefaults, FamilySpec, LEGGED_ACCEL_STD, RunView, seed_of};
use crate::task::MetricKind;
use crate::task::{WALKER_NOMINAL_SEED, WALKER_TEST_SEED_BASE, WALKER_TRAIN_SEED_BASE};

/// walker-dyn: 50 train and 25 test dynamics seeds; one demo per context, one rollout.
pub(crate) const SPEC: FamilySpec = FamilySpec {
    name: "walker-dyn",
    obs_dim: crate::planar::OBS_DIM,
    act_dim: crate::planar::ACT_DIM,
    task_dim: WalkerDynamics::VECTOR_DIM,
    metric: MetricKind::Return,
    value_name: "dynamics seed",
    value_tolerance: 0.0,
    value_key: "dynamics_seed",
    value_decimals: 0,
    write_parameter: |task, out| {
        let dynamics = task.walker_dynamics();
        dynamics
            .unwrap_or_else(WalkerDynamics::nominal)
            .write_log_factors(out)
    },
    train_tasks: || {
        (0..50)
            .map(|i| Task::walker_dyn(WALKER_TRAIN_SEED_BASE + i))
            .collect()
    },
    test_tasks: || {
        (0..25)
            .map(|i| Task::walker_dyn(WALKER_TEST_SEED_BASE + i))
            .collect()
    },
    task_from_value: |v| {
        seed_of(v)
            .map(Task::walker_dyn)
            .ok_or("a dynamics seed must be a non-negative integer")
    },
    nominal_task: Some(Task::WalkerDyn {
        dynamics_seed: WALKER_NOMINAL_SEED,
    }),
    obs_components: &crate::planar::OBS_COMPONENTS,
    eval: EvalDefaults {
        context_sizes: &[1],
        draws: 3,
        rollouts: 1,
        falls_end_episodes: true,
    },
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::Velocity { target: false },
    make_env: |config| Ok(Box::new(crate::legged::PlanarLeggedEnv::walker(config)?)),
};
