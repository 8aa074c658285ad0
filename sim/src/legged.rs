//! cheetah-vel and walker-dyn: the planar legged robots as [`Environment`]s.

use crate::env::{EpisodeClock, clip_action};
use crate::error::SimError;
use crate::family::{EnvConfig, Environment, Family, Task};
use crate::kinds::Physics;
use crate::planar::{ACT_DIM, OBS_DIM};
use crate::plant::{Plant, Robot, TorsoPose};
use crate::render::{Frame, Role, Shape, View};

/// Default cheetah-vel episode length (control steps of 0.05 s).
pub const CHEETAH_HORIZON: usize = 1000;
/// cheetah-vel reward weight of ||a||^2.
pub const CHEETAH_ACTION_COST: f32 = 0.05;
/// Default walker-dyn episode length (control steps of 0.01 s).
pub const WALKER_HORIZON: usize = 1000;
/// walker-dyn reward weight of ||a||^2.
pub const WALKER_ACTION_COST: f32 = 1e-3;
/// walker-dyn reward per step alive.
pub const WALKER_ALIVE_BONUS: f32 = 1.0;
/// walker-dyn is healthy while the torso height is inside this range (m) ...
pub const WALKER_HEALTHY_HEIGHT: [f32; 2] = [0.8, 2.0];
/// ... and the torso tilt is below this (rad).
pub const WALKER_HEALTHY_ANGLE: f32 = 1.0;
/// walker-dyn observed velocities are clipped to +-this (as in Gymnasium).
pub const WALKER_VELOCITY_CLIP: f32 = 10.0;

/// A planar legged robot with its task: the cheetah-vel or the walker-dyn environment, on
/// either physics backend.
pub struct PlanarLeggedEnv {
    family: Family,
    plant: Box<dyn Plant>,
    physics: Physics,
    task: Task,
    config: EnvConfig,
    clock: EpisodeClock,
    /// Observed velocities are clipped to +-this (the walker's, as in Gymnasium; none for the
    /// cheetah).
    velocity_clip: f32,
    obs: [f32; OBS_DIM],
    action: [f32; ACT_DIM],
}

/// The cheetah-vel environment.
pub type CheetahVelEnv = PlanarLeggedEnv;
/// The walker-dyn environment.
pub type WalkerDynEnv = PlanarLeggedEnv;

impl PlanarLeggedEnv {
    /// A cheetah-vel environment on `config.physics`, reset to the first train velocity with
    /// seed 0.
    pub fn cheetah(config: EnvConfig) -> Result<Self, SimError> {
        Self::build(
            Family::CHEETAH_VEL,
            Robot::HalfCheetah,
            CHEETAH_HORIZON,
            f32::INFINITY,
            config,
        )
    }

    /// A walker-dyn environment on `config.physics`, reset to the first train dynamics with
    /// seed 0.
    pub fn walker(config: EnvConfig) -> Result<Self, SimError> {
        Self::build(
            Family::WALKER_DYN,
            Robot::Walker2d,
            WALKER_HORIZON,
            WALKER_VELOCITY_CLIP,
            config,
        )
    }

    fn build(
        family: Family,
        robot: Robot,
        horizon: usize,
        velocity_clip: f32,
        config: EnvConfig,
    ) -> Result<Self, SimError> {
        let task = family.train_tasks()[0];
        let mut plant = robot.plant(config.physics)?;
        plant.reset(0, task.walker_dynamics().as_ref());
        let mut env = Self {
            family,
            plant,
            physics: config.physics,
            task,
            config,
            clock: EpisodeClock::new(config.horizon.unwrap_or(horizon)),
            velocity_clip,
            obs: [0.0; OBS_DIM],
            action: [0.0; ACT_DIM],
        };
        env.observe();
        Ok(env)
    }

    fn observe(&mut self) {
        let clip = self.velocity_clip;
        self.plant.observe(&mut self.obs, clip);
    }

    /// Torso x position (m); not part of the observation.
    pub fn torso_x(&self) -> f32 {
        self.plant.torso().position[0]
    }

    fn walker_healthy(&self) -> bool {
        let TorsoPose {
            position: [_, _, z],
            pitch,
        } = self.plant.torso();
        z > WALKER_HEALTHY_HEIGHT[0]
            && z < WALKER_HEALTHY_HEIGHT[1]
            && pitch.abs() < WALKER_HEALTHY_ANGLE
    }
}

impl Environment for PlanarLeggedEnv {
    fn family(&self) -> Family {
        self.family
    }

    fn physics(&self) -> Physics {
        self.physics
    }

    fn control_dt(&self) -> f32 {
        self.plant.control_dt()
    }

    fn horizon(&self) -> usize {
        self.clock.horizon
    }

    fn task(&self) -> &Task {
        &self.task
    }

    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError> {
        self.family.check_task(task)?;
        self.plant.reset(seed, task.walker_dynamics().as_ref());
        self.task = *task;
        self.clock.restart();
        self.observe();
        Ok(&self.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<crate::family::Transition<'_>, SimError> {
        self.clock.ensure_running()?;
        clip_action(self.family, action, &mut self.action)?;
        let x_before = self.torso_x();
        self.plant.step(&self.action);
        if self.plant.diverged() {
            self.clock.over = true;
            return Err(SimError::PhysicsDiverged {
                family: self.family.name(),
                step: self.clock.step,
            });
        }
        self.observe();
        let forward_velocity = (self.torso_x() - x_before) / self.control_dt();
        let effort: f32 = self.action.iter().map(|a| a * a).sum();
        let (reward, metric_sample, terminated) = match self.task.target_velocity() {
            Some(target_velocity) => {
                let error = (forward_velocity - target_velocity).abs();
                (-error - CHEETAH_ACTION_COST * effort, error, false)
            }
            None => {
                let reward = forward_velocity + WALKER_ALIVE_BONUS - WALKER_ACTION_COST * effort;
                let fell = self.config.healthy_termination && !self.walker_healthy();
                (reward, reward, fell)
            }
        };
        Ok(self.clock.transition(
            &self.obs,
            reward,
            terminated,
            metric_sample,
            forward_velocity,
        ))
    }

    fn observation(&self) -> &[f32] {
        &self.obs
    }

    fn frame(&self) -> Frame {
        let x = self.torso_x();
        let mut shapes = vec![Shape::Capsule {
            a: [x - 3.0, 0.0],
            b: [x + 3.0, 0.0],
            radius: 0.01,
            role: Role::Ground,
        }];
        shapes.extend(self.plant.shapes());
        Frame {
            view: View::Side,
            time: self.clock.step as f32 * self.control_dt(),
            shapes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EpisodeMetric;

    fn config(horizon: usize) -> EnvConfig {
        EnvConfig {
            horizon: Some(horizon),
            ..EnvConfig::default()
        }
    }

    /// Open-loop trot: back leg joints lead the front leg by half a period.
    fn trot(step: usize, dt: f32) -> [f32; 6] {
        let phase = 2.0 * std::f32::consts::PI * step as f32 * dt;
        let pi = std::f32::consts::PI;
        [0.0, -0.5, -1.0, pi, pi - 0.5, pi - 1.0].map(|offset| 0.6 * (phase + offset).sin())
    }

    #[test]
    fn open_loop_gait_moves_the_cheetah_forward_upright() {
        let mut env = PlanarLeggedEnv::cheetah(config(200)).unwrap();
        let task = Task::cheetah_vel(1.0);
        env.reset(&task, 1).unwrap();
        let mut metric = EpisodeMetric::new(Family::CHEETAH_VEL);
        for step in 0.. {
            let transition = env.step(&trot(step, env.control_dt())).unwrap();
            metric.record(&transition.info);
            assert!(transition.obs[1].abs() < 1.0, "tilted at step {step}");
            if transition.done {
                break;
            }
        }
        assert!(
            env.torso_x() > 3.0,
            "moved only {} m in 10 s",
            env.torso_x()
        );
        assert!(metric.value() < 1.0, "mean |v - 1| = {}", metric.value());
        env.reset(&task, 1).unwrap();
        for _ in 0..200 {
            env.step(&[0.0; 6]).unwrap();
        }
        assert!(env.torso_x().abs() < 0.3, "drifted without actions");
    }

    fn walker_steps_upright(env: &mut PlanarLeggedEnv, task: &Task, gains: (f32, f32)) -> usize {
        let mut obs = env.reset(task, 1).unwrap().to_vec();
        for step in 1.. {
            let mut action = [0.0; 6];
            for (j, a) in action.iter_mut().enumerate() {
                *a = -gains.0 * obs[2 + j] - gains.1 * obs[11 + j];
            }
            let transition = env.step(&action).unwrap();
            obs.copy_from_slice(transition.obs);
            if transition.done {
                return step;
            }
        }
        unreachable!()
    }

    #[test]
    fn joint_pd_keeps_the_walker_up_and_without_it_it_falls() {
        // MuJoCo's walker2d.xml under the same PD (gains 1, 0.1; frame skip 5) stands 117-1000
        // steps over seeds 0-5 and falls within 76-162 steps without it.
        let mut env = PlanarLeggedEnv::walker(config(1000)).unwrap();
        let (mut passive_total, mut held_total) = (0, 0);
        for task in Family::WALKER_DYN.train_tasks().iter().take(6) {
            let passive = walker_steps_upright(&mut env, task, (0.0, 0.0));
            let held = walker_steps_upright(&mut env, task, (1.0, 0.1));
            eprintln!("{task}: passive {passive}, held {held}");
            assert!(
                passive < 200,
                "{task}: passive walker stood {passive} steps"
            );
            passive_total += passive;
            held_total += held;
        }
        assert!(
            held_total > 2 * passive_total,
            "PD walker stood {held_total} steps in all, passive {passive_total}"
        );
    }

    #[test]
    fn termination_can_be_switched_off() {
        let mut env = PlanarLeggedEnv::walker(EnvConfig {
            horizon: Some(150),
            healthy_termination: false,
            ..EnvConfig::default()
        })
        .unwrap();
        let task = Family::WALKER_DYN.test_tasks()[0];
        assert_eq!(walker_steps_upright(&mut env, &task, (0.0, 0.0)), 150);
    }

    #[test]
    fn legged_trajectories_are_bit_identical_per_seed_and_dynamics_differ_per_task() {
        let run = |family: Family, task: Task, seed: u64| {
            let mut env = crate::env::make_env(family, config(60)).unwrap();
            let mut trace = env.reset(&task, seed).unwrap().to_vec();
            for step in 0..60 {
                let t = env.step(&trot(step, 0.05)).unwrap();
                trace.extend_from_slice(t.obs);
                trace.push(t.reward);
                if t.done {
                    break;
                }
            }
            trace.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        };
        // Seed 4 twice is the same; another seed (cheetah) or task (walker) is not.
        let cheetah = Task::cheetah_vel(2.0);
        for (family, task, (other_task, other_seed)) in [
            (Family::CHEETAH_VEL, cheetah, (cheetah, 5)),
            (
                Family::WALKER_DYN,
                Task::walker_dyn(3),
                (Task::walker_dyn(4), 4),
            ),
        ] {
            assert_eq!(run(family, task, 4), run(family, task, 4), "{family:?}");
            assert_ne!(
                run(family, task, 4),
                run(family, other_task, other_seed),
                "{family:?}"
            );
        }
    }

    #[test]
    fn the_nominal_walker_task_builds_the_unmodified_robot() {
        use crate::planar::Scaling;
        let s = Scaling::of(Task::walker_nominal().walker_dynamics().as_ref());
        let n = Scaling::NOMINAL;
        assert_eq!(
            (s.mass, s.inertia, s.friction, s.damping),
            (n.mass, n.inertia, n.friction, n.damping)
        );
        let d = Scaling::of(
            Task::walker_dyn(crate::task::WALKER_TEST_SEED_BASE)
                .walker_dynamics()
                .as_ref(),
        );
        assert_ne!(d.mass, n.mass);
    }

    #[test]
    fn observations_have_the_declared_shape_and_hide_the_torso_x() {
        let mut env = PlanarLeggedEnv::cheetah(config(50)).unwrap();
        let obs = env.reset(&Task::cheetah_vel(0.5), 0).unwrap();
        assert_eq!(obs.len(), OBS_DIM);
        assert!((obs[0] - 0.7).abs() < 0.15, "torso height {}", obs[0]);
        let mut oracle = vec![0.0; env.oracle_obs_dim()];
        env.oracle_observation(&mut oracle).unwrap();
        assert_eq!(oracle[OBS_DIM], 0.5);
        assert!(matches!(
            env.reset(&Task::walker_dyn(0), 0),
            Err(SimError::TaskFamilyMismatch { .. })
        ));
        assert!(matches!(
            env.step(&[0.0, 0.0, 0.0, f32::INFINITY, 0.0, 0.0]),
            Err(SimError::NonFiniteAction { index: 3, .. })
        ));
    }
}
