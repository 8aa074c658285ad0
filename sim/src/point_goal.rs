//! point-goal: a planar point robot pushed by forces against linear damping, reaching a goal
//! on the circle of radius 2 (top view).
//!
//! The body is a Rapier rigid body with mass 1 and no collider (nothing to collide with), so a
//! step is one integration with one solver iteration: this is the quickstart family.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier2d::prelude::*;

use crate::env::{EpisodeClock, clip_action};
use crate::error::SimError;
use crate::family::{
    EnvConfig, Environment, EvalDefaults, Family, FamilySpec, MetricKind, RunView, Task, Transition,
};
use crate::kinds::Physics;
use crate::render::{Frame, Role, Shape, View};
use crate::sensing::ObsComponent;
use crate::spec::{goal_test_angles, goal_train_angles, write_goal};
use crate::task::{POINT_GOAL_ACT_DIM, POINT_GOAL_OBS_DIM, TASK_VALUE_TOLERANCE};

/// What a goal family (point-goal, ant-goal) draws under its robot (top view): the dashed
/// circle the goals lie on and the goal at `goal`.
pub(crate) fn goal_marks(goal: [f32; 2]) -> [Shape; 2] {
    [
        Shape::Ring {
            center: [0.0, 0.0],
            radius: crate::task::GOAL_RADIUS,
            role: Role::Guide,
        },
        Shape::Circle {
            center: goal,
            radius: 0.1,
            role: Role::Goal,
        },
    ]
}

/// Observation: position (x, y) and velocity (vx, vy). The goal is not observed.
pub const OBS_DIM: usize = crate::task::POINT_GOAL_OBS_DIM;
/// Action: force along x and y, in units of [`MAX_FORCE`].
pub const ACT_DIM: usize = crate::task::POINT_GOAL_ACT_DIM;
/// Default episode length in control steps.
pub const HORIZON: usize = 100;
/// Seconds per control step (one physics step).
pub const CONTROL_DT: f32 = 0.1;
/// Force (N) produced by an action component of 1.
pub const MAX_FORCE: f32 = 2.0;
/// Mass of the robot (kg).
pub const MASS: f32 = 1.0;
/// Rapier linear damping (1/s): terminal speed is MAX_FORCE / (MASS * LINEAR_DAMPING).
pub const LINEAR_DAMPING: f32 = 1.0;
/// Weight of the action cost in the reward `-distance - ACTION_COST * ||a||^2`.
pub const ACTION_COST: f32 = 0.01;
/// Initial position and velocity components are drawn uniformly from +-this.
pub const RESET_NOISE: f32 = 0.1;

/// The point-goal environment.
pub struct PointGoalEnv {
    world: PhysicsWorld,
    body: RigidBodyHandle,
    task: Task,
    goal: [f32; 2],
    clock: EpisodeClock,
    obs: [f32; OBS_DIM],
    action: [f32; ACT_DIM],
}

fn point_world() -> (PhysicsWorld, RigidBodyHandle) {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::ZERO;
    world.integration_parameters.dt = CONTROL_DT;
    world.integration_parameters.num_solver_iterations = 1;
    let body = world.insert_body(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, MASS, 1.0))
            .linear_damping(LINEAR_DAMPING)
            .lock_rotations()
            .can_sleep(false),
    );
    (world, body)
}

impl PointGoalEnv {
    /// A point-goal environment reset to the first train goal with seed 0.
    pub fn new(config: EnvConfig) -> Self {
        let (world, body) = point_world();
        let task = Family::POINT_GOAL.train_tasks()[0];
        let mut env = Self {
            world,
            body,
            goal: task.goal().unwrap_or_default(),
            task,
            clock: EpisodeClock::new(config.horizon.unwrap_or(HORIZON)),
            obs: [0.0; OBS_DIM],
            action: [0.0; ACT_DIM],
        };
        env.place(&task, 0);
        env
    }

    /// The goal position of the current task.
    pub fn goal(&self) -> [f32; 2] {
        self.goal
    }

    fn place(&mut self, task: &Task, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut noise = || rng.random_range(-RESET_NOISE..=RESET_NOISE);
        let position = Vector::new(noise(), noise());
        let velocity = Vector::new(noise(), noise());
        let body = &mut self.world.bodies[self.body];
        body.set_translation(position, true);
        body.set_linvel(velocity, true);
        body.reset_forces(true);
        self.task = *task;
        self.goal = task.goal().unwrap_or_default();
        self.clock.restart();
        self.observe();
    }

    fn observe(&mut self) {
        let body = &self.world.bodies[self.body];
        let p = body.translation();
        let v = body.linvel();
        self.obs = [p.x, p.y, v.x, v.y];
    }

    fn distance_to_goal(&self) -> f32 {
        let dx = self.obs[0] - self.goal[0];
        let dy = self.obs[1] - self.goal[1];
        (dx * dx + dy * dy).sqrt()
    }
}

impl Environment for PointGoalEnv {
    fn family(&self) -> Family {
        Family::POINT_GOAL
    }

    fn control_dt(&self) -> f32 {
        CONTROL_DT
    }

    fn horizon(&self) -> usize {
        self.clock.horizon
    }

    fn task(&self) -> &Task {
        &self.task
    }

    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError> {
        Family::POINT_GOAL.check_task(task)?;
        self.place(task, seed);
        Ok(&self.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError> {
        self.clock.ensure_running()?;
        clip_action(Family::POINT_GOAL, action, &mut self.action)?;
        let force = Vector::new(self.action[0], self.action[1]) * MAX_FORCE;
        let body = &mut self.world.bodies[self.body];
        body.reset_forces(false);
        body.add_force(force, true);
        self.world.step();
        self.observe();
        if self.obs.iter().any(|x| !x.is_finite()) {
            return Err(SimError::PhysicsDiverged {
                family: Family::POINT_GOAL.name(),
                step: self.clock.step,
            });
        }
        let distance = self.distance_to_goal();
        let effort = self.action[0] * self.action[0] + self.action[1] * self.action[1];
        let reward = -distance - ACTION_COST * effort;
        Ok(self
            .clock
            .transition(&self.obs, reward, false, distance, 0.0))
    }

    fn observation(&self) -> &[f32] {
        &self.obs
    }

    fn frame(&self) -> Frame {
        Frame {
            view: View::Top,
            time: self.clock.step as f32 * CONTROL_DT,
            shapes: goal_marks(self.goal)
                .into_iter()
                .chain([Shape::Circle {
                    center: [self.obs[0], self.obs[1]],
                    radius: 0.08,
                    role: Role::Robot,
                }])
                .collect(),
        }
    }
}

/// A scripted PD controller for point-goal (not learned): it reads the goal from the oracle
/// observation `[x, y, vx, vy, goal_x, goal_y]` and pushes towards it, braking with velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointGoalPdExpert {
    /// Proportional gain (action per metre of error).
    pub kp: f32,
    /// Derivative gain (action per m/s of velocity).
    pub kd: f32,
}

impl Default for PointGoalPdExpert {
    fn default() -> Self {
        Self { kp: 2.0, kd: 1.0 }
    }
}

impl PointGoalPdExpert {
    /// The action for an oracle observation; errors on a wrong length.
    pub fn act(&self, oracle_obs: &[f32], action: &mut [f32]) -> Result<(), SimError> {
        let expected = Family::POINT_GOAL.oracle_obs_dim();
        if oracle_obs.len() != expected {
            return Err(SimError::BufferLength {
                expected,
                got: oracle_obs.len(),
            });
        }
        if action.len() != ACT_DIM {
            return Err(SimError::BufferLength {
                expected: ACT_DIM,
                got: action.len(),
            });
        }
        for axis in 0..2 {
            let error = oracle_obs[4 + axis] - oracle_obs[axis];
            let command = self.kp * error - self.kd * oracle_obs[2 + axis];
            action[axis] = command.clamp(-1.0, 1.0);
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// The family's declaration (`families.rs` lists it), its constant and its tasks.

/// point-goal: 32 train goals at k pi/16, 16 test goals between them; Figure 2's protocol.
pub(crate) const SPEC: FamilySpec = FamilySpec {
    name: "point-goal",
    obs_dim: POINT_GOAL_OBS_DIM,
    act_dim: POINT_GOAL_ACT_DIM,
    task_dim: 2,
    metric: MetricKind::MinGoalDistance,
    value_name: "goal angle (rad)",
    value_tolerance: TASK_VALUE_TOLERANCE,
    value_key: "goal_angle",
    value_decimals: 4,
    write_parameter: write_goal,
    train_tasks: || goal_train_angles().map(Task::point_goal).collect(),
    test_tasks: || goal_test_angles().map(Task::point_goal).collect(),
    task_from_value: |v| Ok(Task::point_goal(v as f32)),
    nominal_value: None,
    obs_components: &OBS_COMPONENTS,
    eval: EvalDefaults {
        context_sizes: &[1],
        draws: 3,
        rollouts: 10,
        falls_end_episodes: false,
    },
    estimator_accel_std: 2.0,
    view: RunView::GoalPath { xy: 0 },
    make_env: |config| {
        if config.physics != Physics::Rapier {
            return Err(SimError::PhysicsUnavailable {
                physics: config.physics,
                how: "point-goal is a Rapier point mass with no MuJoCo model; run it on Rapier"
                    .into(),
            });
        }
        Ok(Box::new(PointGoalEnv::new(config)))
    },
};

impl Family {
    /// point-goal, declared by this module's `SPEC`.
    pub const POINT_GOAL: Family = Family::of(&SPEC);
}

impl Task {
    /// A point-goal task with its goal at `goal_angle` radians on the radius-2 circle.
    pub fn point_goal(goal_angle: f32) -> Task {
        Task::new(Family::POINT_GOAL, goal_angle as f64)
    }
}

/// Rapier integrates the point's position with the velocity before the step's damping and
/// reports the velocity after it.
const POINT_GOAL_RATE_SCALE: f32 = 1.0 / (1.0 + LINEAR_DAMPING * CONTROL_DT);

/// point-goal: `[x, y, vx, vy]`.
pub(crate) const OBS_COMPONENTS: [ObsComponent; 4] = [
    ObsComponent::Position,
    ObsComponent::Position,
    ObsComponent::Rate {
        of: 0,
        scale: POINT_GOAL_RATE_SCALE,
    },
    ObsComponent::Rate {
        of: 1,
        scale: POINT_GOAL_RATE_SCALE,
    },
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EpisodeMetric;

    fn run_expert(env: &mut PointGoalEnv, task: &Task, seed: u64) -> (f32, Vec<f32>) {
        let expert = PointGoalPdExpert::default();
        let mut oracle = [0.0; OBS_DIM + 2];
        let mut action = [0.0; ACT_DIM];
        let mut metric = EpisodeMetric::new(Family::POINT_GOAL);
        let mut trace = env.reset(task, seed).unwrap().to_vec();
        loop {
            env.oracle_observation(&mut oracle).unwrap();
            expert.act(&oracle, &mut action).unwrap();
            let transition = env.step(&action).unwrap();
            metric.record(&transition.info);
            trace.extend_from_slice(transition.obs);
            trace.push(transition.reward);
            if transition.done {
                return (metric.value(), trace);
            }
        }
    }

    #[test]
    fn scripted_expert_reaches_every_test_goal_within_a_tenth() {
        let mut env = PointGoalEnv::new(EnvConfig::default());
        for (i, task) in Family::POINT_GOAL.test_tasks().iter().enumerate() {
            let (min_distance, _) = run_expert(&mut env, task, i as u64);
            assert!(min_distance < 0.1, "{task}: min distance {min_distance}");
        }
    }

    #[test]
    fn trajectories_are_bit_identical_for_equal_seeds_and_differ_across_seeds() {
        let task = Family::POINT_GOAL.test_tasks()[5];
        let mut env = PointGoalEnv::new(EnvConfig::default());
        let (_, first) = run_expert(&mut env, &task, 7);
        let (_, again) = run_expert(&mut PointGoalEnv::new(EnvConfig::default()), &task, 7);
        let (_, other) = run_expert(&mut env, &task, 8);
        assert_eq!(
            first.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            again.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_ne!(first, other);
    }

    #[test]
    fn bad_actions_are_typed_errors_and_large_actions_are_clipped() {
        let mut env = PointGoalEnv::new(EnvConfig::default());
        assert!(matches!(
            env.step(&[0.0]),
            Err(SimError::ActionLength {
                expected: 2,
                got: 1,
                ..
            })
        ));
        assert!(matches!(
            env.step(&[0.0, f32::NAN]),
            Err(SimError::NonFiniteAction { index: 1, .. })
        ));
        let task = Family::POINT_GOAL.train_tasks()[0];
        env.reset(&task, 1).unwrap();
        let clipped = env.step(&[1.0, -1.0]).unwrap().obs.to_vec();
        env.reset(&task, 1).unwrap();
        let huge = env.step(&[1e6, -1e6]).unwrap().obs.to_vec();
        assert_eq!(clipped, huge);
    }

    #[test]
    fn episode_ends_at_the_horizon_and_then_refuses_steps() {
        let config = EnvConfig {
            horizon: Some(3),
            ..EnvConfig::default()
        };
        let mut env = PointGoalEnv::new(config);
        assert!(!env.step(&[0.0, 0.0]).unwrap().done);
        assert!(!env.step(&[0.0, 0.0]).unwrap().done);
        let last = env.step(&[0.0, 0.0]).unwrap();
        assert!(last.done && last.info.truncated && !last.info.terminated);
        assert_eq!(
            env.step(&[0.0, 0.0]),
            Err(SimError::EpisodeOver { step: 3 })
        );
        assert!(matches!(
            env.reset(&Task::cheetah_vel(1.0), 0),
            Err(SimError::TaskFamilyMismatch { .. })
        ));
    }

    #[test]
    fn force_moves_the_robot_and_damping_bounds_its_speed() {
        let mut env = PointGoalEnv::new(EnvConfig::default());
        for _ in 0..50 {
            env.step(&[1.0, 0.0]).unwrap();
        }
        let vx = env.observation()[2];
        let terminal = MAX_FORCE / (MASS * LINEAR_DAMPING);
        assert!(vx > 0.8 * terminal && vx < 1.2 * terminal, "vx {vx}");
    }
}
