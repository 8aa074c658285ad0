//! Building a family's environment, the per-episode metric, and the helpers the built-in
//! environments share (the interface itself, [`Environment`], is in `family.rs`).

use crate::error::SimError;
use crate::family::{EnvConfig, Environment, Family, MetricKind, StepInfo, Transition};

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
            family: family.name(),
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

    /// Counts a step ([`Self::advance`]) and reports it: `obs` after it, its `reward`, whether
    /// the task `terminated` it, the family's `metric_sample` and the torso's
    /// `forward_velocity`.
    pub fn transition<'a>(
        &mut self,
        obs: &'a [f32],
        reward: f32,
        terminated: bool,
        metric_sample: f32,
        forward_velocity: f32,
    ) -> Transition<'a> {
        let (terminated, truncated) = self.advance(terminated);
        Transition {
            obs,
            reward,
            done: terminated || truncated,
            info: StepInfo {
                step: self.step,
                terminated,
                truncated,
                metric_sample,
                forward_velocity,
            },
        }
    }
}
