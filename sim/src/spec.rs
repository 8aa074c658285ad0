//! One spec per family: everything the workspace knows about a family, in one declarative
//! block each (tasks and splits, observation, metric, evaluation and device defaults, the
//! environment's constructor). [`crate::Family::spec`] is the one place that maps a family to its
//! spec; every other crate reads the fields instead of matching on family names.
//!
//! Adding a family: its environment module, a [`crate::Family`] and a [`Task`] variant, a `const`
//! spec here and its arm in [`crate::Family::spec`] (ARCHITECTURE.md lists the files).

use std::f32::consts::PI;

use crate::ant_linclass as linclass;
use crate::dynamics::WalkerDynamics;
use crate::env::{EnvConfig, Environment};
use crate::error::SimError;
use crate::kinds::Family;
use crate::kinds::Physics;
use crate::sensing::ObsComponent;
use crate::sensing::{ANT, ANT_LINCLASS, PLANAR, POINT_GOAL};
use crate::task::{MetricKind, Task};
use crate::task::{WALKER_NOMINAL_SEED, WALKER_TEST_SEED_BASE, WALKER_TRAIN_SEED_BASE};

impl Family {
    /// The family's spec: everything the workspace knows about it ([`FamilySpec`]). The one
    /// place that maps a family to its data; everything else reads the spec's fields. It lives
    /// here, above the families' modules, so that `task.rs` imports none of them back.
    pub fn spec(self) -> &'static FamilySpec {
        match self {
            Family::PointGoal => &POINT_GOAL_SPEC,
            Family::CheetahVel => &CHEETAH_VEL_SPEC,
            Family::WalkerDyn => &WALKER_DYN_SPEC,
            Family::AntGoal => &ANT_GOAL_SPEC,
            Family::AntLinClass => &ANT_LINCLASS_SPEC,
        }
    }

    /// Per observation index, what the entry is: a measured position or angle, the rate of
    /// another entry, or a directly measured quantity. Its length is [`Family::obs_dim`].
    pub fn obs_components(self) -> &'static [ObsComponent] {
        self.spec().obs_components
    }
}

/// What the workspace knows about one family. Plain data and plain functions: read a field,
/// never match on the family.
#[derive(Debug)]
#[non_exhaustive]
pub struct FamilySpec {
    /// The CLI name (`cheetah-vel`, ...).
    pub name: &'static str,
    /// Width of the learner-facing observation.
    pub obs_dim: usize,
    /// Width of the action.
    pub act_dim: usize,
    /// Width of the task parameter appended to the oracle observation.
    pub task_dim: usize,
    /// The paper's evaluation metric.
    pub metric: MetricKind,
    /// What a task value is, for messages: `goal angle (rad)`, ...
    pub value_name: &'static str,
    /// The value's key in a task's label (`goal_angle` in `goal_angle=0.4909`).
    pub value_key: &'static str,
    /// Decimals a label prints the value with (0: a seed).
    pub value_decimals: usize,
    /// Writes a task's parameter vector (`task_dim` long; the caller checked the length),
    /// the oracle observation's tail.
    pub write_parameter: fn(&Task, &mut [f32]),
    /// How far a number may be from a task's value and still name it
    /// ([`crate::TASK_VALUE_TOLERANCE`] for continuous values, 0 for seeds).
    pub value_tolerance: f64,
    /// The meta-train tasks, exactly as in the reference.
    pub train_tasks: fn() -> Vec<Task>,
    /// The meta-test tasks, exactly as in the reference.
    pub test_tasks: fn() -> Vec<Task>,
    /// A task from one finite number (goal angle, velocity, seed); `Err` says why the number
    /// names none.
    pub task_from_value: fn(f64) -> Result<Task, &'static str>,
    /// A task outside both splits that the family's normalised metric refers to (walker-dyn's
    /// unmodified walker); `None` where the family has no such metric.
    pub nominal_task: Option<Task>,
    /// Per observation index, what the entry physically is (position-only sensing).
    pub obs_components: &'static [ObsComponent],
    /// The reference evaluation protocol (§5).
    pub eval: EvalDefaults,
    /// The device filter's default acceleration std (units/s^2), from the sweep in
    /// `docs/ESTIMATOR.md`.
    pub estimator_accel_std: f32,
    /// How a run of this family is drawn.
    pub view: RunView,
    /// Builds the environment on `config.physics`, reset to the first train task.
    pub make_env: fn(EnvConfig) -> Result<Box<dyn Environment>, SimError>,
}

/// A family's reference evaluation protocol: which context sizes, how many context draws per
/// size and rollouts per draw.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct EvalDefaults {
    /// Context sizes (demos per context) evaluated.
    pub context_sizes: &'static [usize],
    /// Context draws per (task, size).
    pub draws: usize,
    /// Rollouts per draw.
    pub rollouts: usize,
    /// Whether the robot can fall and a fall ends the episode (walker-dyn; the SMILe authors'
    /// evaluation runs through falls instead, `Protocol::run_through_falls` in the trainer).
    pub falls_end_episodes: bool,
}

/// How a run's plot shows what the task asked for. Not `#[non_exhaustive]`: a new kind of view
/// must fail to compile at the plots that draw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunView {
    /// The top-view path to the goal; the plant's (x, y) is at observation index `xy`.
    GoalPath {
        /// Index of x in the observation (y follows).
        xy: usize,
    },
    /// Forward velocity over time, against the task's value as the target where `target` is
    /// set.
    Velocity {
        /// Whether the task's value is the target velocity (cheetah-vel).
        target: bool,
    },
}

const GOAL_TRAIN: usize = 32;
const GOAL_TEST: usize = 16;

/// Goal angles of the meta-train split: k pi/16.
fn goal_train_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TRAIN).map(|k| k as f32 * PI / 16.0)
}

/// Goal angles of the meta-test split: 2n pi/16 + pi/32.
fn goal_test_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TEST).map(|n| 2.0 * n as f32 * PI / 16.0 + PI / 32.0)
}

/// The goal families' task parameter: the goal's (x, y).
fn write_goal(task: &Task, out: &mut [f32]) {
    out.copy_from_slice(&task.goal().unwrap_or_default());
}

/// A seed from a number: a non-negative integer within `u32`.
fn seed_of(value: f64) -> Option<u64> {
    (value >= 0.0 && value.fract() == 0.0 && value <= u32::MAX as f64).then_some(value as u64)
}

/// point-goal: 32 train goals at k pi/16, 16 test goals between them; Figure 2's protocol.
pub(crate) const POINT_GOAL_SPEC: FamilySpec = FamilySpec {
    name: "point-goal",
    obs_dim: crate::task::POINT_GOAL_OBS_DIM,
    act_dim: crate::task::POINT_GOAL_ACT_DIM,
    task_dim: 2,
    metric: MetricKind::MinGoalDistance,
    value_name: "goal angle (rad)",
    value_tolerance: crate::task::TASK_VALUE_TOLERANCE,
    value_key: "goal_angle",
    value_decimals: 4,
    write_parameter: write_goal,
    train_tasks: || goal_train_angles().map(Task::point_goal).collect(),
    test_tasks: || goal_test_angles().map(Task::point_goal).collect(),
    task_from_value: |v| Ok(Task::point_goal(v as f32)),
    nominal_task: None,
    obs_components: &POINT_GOAL,
    eval: EvalDefaults {
        context_sizes: &[1],
        draws: 3,
        rollouts: 10,
        falls_end_episodes: false,
    },
    estimator_accel_std: 2.0,
    view: RunView::GoalPath { xy: 0 },
    make_env: |config| {
        if config.physics != Physics::Rapier {
            return Err(SimError::PhysicsUnavailable {
                physics: config.physics,
                how: "point-goal is a Rapier point mass with no MuJoCo model; run it on Rapier"
                    .into(),
            });
        }
        Ok(Box::new(crate::point_goal::PointGoalEnv::new(config)))
    },
};

/// The legged robots' filter default: joints accelerate fast.
const LEGGED_ACCEL_STD: f32 = 50.0;

/// cheetah-vel: 31 train velocities 0..=3 by 0.1, 30 test velocities 0.05..=2.95; Table 1's
/// protocol (context sizes 1-4).
pub(crate) const CHEETAH_VEL_SPEC: FamilySpec = FamilySpec {
    name: "cheetah-vel",
    obs_dim: crate::planar::OBS_DIM,
    act_dim: crate::planar::ACT_DIM,
    task_dim: 1,
    metric: MetricKind::MeanVelocityError,
    value_name: "target velocity (m/s)",
    value_tolerance: crate::task::TASK_VALUE_TOLERANCE,
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
    nominal_task: None,
    obs_components: &PLANAR,
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

/// walker-dyn: 50 train and 25 test dynamics seeds; one demo per context, one rollout.
pub(crate) const WALKER_DYN_SPEC: FamilySpec = FamilySpec {
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
    obs_components: &PLANAR,
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

/// ant-goal: point-goal's goals for the 3-D ant; Figure 2's protocol.
pub(crate) const ANT_GOAL_SPEC: FamilySpec = FamilySpec {
    name: "ant-goal",
    obs_dim: crate::ant::OBS_DIM,
    act_dim: crate::ant::ACT_DIM,
    task_dim: 2,
    metric: MetricKind::MinGoalDistance,
    value_name: "goal angle (rad)",
    value_tolerance: crate::task::TASK_VALUE_TOLERANCE,
    value_key: "goal_angle",
    value_decimals: 4,
    write_parameter: write_goal,
    train_tasks: || goal_train_angles().map(Task::ant_goal).collect(),
    test_tasks: || goal_test_angles().map(Task::ant_goal).collect(),
    task_from_value: |v| Ok(Task::ant_goal(v as f32)),
    nominal_task: None,
    obs_components: &ANT,
    eval: EvalDefaults {
        context_sizes: &[1],
        draws: 3,
        rollouts: 10,
        falls_end_episodes: false,
    },
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::GoalPath {
        xy: crate::ant::obs::XY,
    },
    make_env: |config| Ok(Box::new(crate::ant_goal::AntGoalEnv::new(config)?)),
};

/// ant-linclass: 64 train and 32 test hyperplane seeds; aggregating demos is what this family
/// tests, so the success is read per context size (1, 2, 4, 8).
pub(crate) const ANT_LINCLASS_SPEC: FamilySpec = FamilySpec {
    name: "ant-linclass",
    obs_dim: linclass::OBS_DIM,
    act_dim: crate::ant::ACT_DIM,
    task_dim: linclass::POINT_DIM,
    metric: MetricKind::ClassificationSuccess,
    value_name: "hyperplane seed",
    value_tolerance: 0.0,
    value_key: "hyperplane_seed",
    value_decimals: 0,
    write_parameter: |task, out| out.copy_from_slice(&task.linclass_normal().unwrap_or_default()),
    train_tasks: || {
        (0..linclass::TRAIN_TASKS)
            .map(|i| Task::ant_linclass(linclass::TRAIN_SEED_BASE + i))
            .collect()
    },
    test_tasks: || {
        (0..linclass::TEST_TASKS)
            .map(|i| Task::ant_linclass(linclass::TEST_SEED_BASE + i))
            .collect()
    },
    task_from_value: |v| {
        seed_of(v)
            .map(Task::ant_linclass)
            .ok_or("a hyperplane seed must be a non-negative integer")
    },
    nominal_task: None,
    obs_components: &ANT_LINCLASS,
    eval: EvalDefaults {
        context_sizes: &[1, 2, 4, 8],
        draws: 3,
        rollouts: 5,
        falls_end_episodes: false,
    },
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::Velocity { target: false },
    make_env: |config| Ok(Box::new(crate::ant_linclass::AntLinClassEnv::new(config)?)),
};
