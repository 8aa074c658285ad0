//! The physics backend, the one kind below everything in the crate (the error type names it).
//! Its methods (names, availability) live in `physics.rs`.

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
