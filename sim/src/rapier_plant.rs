//! The Rapier backend's [`Plant`]: a robot built in code from its declaration, rebuilt in a
//! fresh world at every reset. One implementation for every Rapier robot (`planar.rs`'s
//! cheetah and walker, `ant.rs`'s ant); a robot says how it is built and read
//! ([`RapierRobot`]).

use crate::dynamics::WalkerDynamics;
use crate::plant::{Plant, TorsoPose};
use crate::render::Shape;

/// A robot built in code on Rapier, as [`RapierPlant`] drives it.
pub(crate) trait RapierRobot: Send + Sized {
    /// The declaration it is built from.
    type Spec: Send;
    /// Width of its observation.
    const OBS_DIM: usize;
    /// Builds it from `spec` in its rest pose with `seed`'s initial-state noise, under
    /// `dynamics` where the robot's dynamics are randomised (`None`: nominal).
    fn build(spec: &Self::Spec, seed: u64, dynamics: Option<&WalkerDynamics>) -> Self;
    /// Seconds of simulated time per control step of a robot built from `spec`.
    fn control_dt(spec: &Self::Spec) -> f32;
    /// Sets the joint torques of `action` (already clipped) and advances one control step.
    fn step(&mut self, action: &[f32]);
    /// True if any body's position or velocity is non-finite.
    fn diverged(&self) -> bool;
    /// Writes the observation into `out` ([`Self::OBS_DIM`] long); velocities clipped to
    /// +-`velocity_clip`.
    fn observe(&self, out: &mut [f32], velocity_clip: f32);
    /// The torso's position and pitch now.
    fn torso(&self) -> TorsoPose;
    /// The robot's shapes for drawing (see [`Plant::shapes`]).
    fn shapes(&self) -> Vec<Shape>;
}

/// A Rapier robot as a [`Plant`]: its declaration, and the robot built from it.
pub(crate) struct RapierPlant<R: RapierRobot> {
    spec: R::Spec,
    robot: R,
}

impl<R: RapierRobot> RapierPlant<R> {
    /// The robot of `spec`, reset with seed 0 and nominal dynamics.
    pub fn new(spec: R::Spec) -> Self {
        let robot = R::build(&spec, 0, None);
        Self { spec, robot }
    }
}

impl<R: RapierRobot> Plant for RapierPlant<R> {
    fn control_dt(&self) -> f32 {
        R::control_dt(&self.spec)
    }

    fn reset(&mut self, seed: u64, dynamics: Option<&WalkerDynamics>) {
        self.robot = R::build(&self.spec, seed, dynamics);
    }

    fn step(&mut self, action: &[f32]) {
        self.robot.step(action);
    }

    fn diverged(&self) -> bool {
        self.robot.diverged()
    }

    /// A buffer of another width than the robot's observation is left as it is.
    fn observe(&self, out: &mut [f32], velocity_clip: f32) {
        if out.len() == R::OBS_DIM {
            self.robot.observe(out, velocity_clip);
        }
    }

    fn torso(&self) -> TorsoPose {
        self.robot.torso()
    }

    fn shapes(&self) -> Vec<Shape> {
        self.robot.shapes()
    }
}
