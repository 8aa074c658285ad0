//! The kinds every module of the crate names, the task family (and a family's task) and the
//! physics backend, kept below them all so the error type can carry one without a loop: the
//! one list of families, and the enums written from it. Their methods live with what they
//! read: `task.rs` (tasks, splits) and `families.rs` (the map to the families' declarations)
//! for [`Family`] and [`Task`], `physics.rs` (names, availability) for [`Physics`].

/// The one list of task families, in CLI order: per family what it is (its [`Family`]
/// variant's doc), its variant, the module that declares its `SPEC` (`families.rs` maps the
/// variant there), and its [`Task`] variant: what a task is and its one parameter. This module
/// writes the two enums from it; `families.rs` writes [`Family::ALL`] and [`Family::spec`].
/// Adding a family is its module and its entry here (and the app's quickstart recipe).
macro_rules! with_families {
    ($then:ident) => {
        $then! {
            /// Planar point robot reaching a goal on the circle of radius 2 (top view).
            #[default]
            PointGoal in point_goal,
            /// point-goal: reach the goal at this angle (radians) on the circle of radius 2.
            task {
                /// Angle of the goal on the circle, radians.
                goal_angle: f32
            };
            /// Planar HalfCheetah analogue running at a target forward velocity.
            CheetahVel in cheetah_vel,
            /// cheetah-vel: run forward at this speed (m/s).
            task {
                /// Target forward velocity v*, m/s.
                target_velocity: f32
            };
            /// Planar Walker2d analogue under randomised body dynamics.
            WalkerDyn in walker_dyn,
            /// walker-dyn: walk under the dynamics drawn from this seed.
            task {
                /// Seed of the dynamics randomisation (see [`crate::WalkerDynamics::from_seed`]);
                /// [`crate::WALKER_NOMINAL_SEED`] means the unmodified robot.
                dynamics_seed: u64
            };
            /// 3-D Ant (Gymnasium's quadruped) walking to a goal on the circle of radius 2; the
            /// same goal angles as point-goal.
            AntGoal in ant_goal,
            /// ant-goal: walk the ant's torso to the goal at this angle (radians) on the circle
            /// of radius 2.
            task {
                /// Angle of the goal on the circle, radians.
                goal_angle: f32
            };
            /// 3-D Ant walking to one of two targets to classify a pair of 4-D points by a
            /// hidden hyperplane ([`crate::ant_linclass`]).
            AntLinClass in ant_linclass,
            /// ant-linclass: classify pairs of 4-D points by the hyperplane drawn from this seed.
            task {
                /// Seed of the hyperplane's normal ([`crate::ant_linclass::hyperplane_normal`]).
                hyperplane_seed: u64
            };
        }
    };
}
pub(crate) use with_families;

/// Writes [`Family`] and [`Task`] from the list, with the two matches between them.
macro_rules! declare_families {
    ($(
        $(#[$family_attr:meta])* $variant:ident in $module:ident,
        $(#[$task_doc:meta])* task { $(#[$param_doc:meta])* $param:ident: $ty:ty };
    )+) => {
        /// A family of tasks sharing one robot; the CLI names are `point-goal`, `cheetah-vel`,
        /// `walker-dyn`, `ant-goal`, `ant-linclass`.
        ///
        /// What the workspace knows about each family is its [`crate::FamilySpec`]
        /// ([`Family::spec`]), declared in the family's own module and mapped in
        /// `families.rs`. Deliberately not `#[non_exhaustive]`: a new family fails to compile
        /// in the app's per-family recipes instead of falling silently into a catch-all arm.
        /// The default is point-goal, the toy every learner's configuration starts from.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
        pub enum Family {
            $($(#[$family_attr])* $variant,)+
        }

        /// One task: the hidden parameter the learner must infer from demonstrations.
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[non_exhaustive]
        pub enum Task {
            $($(#[$task_doc])* $variant { $(#[$param_doc])* $param: $ty },)+
        }

        impl Task {
            /// The family this task belongs to.
            pub fn family(&self) -> Family {
                match self {
                    $(Task::$variant { .. } => Family::$variant,)+
                }
            }

            /// The single number naming this task: goal angle, target velocity or dynamics
            /// seed. `family.task_from_value(task.value())` gives the task back.
            pub fn value(&self) -> f64 {
                match *self {
                    $(Task::$variant { $param } => $param as f64,)+
                }
            }
        }
    };
}

with_families!(declare_families);

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
