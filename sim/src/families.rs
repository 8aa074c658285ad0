//! The list of task families: each [`Family`] and the module that declares it. It sits above
//! every family's module (it imports them all), so no family module and nothing below them
//! imports it back; `task.rs` and the rest reach a family's data through [`Family::spec`].
//!
//! Adding a family: its module with its environment and its `SPEC` (as `point_goal.rs`) and its
//! entry in the one list of families ([`with_families`], `kinds.rs`), which writes the
//! [`Family`] and `Task` enums there and this module's map.

use crate::kinds::{Family, with_families};
use crate::sensing::ObsComponent;
use crate::spec::FamilySpec;

/// Writes [`Family::ALL`] and the one `match` of [`Family::spec`] from the list
/// ([`with_families`]).
macro_rules! map_families {
    ($(
        $(#[$family_attr:meta])* $variant:ident in $module:ident,
        $(#[$task_doc:meta])* task { $($param:tt)* };
    )+) => {
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

with_families!(map_families);

impl Family {
    /// Per observation index, what the entry is: a measured position or angle, the rate of
    /// another entry, or a directly measured quantity. Its length is [`Family::obs_dim`].
    pub fn obs_components(self) -> &'static [ObsComponent] {
        self.spec().obs_components
    }
}
