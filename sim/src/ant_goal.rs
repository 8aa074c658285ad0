//! ant-goal: the 3-D [`crate::ant`] quadruped walking its torso to a goal on the circle of
//! radius 2 around its start (top view). The reference's "Ant 2D goal": 100-step episodes, no
//! termination, reward `-||xy - goal|| - 0.005 ||a||^2`, metric the minimum distance. No
//! shaping term: a per-task SAC expert learnt to reach a goal (min distance 0.07) within 25k
//! steps on this reward alone (docs/RESULTS.md).

use crate::ant::{ACT_DIM, AntRobot, AntSpec, OBS_DIM, obs};
use crate::env::{EpisodeClock, check_family, clip_action};
use crate::render::{Frame, Role, Shape, View};
use crate::{EnvConfig, Environment, Family, SimError, StepInfo, Task, Transition};

/// Default episode length (control steps of 0.05 s), as in the reference.
pub const HORIZON: usize = 100;
/// Weight of ||a||^2 in the reward `-distance - ACTION_COST * ||a||^2` (the reference's).
pub const ACTION_COST: f32 = 0.005;
/// Observed velocities are clipped to +-this (m/s, rad/s), as walker-dyn's: a rare violent
/// contact must not feed a network a huge input.
pub const VELOCITY_CLIP: f32 = 10.0;

/// The ant-goal environment.
pub struct AntGoalEnv {
    spec: AntSpec,
    robot: AntRobot,
    task: Task,
    goal: [f32; 2],
    clock: EpisodeClock,
    obs: [f32; OBS_DIM],
    action: [f32; ACT_DIM],
    /// Torso (x, y) after each step of the episode, the start first (drawn in frames).
    path: Vec<[f32; 2]>,
}

impl AntGoalEnv {
    /// An ant-goal environment reset to the first train goal with seed 0.
    pub fn new(config: EnvConfig) -> Self {
        let spec = crate::ant::ant();
        let task = Family::AntGoal.train_tasks()[0];
        let robot = AntRobot::build(&spec, 0);
        let mut env = Self {
            spec,
            robot,
            goal: task.goal().unwrap_or_default(),
            task,
            clock: EpisodeClock::new(config.horizon.unwrap_or(HORIZON)),
            obs: [0.0; OBS_DIM],
            action: [0.0; ACT_DIM],
            path: Vec::with_capacity(HORIZON + 1),
        };
        env.observe();
        env.path.push(env.torso_xy());
        env
    }

    /// The goal position of the current task.
    pub fn goal(&self) -> [f32; 2] {
        self.goal
    }

    /// Torso (x, y) position (m), also the last two observation entries.
    pub fn torso_xy(&self) -> [f32; 2] {
        [self.obs[obs::XY], self.obs[obs::XY + 1]]
    }

    /// Torso height (m).
    pub fn torso_z(&self) -> f32 {
        self.obs[obs::Z]
    }

    fn observe(&mut self) {
        self.robot.observe(&mut self.obs, VELOCITY_CLIP);
    }

    fn distance_to_goal(&self) -> f32 {
        let [x, y] = self.torso_xy();
        let (dx, dy) = (x - self.goal[0], y - self.goal[1]);
        (dx * dx + dy * dy).sqrt()
    }
}

impl Environment for AntGoalEnv {
    fn family(&self) -> Family {
        Family::AntGoal
    }

    fn control_dt(&self) -> f32 {
        self.spec.physics_dt * self.spec.substeps as f32
    }

    fn horizon(&self) -> usize {
        self.clock.horizon
    }

    fn task(&self) -> &Task {
        &self.task
    }

    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError> {
        check_family(Family::AntGoal, task)?;
        if !task.value().is_finite() {
            return Err(SimError::InvalidTask {
                family: Family::AntGoal,
                reason: "goal angle is not finite".into(),
            });
        }
        self.robot = AntRobot::build(&self.spec, seed);
        self.task = *task;
        self.goal = task.goal().unwrap_or_default();
        self.clock.restart();
        self.observe();
        self.path.clear();
        self.path.push(self.torso_xy());
        Ok(&self.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError> {
        self.clock.ensure_running()?;
        clip_action(Family::AntGoal, action, &mut self.action)?;
        let x_before = self.robot.torso_position()[0];
        self.robot.set_torques(&self.action);
        self.robot.advance();
        if self.robot.diverged() {
            self.clock.over = true;
            return Err(SimError::PhysicsDiverged {
                family: Family::AntGoal,
                step: self.clock.step,
            });
        }
        self.observe();
        self.path.push(self.torso_xy());
        let forward_velocity = (self.robot.torso_position()[0] - x_before) / self.control_dt();
        let distance = self.distance_to_goal();
        let effort: f32 = self.action.iter().map(|a| a * a).sum();
        let (terminated, truncated) = self.clock.advance(false);
        Ok(Transition {
            obs: &self.obs,
            reward: -distance - ACTION_COST * effort,
            done: terminated || truncated,
            info: StepInfo {
                step: self.clock.step,
                terminated,
                truncated,
                metric_sample: distance,
                forward_velocity,
            },
        })
    }

    fn observation(&self) -> &[f32] {
        &self.obs
    }

    fn frame(&self) -> Frame {
        let mut shapes = vec![
            Shape::Ring {
                center: [0.0, 0.0],
                radius: crate::task::GOAL_RADIUS,
                role: Role::Guide,
            },
            Shape::Circle {
                center: self.goal,
                radius: 0.1,
                role: Role::Goal,
            },
        ];
        shapes.extend(self.path.windows(2).map(|w| Shape::Capsule {
            a: w[0],
            b: w[1],
            radius: 0.01,
            role: Role::Guide,
        }));
        shapes.extend(self.robot.top_view_shapes());
        Frame {
            view: View::Top,
            time: self.clock.step as f32 * self.control_dt(),
            shapes,
        }
    }
}

#[cfg(test)]
mod tests;
