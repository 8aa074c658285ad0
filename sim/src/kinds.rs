//! The kinds every module of the crate names, the task family (and a family's task) and the
//! physics backend, kept below them all so the error type can carry one without a loop. Their
//! methods live with what they read: `task.rs` (tasks, splits), each family's module (its
//! [`Family`] constant and its tasks' constructors), `families.rs` (the built-in list and the
//! registry of families declared elsewhere), `physics.rs` (names, availability) for
//! [`Physics`].

use std::fmt;
use std::hash::{Hash, Hasher};

use crate::spec::FamilySpec;

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

/// A physics backend. A task family (tasks, splits, reward, metric, observation layout) is
/// written once; each robot has one implementation per backend ([`crate::Robot`]).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Physics {
    /// Rapier (rapier2d / rapier3d) robots built in code: the default, the device's plant,
    /// needing nothing but the Rust toolchain.
    #[default]
    Rapier,
    /// MuJoCo 3.17.0 loading Gymnasium's XMLs: the paper's own engine. Needs the cargo feature
    /// `mujoco` and `scripts/fetch-mujoco.sh`.
    Mujoco,
}
