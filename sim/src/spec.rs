//! What a family's declaration holds ([`FamilySpec`]: tasks and splits, observation, metric,
//! evaluation and device defaults, the environment's constructor) and the helpers families
//! share (the goal families' angles, seeds from numbers). Each family declares its own spec in
//! its module (`point_goal.rs`, `cheetah_vel.rs`, `walker_dyn.rs`, `ant_goal.rs`,
//! `ant_linclass.rs`); `families.rs` is the one list that maps a [`crate::Family`] to it, and
//! every other crate reads the fields instead of matching on family names.

use std::f32::consts::PI;

use crate::env::{EnvConfig, Environment};
use crate::error::SimError;
use crate::kinds::Task;
use crate::sensing::ObsComponent;
use crate::task::MetricKind;

/// What the workspace knows about one family. Plain data and plain functions: read a field,
/// never match on the family. A family's module writes it as one struct literal, every field
/// named (the five built in, as `cheetah_vel.rs`, and a family of another crate alike), and
/// [`Family::of`](crate::Family::of) makes it a family.
#[derive(Debug)]
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
    /// The value of a task outside both splits that the family's normalised metric refers to
    /// (walker-dyn's unmodified walker, [`crate::Family::nominal_task`]); `None` where the
    /// family has no such metric.
    pub nominal_value: Option<f64>,
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
pub(crate) fn goal_train_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TRAIN).map(|k| k as f32 * PI / 16.0)
}

/// Goal angles of the meta-test split: 2n pi/16 + pi/32.
pub(crate) fn goal_test_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TEST).map(|n| 2.0 * n as f32 * PI / 16.0 + PI / 32.0)
}

/// The goal families' task parameter: the goal's (x, y).
pub(crate) fn write_goal(task: &Task, out: &mut [f32]) {
    out.copy_from_slice(&task.goal().unwrap_or_default());
}

/// A seed from a number: a non-negative integer within `u32`.
pub(crate) fn seed_of(value: f64) -> Option<u64> {
    (value >= 0.0 && value.fract() == 0.0 && value <= u32::MAX as f64).then_some(value as u64)
}

/// The legged robots' filter default: joints accelerate fast.
pub(crate) const LEGGED_ACCEL_STD: f32 = 50.0;
