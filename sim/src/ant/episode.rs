//! What both Ant families share within an episode: the robot, the step clock, the clipped
//! action, the ant's 29 observed entries and the torso's path. A family adds its task (a goal,
//! a pair of points), its reward and its metric around it.

use super::{ACT_DIM, OBS_DIM, obs};
use crate::env::{EpisodeClock, clip_action};
use crate::error::SimError;
use crate::family::{EnvConfig, Family};
use crate::kinds::Physics;
use crate::plant::{Plant, Robot};
use crate::render::{Frame, Role, Shape, View};

/// Observed velocities are clipped to +-this (m/s, rad/s), as walker-dyn's: a rare violent
/// contact must not feed a network a huge input.
pub const VELOCITY_CLIP: f32 = 10.0;

/// One ant episode of `family` (named in errors).
pub(crate) struct AntEpisode {
    family: Family,
    physics: Physics,
    robot: Box<dyn Plant>,
    /// Steps taken and whether the episode is over.
    pub clock: EpisodeClock,
    /// The ant's observation after the last reset or step.
    pub obs: [f32; OBS_DIM],
    action: [f32; ACT_DIM],
    /// Torso (x, y) after each step, the start first (drawn in frames).
    path: Vec<[f32; 2]>,
}

impl AntEpisode {
    /// The ant of `family` on `config.physics` reset with seed 0, episodes of
    /// `config.horizon` steps (else `default_horizon`).
    pub fn new(
        family: Family,
        config: EnvConfig,
        default_horizon: usize,
    ) -> Result<Self, SimError> {
        let robot = Robot::Ant.plant(config.physics)?;
        let horizon = config.horizon.unwrap_or(default_horizon);
        let mut episode = Self {
            family,
            physics: config.physics,
            robot,
            clock: EpisodeClock::new(horizon),
            obs: [0.0; OBS_DIM],
            action: [0.0; ACT_DIM],
            path: Vec::with_capacity(horizon + 1),
        };
        episode.reset(0);
        Ok(episode)
    }

    /// The physics backend of the ant.
    pub fn physics(&self) -> Physics {
        self.physics
    }

    /// A new episode: the rest pose with `seed`'s initial-state noise.
    pub fn reset(&mut self, seed: u64) {
        self.robot.reset(seed, None);
        self.clock.restart();
        self.robot.observe(&mut self.obs, VELOCITY_CLIP);
        self.path.clear();
        self.path.push(self.torso_xy());
    }

    /// Seconds per control step.
    pub fn control_dt(&self) -> f32 {
        self.robot.control_dt()
    }

    /// Torso (x, y) position (m).
    pub fn torso_xy(&self) -> [f32; 2] {
        [self.obs[obs::XY], self.obs[obs::XY + 1]]
    }

    /// Distance (m) from the torso to the point `target` in the ground plane.
    pub fn torso_distance(&self, target: [f32; 2]) -> f32 {
        let [x, y] = self.torso_xy();
        let (dx, dy) = (x - target[0], y - target[1]);
        (dx * dx + dy * dy).sqrt()
    }

    /// Applies `action` (checked, clipped to [-1, 1]) for one control step and observes;
    /// returns the torso's world-frame x velocity over the step. The family advances the
    /// clock (it knows whether the step ended the episode).
    pub fn physics_step(&mut self, action: &[f32]) -> Result<f32, SimError> {
        self.clock.ensure_running()?;
        clip_action(self.family, action, &mut self.action)?;
        let x_before = self.robot.torso().position[0];
        self.robot.step(&self.action);
        if self.robot.diverged() {
            self.clock.over = true;
            return Err(SimError::PhysicsDiverged {
                family: self.family.name(),
                step: self.clock.step,
            });
        }
        self.robot.observe(&mut self.obs, VELOCITY_CLIP);
        self.path.push(self.torso_xy());
        Ok((self.robot.torso().position[0] - x_before) / self.control_dt())
    }

    /// ||a||^2 of the last (clipped) action.
    pub fn effort(&self) -> f32 {
        self.action.iter().map(|a| a * a).sum()
    }

    /// A top-view frame: the family's `scene` shapes, then the torso's path and the ant.
    pub fn frame(&self, mut scene: Vec<Shape>) -> Frame {
        scene.extend(self.path.windows(2).map(|w| Shape::Capsule {
            a: w[0],
            b: w[1],
            radius: 0.01,
            role: Role::Guide,
        }));
        scene.extend(self.robot.shapes());
        Frame {
            view: View::Top,
            time: self.clock.step as f32 * self.control_dt(),
            shapes: scene,
        }
    }
}
