//! Which physics engine simulates the robots: the choice a user makes per run
//! (`physics = "mujoco"` in a config, `--physics` on the command line) and every result records.

use std::fmt;
use std::str::FromStr;

use crate::error::SimError;
use crate::kinds::Physics;

/// The MuJoCo version the `mujoco` backend is built for (`mj_version()` of the library must
/// equal it).
pub const MUJOCO_VERSION: &str = "3.17.0";

impl Physics {
    /// Both backends, the default first.
    pub const ALL: [Physics; 2] = [Physics::Rapier, Physics::Mujoco];

    /// The name used in configs, on the command line and in files: `rapier` or `mujoco`.
    pub fn name(self) -> &'static str {
        match self {
            Physics::Rapier => "rapier",
            Physics::Mujoco => "mujoco",
        }
    }

    /// Whether this build can simulate on this backend (MuJoCo needs the `mujoco` feature).
    pub fn is_available(self) -> bool {
        match self {
            Physics::Rapier => true,
            Physics::Mujoco => cfg!(feature = "mujoco"),
        }
    }

    /// `Ok` if [`Self::is_available`], else [`SimError::PhysicsUnavailable`] saying how to get it.
    pub fn ensure_available(self) -> Result<(), SimError> {
        if self.is_available() {
            Ok(())
        } else {
            Err(self.unavailable())
        }
    }

    /// The error of a build without this backend.
    pub(crate) fn unavailable(self) -> SimError {
        SimError::PhysicsUnavailable {
            physics: self,
            how: "this binary was built without the `mujoco` feature; run \
                  scripts/fetch-mujoco.sh, then build with `cargo build --release --features mujoco`"
                .into(),
        }
    }

    /// Parses a physics name from a file or command line, where a missing field means the
    /// default (files written before the MuJoCo backend existed are Rapier's).
    pub fn from_name_or_default(name: Option<&str>) -> Result<Self, SimError> {
        name.map_or(Ok(Physics::Rapier), str::parse)
    }
}

impl fmt::Display for Physics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Physics {
    type Err = SimError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Physics::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| SimError::UnknownPhysics(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_refused() {
        for p in Physics::ALL {
            assert_eq!(p.name().parse::<Physics>().unwrap(), p);
        }
        assert!(matches!(
            "bullet".parse::<Physics>(),
            Err(SimError::UnknownPhysics(_))
        ));
        assert_eq!(
            Physics::from_name_or_default(None).unwrap(),
            Physics::Rapier
        );
        assert!(Physics::Rapier.ensure_available().is_ok());
    }

    #[cfg(not(feature = "mujoco"))]
    #[test]
    fn a_build_without_the_feature_says_how_to_get_mujoco() {
        let err = Physics::Mujoco.ensure_available().unwrap_err().to_string();
        assert!(
            err.contains("fetch-mujoco.sh") && err.contains("--features mujoco"),
            "{err}"
        );
    }
}
