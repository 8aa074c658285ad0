//! The two kinds every module of the crate names, the task family and the physics backend,
//! kept below them all so the error type can carry one without a loop. Their methods live
//! with what they read: `task.rs` (tasks, splits) and `families.rs` (the list of the families'
//! declarations) for [`Family`], `physics.rs` (names, availability) for [`Physics`].

/// A family of tasks sharing one robot; the CLI names are `point-goal`, `cheetah-vel`,
/// `walker-dyn`, `ant-goal`, `ant-linclass`.
///
/// What the workspace knows about each family is its [`crate::FamilySpec`] ([`Family::spec`]),
/// declared in the family's own module and listed in `families.rs`. Deliberately not
/// `#[non_exhaustive]`: a new family fails to compile at [`Family::spec`] (and the app's
/// per-family recipes) instead of falling silently into a catch-all arm. The default is point-goal, the toy every learner's
/// configuration starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum Family {
    /// Planar point robot reaching a goal on the circle of radius 2 (top view).
    #[default]
    PointGoal,
    /// Planar HalfCheetah analogue running at a target forward velocity.
    CheetahVel,
    /// Planar Walker2d analogue under randomised body dynamics.
    WalkerDyn,
    /// 3-D Ant (Gymnasium's quadruped) walking to a goal on the circle of radius 2; the same
    /// goal angles as point-goal.
    AntGoal,
    /// 3-D Ant walking to one of two targets to classify a pair of 4-D points by a hidden
    /// hyperplane ([`crate::ant_linclass`]).
    AntLinClass,
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
