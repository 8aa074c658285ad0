//! A family's interface, everything that names everything else: the family's declaration
//! ([`FamilySpec`]), its handle ([`Family`]), its tasks ([`Task`]) and metric
//! ([`MetricKind`]), and the environment it builds ([`Environment`], with [`EnvConfig`] and what
//! a step reports). These types refer to one another (a family's declaration builds its
//! environment, which names its family and task), so they live in one module, below every
//! family and above only the error type, the physics backend, the sensing table and the
//! drawing. Their methods live with what they read: `task.rs` (tasks, splits, names),
//! `families.rs` (the built-in list and the registry), each family's module (its constant and
//! its tasks' constructors), `env.rs` (building an environment, the episode's metric).

use std::fmt;
use std::hash::{Hash, Hasher};

use crate::error::SimError;
use crate::kinds::Physics;
use crate::render::Frame;
use crate::sensing::ObsComponent;

/// A family of tasks sharing one robot: a handle on its declaration, the [`FamilySpec`] its
/// module writes (everything the workspace knows about it: tasks and splits, observation,
/// metric, evaluation, the environment's constructor).
///
/// The families are open, as Gymnasium's `register` makes environments: the five of the paper
/// are constants in their modules ([`Family::POINT_GOAL`], [`Family::CHEETAH_VEL`],
/// [`Family::WALKER_DYN`], [`Family::ANT_GOAL`], [`Family::ANT_LINCLASS`]; the CLI names are
/// `point-goal`, `cheetah-vel`, `walker-dyn`, `ant-goal`, `ant-linclass`), and a crate outside
/// this one declares its own with [`Family::of`] and one [`Family::register`] call, after which
/// configurations, datasets and policy files name it like any other. Two handles are the same
/// family when their names are (the registry keeps names unique). The default is point-goal,
/// the toy every learner's configuration starts from.
#[derive(Clone, Copy)]
pub struct Family {
    spec: &'static FamilySpec,
}

impl Family {
    /// The family `spec` declares. Files and flags name it once it is registered
    /// ([`Family::register`]); the built-in families always are.
    pub const fn of(spec: &'static FamilySpec) -> Family {
        Family { spec }
    }

    /// The family's declaration: everything the workspace knows about it ([`FamilySpec`]).
    /// Everything else reads its fields instead of matching on family names.
    pub fn spec(self) -> &'static FamilySpec {
        self.spec
    }
}

impl PartialEq for Family {
    fn eq(&self, other: &Family) -> bool {
        self.spec.name == other.spec.name
    }
}

impl Eq for Family {}

impl Hash for Family {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.spec.name.hash(state)
    }
}

impl fmt::Debug for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.spec.name)
    }
}

impl Default for Family {
    fn default() -> Family {
        Family::POINT_GOAL
    }
}

/// One task: the hidden parameter the learner must infer from demonstrations, one number of
/// its family (a goal angle, a target velocity, a dynamics or hyperplane seed). Each family's
/// module has its constructors ([`Task::cheetah_vel`], ...); [`Family::task_from_value`]
/// checks a number from a user or a file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Task {
    family: Family,
    value: f64,
}

impl Task {
    /// The task of `family` whose parameter is `value`, unchecked: what a family's own
    /// constructors and `task_from_value` build on (a seed is an integer in `f64`, exact up to
    /// 2^53; a velocity or angle an `f32` widened, exact).
    pub const fn new(family: Family, value: f64) -> Task {
        Task { family, value }
    }

    /// The family this task belongs to.
    pub fn family(&self) -> Family {
        self.family
    }

    /// The single number naming this task: goal angle, target velocity or seed.
    /// `family.task_from_value(task.value())` gives the task back.
    pub fn value(&self) -> f64 {
        self.value
    }
}

/// How a family's per-episode metric aggregates the per-step samples in [`crate::StepInfo`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MetricKind {
    /// Minimum distance to the goal over the episode (lower is better).
    MinGoalDistance,
    /// Mean over the episode of |v - v*| (lower is better).
    MeanVelocityError,
    /// Sum of rewards (higher is better).
    Return,
    /// 1 if the episode's classification decision was correct, else 0 (higher is better); the
    /// per-step sample is the latched [`crate::ant_linclass::Decision`], and
    /// [`crate::EpisodeMetric::no_op`] tells whether no decision was made.
    ClassificationSuccess,
}

impl MetricKind {
    /// Whether a smaller value is better (distances and errors) or a larger one (return,
    /// success).
    pub fn lower_is_better(self) -> bool {
        match self {
            MetricKind::MinGoalDistance | MetricKind::MeanVelocityError => true,
            MetricKind::Return | MetricKind::ClassificationSuccess => false,
        }
    }
}

/// What the workspace knows about one family. Plain data and plain functions: read a field,
/// never match on the family. A family's module writes it as one struct literal, every field
/// named (the five built in, as `cheetah_vel.rs`, and a family of another crate alike; a
/// family whose tasks are another's takes those fields from the other's, as ant-goal takes
/// point-goal's goals), and
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

/// Options of an environment: its episode, and which physics backend simulates it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvConfig {
    /// Episode length in control steps; `None` uses the family's default (100 or 1000).
    pub horizon: Option<usize>,
    /// walker-dyn only: end the episode when the walker falls (torso too low or tilted).
    pub healthy_termination: bool,
    /// The physics backend (default Rapier). point-goal exists on Rapier only.
    pub physics: Physics,
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            horizon: None,
            healthy_termination: true,
            physics: Physics::Rapier,
        }
    }
}

impl EnvConfig {
    /// Episodes of `horizon` steps (`None`: the family's) on `physics`, ending as the family
    /// ends them (a walker's fall among them).
    pub fn new(horizon: Option<usize>, physics: Physics) -> Self {
        Self {
            horizon,
            physics,
            ..Self::default()
        }
    }
}

/// What one control step reports besides observation, reward and done.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo {
    /// Number of control steps taken in this episode, this one included.
    pub step: usize,
    /// The episode ended because of the task (a fallen walker): do not bootstrap.
    pub terminated: bool,
    /// The episode ended because the horizon was reached.
    pub truncated: bool,
    /// This step's sample of the family's metric (see [`Family::metric_kind`]): distance to
    /// the goal, |v - v*|, or the reward.
    pub metric_sample: f32,
    /// Forward (x) velocity of the robot's torso after the step, m/s (0 for point-goal; the
    /// world-frame x velocity for ant-goal).
    pub forward_velocity: f32,
}

/// The result of one control step. `obs` borrows the environment's internal buffer: copy it
/// before stepping again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition<'a> {
    /// Observation after the step (never contains the task parameter).
    pub obs: &'a [f32],
    /// Reward of the step.
    pub reward: f32,
    /// The episode is over (terminated or truncated); `step` now returns an error.
    pub done: bool,
    /// Details, including the metric sample.
    pub info: StepInfo,
}

/// A simulated robot and its task. Every family implements it; a 3-D family does too.
///
/// Lifecycle: build (already reset to the family's first train task with seed 0), then
/// `reset(task, seed)`, then `step` until `done`. Same family, task, seed and actions give
/// bit-identical observations and rewards.
pub trait Environment: Send {
    /// The task family.
    fn family(&self) -> Family;
    /// The physics backend simulating it.
    fn physics(&self) -> Physics {
        Physics::Rapier
    }
    /// Learner-facing observation dimension.
    fn obs_dim(&self) -> usize {
        self.family().obs_dim()
    }
    /// Action dimension; actions are clipped to [-1, 1] per component.
    fn act_dim(&self) -> usize {
        self.family().act_dim()
    }
    /// Oracle observation dimension (observation followed by the task parameter).
    fn oracle_obs_dim(&self) -> usize {
        self.family().oracle_obs_dim()
    }
    /// Seconds of simulated time per control step.
    fn control_dt(&self) -> f32;
    /// Episode length in control steps.
    fn horizon(&self) -> usize;
    /// The current task.
    fn task(&self) -> &Task;
    /// Starts an episode of `task` with seeded initial-state noise; returns the observation.
    /// A task of another family, or whose value is not finite, is refused
    /// ([`Family::check_task`]).
    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError>;
    /// Applies one action (clipped to [-1, 1]) for one control step.
    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError>;
    /// The current observation.
    fn observation(&self) -> &[f32];
    /// Writes the oracle observation (observation, then task parameter) into `out`.
    fn oracle_observation(&self, out: &mut [f32]) -> Result<(), SimError> {
        let expected = self.oracle_obs_dim();
        if out.len() != expected {
            return Err(SimError::BufferLength {
                expected,
                got: out.len(),
            });
        }
        let (obs, task) = out.split_at_mut(self.obs_dim());
        obs.copy_from_slice(self.observation());
        self.task().write_parameter(task)
    }
    /// A drawable snapshot of the current state (top view or side view).
    fn frame(&self) -> Frame;
}
