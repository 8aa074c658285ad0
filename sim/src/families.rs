//! The list of task families: each [`Family`] and the module that declares it. It sits above
//! every family's module (it imports them all), so no family module and nothing below them
//! imports it back; `task.rs` and the rest reach a family's data through [`Family::spec`].
//!
//! Adding a family: its module with its environment and its `SPEC` (as `point_goal.rs`), its
//! line in [`families!`] below, a [`Family`] variant (`kinds.rs`) and a `Task` variant with its
//! arms (`task.rs`), the two enums the compiler checks every `match` against.

use crate::kinds::Family;
use crate::sensing::ObsComponent;
use crate::spec::FamilySpec;

/// The list: each family's variant and the module whose `SPEC` declares it, in CLI order.
/// It writes [`Family::ALL`] and the one `match` of [`Family::spec`].
macro_rules! families {
    ($($variant:ident => $module:ident),+ $(,)?) => {
        impl Family {
            /// Every family, in CLI order.
            pub const ALL: [Family; [$(Family::$variant),+].len()] = [$(Family::$variant),+];

            /// The family's spec: everything the workspace knows about it ([`FamilySpec`]),
            /// declared in the family's module. The one place that maps a family to its data;
            /// everything else reads the spec's fields.
            pub fn spec(self) -> &'static FamilySpec {
                match self {
                    $(Family::$variant => &crate::$module::SPEC),+
                }
            }
        }
    };
}

families! {
    PointGoal => point_goal,
    CheetahVel => cheetah_vel,
    WalkerDyn => walker_dyn,
    AntGoal => ant_goal,
    AntLinClass => ant_linclass,
}

impl Family {
    /// Per observation index, what the entry is: a measured position or angle, the rate of
    /// another entry, or a directly measured quantity. Its length is [`Family::obs_dim`].
    pub fn obs_components(self) -> &'static [ObsComponent] {
        self.spec().obs_components
    }
}
