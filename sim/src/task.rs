//! Task families, their tasks and the paper's meta-train / meta-test splits.

use std::fmt;
use std::str::FromStr;

use crate::error::SimError;
use crate::family::{Family, MetricKind, Task};

/// Point-goal's observation width, `[x, y, vx, vy]` (the env, `point_goal.rs`, reads it here).
pub(crate) const POINT_GOAL_OBS_DIM: usize = 4;
/// Point-goal's action width, a force along x and y.
pub(crate) const POINT_GOAL_ACT_DIM: usize = 2;

/// Meta-train or meta-test half of a family's task list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Split {
    /// Tasks the meta-learner trains on.
    Train,
    /// Held-out tasks used for evaluation.
    Test,
}

/// Walker dynamics seeds of the meta-train split are `WALKER_TRAIN_SEED_BASE + i`, i in 0..50.
pub const WALKER_TRAIN_SEED_BASE: u64 = 0;
/// Walker dynamics seeds of the meta-test split are `WALKER_TEST_SEED_BASE + i`, i in 0..25.
pub const WALKER_TEST_SEED_BASE: u64 = 10_000;
/// The dynamics seed reserved for the *unmodified* walker: `Task::walker_dyn(WALKER_NOMINAL_SEED)`
/// (also [`Task::walker_nominal`]) has every factor 1 ([`crate::WalkerDynamics::nominal`]), so its
/// task parameter is all zeros. It is `u32::MAX`, the largest seed
/// [`Family::task_from_value`] accepts, far outside both splits' seed ranges; the walker-dyn
/// normalised metric's "base" policy is trained on it (`smile expert --env walker-dyn --nominal`).
/// A seed rather than a new [`Task`] variant, so every path that names a task by its value
/// (CLI `--task-value`, datasets, policy files) handles it unchanged.
pub const WALKER_NOMINAL_SEED: u64 = u32::MAX as u64;

/// How far (in the value's unit) a number may be from a task's value and still name that task,
/// for the families with a continuous parameter: 1e-3 rad for point-goal and ant-goal goal
/// angles and 1e-3 m/s for cheetah-vel target velocities ([`Family::value_tolerance`]; walker-dyn seeds are
/// integers and match exactly). Labels print 4 decimals for angles and 2 for velocities, so the
/// number read off a label (`goal_angle=0.4909` for 0.490874 rad) names its task, while the
/// closest two tasks of a family, train and test lists together, are 0.05 apart: no number
/// names two tasks.
pub const TASK_VALUE_TOLERANCE: f64 = 1e-3;

impl Family {
    /// The CLI name of the family.
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// The family's tasks of one split, exactly as in the reference.
    pub fn tasks(self, split: Split) -> Vec<Task> {
        match split {
            Split::Train => self.train_tasks(),
            Split::Test => self.test_tasks(),
        }
    }

    /// Meta-train tasks: 32 goals at k*pi/16 (point-goal, ant-goal); 31 velocities 0.0..=3.0
    /// step 0.1; 50 dynamics seeds; 64 hyperplane seeds.
    pub fn train_tasks(self) -> Vec<Task> {
        (self.spec().train_tasks)()
    }

    /// Meta-test tasks: 16 goals at 2n*pi/16 + pi/32 (point-goal, ant-goal); 30 velocities
    /// 0.05..=2.95 step 0.1; 25 dynamics seeds; 32 hyperplane seeds.
    pub fn test_tasks(self) -> Vec<Task> {
        (self.spec().test_tasks)()
    }

    /// A task of this family from one explicit number: goal angle (radians), target velocity
    /// (m/s), dynamics or hyperplane seed (a non-negative integer).
    pub fn task_from_value(self, value: f64) -> Result<Task, SimError> {
        let invalid = |reason: &str| SimError::InvalidTask {
            family: self.name(),
            reason: reason.to_string(),
        };
        if !value.is_finite() {
            return Err(invalid("not finite"));
        }
        (self.spec().task_from_value)(value).map_err(invalid)
    }

    /// What an environment's `reset` checks first: `task` is of this family and its value is
    /// finite (`Task::new` takes any number; a NaN goal or velocity would poison every
    /// reward). A family of your own calls it too.
    pub fn check_task(self, task: &Task) -> Result<(), SimError> {
        if task.family() != self {
            return Err(SimError::TaskFamilyMismatch {
                env_family: self.name(),
                task_family: task.family().name(),
            });
        }
        if !task.value().is_finite() {
            return Err(SimError::InvalidTask {
                family: self.name(),
                reason: format!("its {} {} is not finite", self.value_name(), task.value()),
            });
        }
        Ok(())
    }

    /// How far a number may be from a task's value and still name it: [`TASK_VALUE_TOLERANCE`]
    /// for point-goal, ant-goal and cheetah-vel, 0 for walker-dyn and ant-linclass (seeds are
    /// integers).
    pub fn value_tolerance(self) -> f64 {
        self.spec().value_tolerance
    }

    /// What a task value of this family is, for messages: `goal angle (rad)`, ...
    pub fn value_name(self) -> &'static str {
        self.spec().value_name
    }

    /// The one tolerant lookup of a task by its parameter: the index in `tasks` of the task
    /// of this family whose value is nearest `value`, when it is within
    /// [`Family::value_tolerance`] of it. Otherwise [`SimError::NoTaskNear`], which lists the
    /// values of `tasks`.
    pub fn find_task<'t>(
        self,
        value: f64,
        tasks: impl IntoIterator<Item = &'t Task>,
    ) -> Result<usize, SimError> {
        let tolerance = self.value_tolerance();
        let mut best: Option<(usize, f64)> = None;
        let mut available = Vec::new();
        for (i, task) in tasks.into_iter().enumerate() {
            if task.family() != self {
                continue;
            }
            available.push(task.short_value());
            let distance = (task.value() - value).abs();
            if distance <= tolerance && best.is_none_or(|(_, d)| distance < d) {
                best = Some((i, distance));
            }
        }
        best.map(|(i, _)| i).ok_or_else(|| SimError::NoTaskNear {
            family: self.name(),
            value_name: self.value_name(),
            value,
            tolerance,
            available: if available.is_empty() {
                "none".into()
            } else {
                available.join(", ")
            },
        })
    }

    /// The task `value` names: the meta-train or meta-test task (or the nominal walker) within
    /// [`Family::value_tolerance`] of it, so that `0.4909` is test goal 0.490874 exactly; else
    /// a new task with exactly this value ([`Family::task_from_value`]).
    pub fn task_named(self, value: f64) -> Result<Task, SimError> {
        let mut known = self.train_tasks();
        known.extend(self.test_tasks());
        known.extend(self.nominal_task());
        match self.find_task(value, &known) {
            Ok(i) => Ok(known[i]),
            Err(_) => self.task_from_value(value),
        }
    }

    /// The task outside both splits that the family's normalised metric refers to (walker-dyn's
    /// unmodified walker); `None` where the family has none.
    pub fn nominal_task(self) -> Option<Task> {
        let value = self.spec().nominal_value?;
        Some(Task::new(self, value))
    }

    /// Dimension of the learner-facing observation.
    pub fn obs_dim(self) -> usize {
        self.spec().obs_dim
    }

    /// Dimension of the action.
    pub fn act_dim(self) -> usize {
        self.spec().act_dim
    }

    /// Dimension of the task parameter vector appended in the oracle observation.
    pub fn task_dim(self) -> usize {
        self.spec().task_dim
    }

    /// Dimension of the oracle observation (observation followed by the task parameter).
    pub fn oracle_obs_dim(self) -> usize {
        self.obs_dim() + self.task_dim()
    }

    /// The paper's evaluation metric of this family.
    pub fn metric_kind(self) -> MetricKind {
        self.spec().metric
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A family is written as its CLI name (`"cheetah-vel"`) in every config, report and run file,
/// and read back through [`FromStr`]: an unknown name fails when the file is parsed, with the
/// list of known ones.
impl serde::Serialize for Family {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Family {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Name;
        impl serde::de::Visitor<'_> for Name {
            type Value = Family;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a task family name such as \"cheetah-vel\"")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Family, E> {
                v.parse().map_err(E::custom)
            }
        }
        d.deserialize_str(Name)
    }
}

impl fmt::Display for Split {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Split::Train => "train",
            Split::Test => "test",
        })
    }
}

impl FromStr for Split {
    type Err = SimError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "train" => Ok(Split::Train),
            "test" => Ok(Split::Test),
            other => Err(SimError::UnknownSplit(other.to_string())),
        }
    }
}

/// Radius of the circle the point-goal and ant-goal goals lie on.
pub const GOAL_RADIUS: f32 = 2.0;

impl Task {
    /// The goal position of a point-goal or ant-goal task.
    pub fn goal(&self) -> Option<[f32; 2]> {
        let goal_family = [Family::POINT_GOAL, Family::ANT_GOAL].contains(&self.family());
        goal_family.then(|| {
            let goal_angle = self.value() as f32;
            [
                GOAL_RADIUS * goal_angle.cos(),
                GOAL_RADIUS * goal_angle.sin(),
            ]
        })
    }

    /// Whether `value` names this task: within [`Family::value_tolerance`] of [`Task::value`].
    pub fn is_named_by(&self, value: f64) -> bool {
        (self.value() - value).abs() <= self.family().value_tolerance()
    }

    /// Whether `other` is this task up to the tolerance of [`Task::is_named_by`] (same family,
    /// values within tolerance): a task read back from a file or typed by a user.
    pub fn same_task(&self, other: &Task) -> bool {
        self.family() == other.family() && self.is_named_by(other.value())
    }

    /// The value as a label prints it (`0.4909`, `1.25`, `10003`): the spec's decimals.
    fn short_value(&self) -> String {
        format!("{:.*}", self.family().spec().value_decimals, self.value())
    }

    /// Writes the task parameter vector (length `family().task_dim()`) that the oracle
    /// observation appends: goal (x, y) (point-goal, ant-goal); v*; or the walker's log-scale
    /// dynamics factors; the hyperplane's unit normal (ant-linclass). The family's spec writes
    /// it ([`crate::FamilySpec::write_parameter`]).
    pub fn write_parameter(&self, out: &mut [f32]) -> Result<(), SimError> {
        let spec = self.family().spec();
        if out.len() != spec.task_dim {
            return Err(SimError::BufferLength {
                expected: spec.task_dim,
                got: out.len(),
            });
        }
        (spec.write_parameter)(self, out);
        Ok(())
    }

    /// The task parameter vector as a fresh `Vec` (see [`Task::write_parameter`]).
    pub fn parameter(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.family().task_dim()];
        // The buffer has the right length by construction.
        let _ = self.write_parameter(&mut out);
        out
    }

    /// A short human-readable label, e.g. `goal_angle=0.1963`; the family's nominal task (the
    /// unmodified walker) says so.
    pub fn label(&self) -> String {
        let spec = self.family().spec();
        let nominal = if self.family().nominal_task() == Some(*self) {
            " (nominal)"
        } else {
            ""
        };
        format!("{}={}{nominal}", spec.value_key, self.short_value())
    }
}

impl fmt::Display for Task {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.family(), self.label())
    }
}

#[cfg(test)]
mod tests;
