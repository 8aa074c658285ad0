//! The physics boundary: a robot as a family's environment drives it, whatever engine
//! simulates it. A family ([`crate::legged`], [`crate::ant_goal`], ...) owns the task, reward,
//! metric and episode; a [`Plant`] owns the bodies, joints and contacts. Each robot has one
//! implementation per backend: Rapier's built in code ([`crate::planar`], [`crate::ant`]),
//! MuJoCo's loaded from Gymnasium's XML (`mujoco` feature). This module names the interface
//! only; `backends.rs` builds a robot on a backend (one arm per backend and robot), so the
//! backends import this module and nothing here imports them.

use crate::dynamics::WalkerDynamics;
use crate::render::Shape;

/// The robots of the task families.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Robot {
    /// HalfCheetah (cheetah-vel): planar, 6 torque-controlled joints, 17-D observation.
    HalfCheetah,
    /// Walker2d (walker-dyn): planar, 6 joints, 17-D observation, randomisable dynamics.
    Walker2d,
    /// Ant (ant-goal, ant-linclass): 3-D quadruped, 8 joints, 29-D observation.
    Ant,
}

/// Where a robot's torso is.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TorsoPose {
    /// Torso position (x, y, z), world frame, z up, metres (planar robots: y = 0).
    pub position: [f32; 3],
    /// Planar robots: the torso's pitch in MuJoCo's coordinates (rooty); 0 for the ant.
    pub pitch: f32,
}

/// One robot in its own physics world: what a family's environment steps.
///
/// Same seed, dynamics and actions give bit-identical observations on the same machine.
pub(crate) trait Plant: Send {
    /// Seconds of simulated time per control step.
    fn control_dt(&self) -> f32;
    /// A new episode: the robot's rest pose with `seed`'s initial-state noise, under `dynamics`
    /// (walker-dyn's randomised masses, inertias, damping and friction; `None`: nominal).
    fn reset(&mut self, seed: u64, dynamics: Option<&WalkerDynamics>);
    /// One control step with `action` (already checked and clipped to [-1, 1]) as the motors'
    /// command: torque `action[i] * gear[i]` on joint `i`.
    fn step(&mut self, action: &[f32]);
    /// True once the state is non-finite or the engine gave up on it.
    fn diverged(&self) -> bool;
    /// Writes the robot's observation (its layout: [`Robot::obs_dim`]), velocities clipped to
    /// +-`velocity_clip`.
    fn observe(&self, out: &mut [f32], velocity_clip: f32);
    /// The torso's position and pitch now.
    fn torso(&self) -> TorsoPose;
    /// The robot's capsules for drawing: side view (x, z) for the planar robots, top view
    /// (x, y) for the ant.
    fn shapes(&self) -> Vec<Shape>;
}
