//! cheetah-vel, the family's declaration: the planar cheetah (`planar.rs`, on either plant
//! through `legged.rs`) running at a target forward velocity.

use crate::family::{EvalDefaults, Family, FamilySpec, MetricKind, RunView, Task};
use crate::spec::LEGGED_ACCEL_STD;
use crate::task::TASK_VALUE_TOLERANCE;

/// cheetah-vel: 31 train velocities 0..=3 by 0.1, 30 test velocities 0.05..=2.95; Table 1's
/// protocol (context sizes 1-4).
pub(crate) const SPEC: FamilySpec = FamilySpec {
    name: "cheetah-vel",
    obs_dim: crate::planar::OBS_DIM,
    act_dim: crate::planar::ACT_DIM,
    task_dim: 1,
    metric: MetricKind::MeanVelocityError,
    value_name: "target velocity (m/s)",
    value_tolerance: TASK_VALUE_TOLERANCE,
    value_key: "target_velocity",
    value_decimals: 2,
    write_parameter: |task, out| out[0] = task.value() as f32,
    train_tasks: || {
        (0..=30)
            .map(|k| Task::cheetah_vel(k as f32 * 0.1))
            .collect()
    },
    test_tasks: || {
        (0..30)
            .map(|k| Task::cheetah_vel(0.05 + k as f32 * 0.1))
            .collect()
    },
    task_from_value: |v| Ok(Task::cheetah_vel(v as f32)),
    nominal_value: None,
    obs_components: &crate::planar::OBS_COMPONENTS,
    eval: EvalDefaults {
        context_sizes: &[1, 2, 3, 4],
        draws: 3,
        rollouts: 5,
        falls_end_episodes: false,
    },
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::Velocity { target: true },
    make_env: |config| Ok(Box::new(crate::legged::PlanarLeggedEnv::cheetah(config)?)),
};

impl Family {
    /// cheetah-vel, declared by this module's `SPEC`.
    pub const CHEETAH_VEL: Family = Family::of(&SPEC);
}

impl Task {
    /// A cheetah-vel task with target velocity `target_velocity` m/s.
    pub fn cheetah_vel(target_velocity: f32) -> Task {
        Task::new(Family::CHEETAH_VEL, target_velocity as f64)
    }

    /// The target velocity of a cheetah-vel task, m/s (`None` for other families).
    pub fn target_velocity(&self) -> Option<f32> {
        (self.family() == Family::CHEETAH_VEL).then_some(self.value() as f32)
    }
}
