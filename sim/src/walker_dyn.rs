//! walker-dyn, the family's declaration: the planar walker (`planar.rs`, on either plant
//! through `legged.rs`) under randomised body dynamics ([`WalkerDynamics`]).

use crate::dynamics::WalkerDynamics;
use crate::family::{EvalDefaults, Family, FamilySpec, MetricKind, RunView, Task};
use crate::spec::{LEGGED_ACCEL_STD, seed_of};
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
    nominal_value: Some(WALKER_NOMINAL_SEED as f64),
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

impl Family {
    /// walker-dyn, declared by this module's `SPEC`.
    pub const WALKER_DYN: Family = Family::of(&SPEC);
}

impl Task {
    /// A walker-dyn task whose dynamics are drawn from `dynamics_seed` (except the reserved
    /// [`WALKER_NOMINAL_SEED`], the unmodified robot).
    pub fn walker_dyn(dynamics_seed: u64) -> Task {
        Task::new(Family::WALKER_DYN, dynamics_seed as f64)
    }

    /// The walker-dyn task with the unmodified dynamics (seed [`WALKER_NOMINAL_SEED`]); in
    /// neither split.
    pub fn walker_nominal() -> Task {
        Task::walker_dyn(WALKER_NOMINAL_SEED)
    }

    /// The dynamics of a walker-dyn task (`None` for other families): the one place a seed
    /// becomes factors, so the environment and the task parameter always agree.
    pub fn walker_dynamics(&self) -> Option<WalkerDynamics> {
        if self.family() != Family::WALKER_DYN {
            return None;
        }
        Some(match self.value() as u64 {
            WALKER_NOMINAL_SEED => WalkerDynamics::nominal(),
            dynamics_seed => WalkerDynamics::from_seed(dynamics_seed),
        })
    }
}
