//! The environment interface shared by every family, and the per-episode metric.

use crate::error::SimError;
use crate::kinds::Family;
use crate::kinds::Physics;
use crate::kinds::Task;
use crate::render::Frame;
use crate::task::MetricKind;

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

/// The latched classification decision of an ant-linclass episode, as the per-step metric
/// sample encodes it (and [`EpisodeMetric`] decodes it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Neither target reached yet (sample 0).
    Undecided,
    /// The correct target was reached first (sample 1).
    Correct,
    /// The wrong target was reached first (sample -1).
    Wrong,
}

impl Decision {
    /// The metric sample of this decision: 0, 1 or -1.
    pub fn sample(self) -> f32 {
        match self {
            Decision::Undecided => 0.0,
            Decision::Correct => 1.0,
            Decision::Wrong => -1.0,
        }
    }

    /// The decision a metric sample encodes (anything but 1 and -1 is undecided).
    pub fn from_sample(sample: f32) -> Self {
        if sample == 1.0 {
            Decision::Correct
        } else if sample == -1.0 {
            Decision::Wrong
        } else {
            Decision::Undecided
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

/// Builds an environment of `family` on `config.physics`, reset to the family's first train
/// task. Errors if the backend is not in this build ([`SimError::PhysicsUnavailable`]) or the
/// family has no robot on it (point-goal is Rapier's only).
pub fn make_env(family: Family, config: EnvConfig) -> Result<Box<dyn Environment>, SimError> {
    if config.horizon == Some(0) {
        return Err(SimError::ZeroHorizon);
    }
    (family.spec().make_env)(config)
}

/// Accumulates a family's per-episode metric from the `StepInfo`s of an episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeMetric {
    kind: MetricKind,
    min: f32,
    sum: f64,
    last: f32,
    steps: usize,
}

impl EpisodeMetric {
    /// An empty accumulator for `family`'s metric.
    pub fn new(family: Family) -> Self {
        Self {
            kind: family.metric_kind(),
            min: f32::INFINITY,
            sum: 0.0,
            last: 0.0,
            steps: 0,
        }
    }

    /// Adds one step.
    pub fn record(&mut self, info: &StepInfo) {
        self.min = self.min.min(info.metric_sample);
        self.sum += info.metric_sample as f64;
        self.last = info.metric_sample;
        self.steps += 1;
    }

    /// Which metric this is.
    pub fn kind(&self) -> MetricKind {
        self.kind
    }

    /// The metric so far: min distance, mean |v - v*|, return, or classification success (NaN
    /// before any step, except 0 for the return).
    pub fn value(&self) -> f32 {
        match self.kind {
            MetricKind::MinGoalDistance if self.steps == 0 => f32::NAN,
            MetricKind::MinGoalDistance => self.min,
            MetricKind::MeanVelocityError if self.steps == 0 => f32::NAN,
            MetricKind::MeanVelocityError => (self.sum / self.steps as f64) as f32,
            MetricKind::Return => self.sum as f32,
            MetricKind::ClassificationSuccess if self.steps == 0 => f32::NAN,
            MetricKind::ClassificationSuccess => match Decision::from_sample(self.last) {
                Decision::Correct => 1.0,
                _ => 0.0,
            },
        }
    }

    /// For a classification metric, whether the episode so far made no decision (a no-op);
    /// `None` for the other metrics and before any step.
    pub fn no_op(&self) -> Option<bool> {
        (self.kind == MetricKind::ClassificationSuccess && self.steps > 0)
            .then(|| Decision::from_sample(self.last) == Decision::Undecided)
    }
}

/// Checks an action's length and finiteness and writes its [-1, 1] clip into `clipped`.
pub(crate) fn clip_action(
    family: Family,
    action: &[f32],
    clipped: &mut [f32],
) -> Result<(), SimError> {
    if action.len() != clipped.len() {
        return Err(SimError::ActionLength {
            family,
            expected: clipped.len(),
            got: action.len(),
        });
    }
    for (index, (&value, out)) in action.iter().zip(clipped.iter_mut()).enumerate() {
        if !value.is_finite() {
            return Err(SimError::NonFiniteAction { index, value });
        }
        *out = value.clamp(-1.0, 1.0);
    }
    Ok(())
}

/// Step counting shared by the environments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct EpisodeClock {
    pub step: usize,
    pub horizon: usize,
    pub over: bool,
}

impl EpisodeClock {
    pub fn new(horizon: usize) -> Self {
        Self {
            step: 0,
            horizon: horizon.max(1),
            over: false,
        }
    }

    pub fn restart(&mut self) {
        self.step = 0;
        self.over = false;
    }

    /// Errors if the episode is already over.
    pub fn ensure_running(&self) -> Result<(), SimError> {
        if self.over {
            Err(SimError::EpisodeOver { step: self.step })
        } else {
            Ok(())
        }
    }

    /// Counts a step; returns (terminated, truncated) and marks the episode over if either.
    pub fn advance(&mut self, terminated: bool) -> (bool, bool) {
        self.step += 1;
        let truncated = !terminated && self.step >= self.horizon;
        self.over = terminated || truncated;
        (terminated, truncated)
    }
}

/// Rejects a task of the wrong family.
pub(crate) fn check_family(env_family: Family, task: &Task) -> Result<(), SimError> {
    if task.family() == env_family {
        Ok(())
    } else {
        Err(SimError::TaskFamilyMismatch {
            env_family,
            task_family: task.family(),
        })
    }
}
