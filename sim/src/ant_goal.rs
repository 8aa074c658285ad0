//! ant-goal: the 3-D [`crate::ant`] quadruped walking its torso to a goal on the circle of
//! radius 2 around its start (top view). The reference's "Ant 2D goal": 100-step episodes, no
//! termination, reward `-||xy - goal|| - 0.005 ||a||^2`, metric the minimum distance. No
//! shaping term: a per-task SAC expert learnt to reach a goal (min distance 0.07) within 25k
//! steps on this reward alone (docs/RESULTS.md).

use crate::ant::AntEpisode;
use crate::error::SimError;
use crate::family::{EnvConfig, Environment, Family, FamilySpec, RunView, Task, Transition};
use crate::render::Frame;
use crate::spec::LEGGED_ACCEL_STD;
use crate::spec::{goal_test_angles, goal_train_angles};

/// Default episode length (control steps of 0.05 s), as in the reference.
pub const HORIZON: usize = 100;
/// Weight of ||a||^2 in the reward `-distance - ACTION_COST * ||a||^2` (the reference's).
pub const ACTION_COST: f32 = 0.005;
pub use crate::ant::VELOCITY_CLIP;

/// The ant-goal environment.
pub struct AntGoalEnv {
    ant: AntEpisode,
    task: Task,
    goal: [f32; 2],
}

impl AntGoalEnv {
    /// An ant-goal environment on `config.physics` reset to the first train goal with seed 0.
    pub fn new(config: EnvConfig) -> Result<Self, SimError> {
        let task = Family::ANT_GOAL.train_tasks()[0];
        Ok(Self {
            ant: AntEpisode::new(Family::ANT_GOAL, config, HORIZON)?,
            goal: task.goal().unwrap_or_default(),
            task,
        })
    }

    /// The goal position of the current task.
    pub fn goal(&self) -> [f32; 2] {
        self.goal
    }

    /// Torso (x, y) position (m), also the last two observation entries.
    pub fn torso_xy(&self) -> [f32; 2] {
        self.ant.torso_xy()
    }

    /// Torso height (m).
    pub fn torso_z(&self) -> f32 {
        self.ant.obs[crate::ant::obs::Z]
    }
}

impl Environment for AntGoalEnv {
    fn family(&self) -> Family {
        Family::ANT_GOAL
    }

    fn physics(&self) -> crate::kinds::Physics {
        self.ant.physics()
    }

    fn control_dt(&self) -> f32 {
        self.ant.control_dt()
    }

    fn horizon(&self) -> usize {
        self.ant.clock.horizon
    }

    fn task(&self) -> &Task {
        &self.task
    }

    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError> {
        Family::ANT_GOAL.check_task(task)?;
        self.task = *task;
        self.goal = task.goal().unwrap_or_default();
        self.ant.reset(seed);
        Ok(&self.ant.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError> {
        let forward_velocity = self.ant.physics_step(action)?;
        let distance = self.ant.torso_distance(self.goal);
        let reward = -distance - ACTION_COST * self.ant.effort();
        let ant = &mut self.ant;
        Ok(ant
            .clock
            .transition(&ant.obs, reward, false, distance, forward_velocity))
    }

    fn observation(&self) -> &[f32] {
        &self.ant.obs
    }

    fn frame(&self) -> Frame {
        self.ant
            .frame(crate::point_goal::goal_marks(self.goal).to_vec())
    }
}

// ---------------------------------------------------------------------------------------------
// The family's declaration (`families.rs` lists it), its constant and its tasks.

/// ant-goal: point-goal's goals for the 3-D ant; Figure 2's protocol. The task parameter, its
/// names, the metric and the protocol are point-goal's (taken from its `SPEC`, so that a goal
/// angle names, labels and scores the same goal in both families); the rest is the ant's.
pub(crate) const SPEC: FamilySpec = FamilySpec {
    name: "ant-goal",
    obs_dim: crate::ant::OBS_DIM,
    act_dim: crate::ant::ACT_DIM,
    train_tasks: || goal_train_angles().map(Task::ant_goal).collect(),
    test_tasks: || goal_test_angles().map(Task::ant_goal).collect(),
    task_from_value: |v| Ok(Task::ant_goal(v as f32)),
    obs_components: &crate::ant::OBS_COMPONENTS,
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::GoalPath {
        xy: crate::ant::obs::XY,
    },
    make_env: |config| Ok(Box::new(AntGoalEnv::new(config)?)),
    ..crate::point_goal::SPEC
};

impl Family {
    /// ant-goal, declared by this module's `SPEC`.
    pub const ANT_GOAL: Family = Family::of(&SPEC);
}

impl Task {
    /// An ant-goal task with its goal at `goal_angle` radians on the radius-2 circle.
    pub fn ant_goal(goal_angle: f32) -> Task {
        Task::new(Family::ANT_GOAL, goal_angle as f64)
    }
}

#[cfg(test)]
mod tests;
