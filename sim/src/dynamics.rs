//! walker-dyn's randomised dynamics: the reference's per-body, per-joint and per-geometry
//! scale factors, drawn deterministically from a seed.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Number of rigid bodies of the walker (torso, and thigh, leg, foot per side).
pub const WALKER_BODIES: usize = 7;
/// Number of actuated joints of the walker.
pub const WALKER_JOINTS: usize = 6;

/// Multiplicative factors applied to the nominal walker; all 1 for the unmodified robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkerDynamics {
    /// Per-body mass factor, 1.5^U(-3, 3).
    pub mass: [f32; WALKER_BODIES],
    /// Per-body rotational inertia factor, 1.5^U(-3, 3).
    pub inertia: [f32; WALKER_BODIES],
    /// Per-joint damping factor, 1.3^U(-3, 3).
    pub damping: [f32; WALKER_JOINTS],
    /// Per-body (collider) friction factor, 1.5^U(-3, 3).
    pub friction: [f32; WALKER_BODIES],
}

impl WalkerDynamics {
    /// Length of the log-factor vector used as the walker's task parameter.
    pub const VECTOR_DIM: usize = 3 * WALKER_BODIES + WALKER_JOINTS;

    /// The unmodified robot.
    pub fn nominal() -> Self {
        Self {
            mass: [1.0; WALKER_BODIES],
            inertia: [1.0; WALKER_BODIES],
            damping: [1.0; WALKER_JOINTS],
            friction: [1.0; WALKER_BODIES],
        }
    }

    /// Dynamics drawn from `seed` with ChaCha8: masses and inertias x 1.5^U(-3,3), joint
    /// damping x 1.3^U(-3,3), friction x 1.5^U(-3,3), each factor independent. This is the raw
    /// draw for any seed; a walker-dyn task maps its seed through
    /// [`crate::Task::walker_dynamics`], which gives [`Self::nominal`] for the reserved
    /// [`crate::WALKER_NOMINAL_SEED`].
    pub fn from_seed(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5741_4c4b_4552_4459); // "WALKERDY"
        let mut factor = |base: f32| base.powf(rng.random_range(-3.0f32..=3.0));
        let mut dynamics = Self::nominal();
        dynamics.mass.iter_mut().for_each(|m| *m = factor(1.5));
        dynamics.inertia.iter_mut().for_each(|i| *i = factor(1.5));
        dynamics.damping.iter_mut().for_each(|d| *d = factor(1.3));
        dynamics.friction.iter_mut().for_each(|f| *f = factor(1.5));
        dynamics
    }

    /// Writes log(factor) / log(base), i.e. the U(-3, 3) exponents, mass then inertia, damping,
    /// friction. `out` must have length [`Self::VECTOR_DIM`].
    pub(crate) fn write_log_factors(&self, out: &mut [f32]) {
        let exponents = self
            .mass
            .iter()
            .chain(&self.inertia)
            .map(|f| f.ln() / 1.5f32.ln())
            .chain(self.damping.iter().map(|f| f.ln() / 1.3f32.ln()))
            .chain(self.friction.iter().map(|f| f.ln() / 1.5f32.ln()));
        for (slot, value) in out.iter_mut().zip(exponents) {
            *slot = value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_are_deterministic_and_within_the_reference_ranges() {
        let a = WalkerDynamics::from_seed(3);
        assert_eq!(a, WalkerDynamics::from_seed(3));
        assert_ne!(a, WalkerDynamics::from_seed(4));
        let bound = |base: f32| base.powi(3) * 1.0001;
        for f in a.mass.iter().chain(&a.inertia).chain(&a.friction) {
            assert!(*f <= bound(1.5) && *f >= 1.0 / bound(1.5));
        }
        for f in a.damping {
            assert!(f <= bound(1.3) && f >= 1.0 / bound(1.3));
        }
        let mut exponents = [0.0; WalkerDynamics::VECTOR_DIM];
        a.write_log_factors(&mut exponents);
        assert!(exponents.iter().all(|e| e.abs() <= 3.001));
    }
}
