//! **reach-line**: a task family written outside `sim`, as a user's crate would write one.
//!
//! A cart on a rail (its own plant: a damped double integrator, integrated here) must stop at a
//! target position it does not observe; each task is one target in [-1, 1]. The whole family is
//! this file: the plant and its environment ([`ReachLineEnv`], an [`Environment`]), the
//! declaration ([`SPEC`], a [`FamilySpec`]), its handle ([`REACH_LINE`]) and a scripted expert
//! that reads the target from the oracle observation ([`expert`]). One call makes its name
//! known to every parser (configurations, demo files, policy files):
//!
//! ```
//! let family = reach_line::register().unwrap();
//! assert_eq!("reach-line".parse::<sim::Family>().unwrap(), family);
//! ```
//!
//! Then the library treats it like the paper's families: [`record_demos`] writes `sim`'s demo
//! format, and `trainer::run::train` meta-trains Meta-BC or SMILe on those demos from a
//! configuration that says `env = "reach-line"` (`tests/train.rs` does both).
#![warn(missing_docs)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::render::{Frame, Role, Shape, View};
use sim::{
    DatasetError, DemoDataset, EnvConfig, Environment, EvalDefaults, Family, FamilySpec,
    MetricKind, ObsComponent, RunView, SimError, Split, StepInfo, Task, TaskDemos, Transition,
};

/// Observation: the cart's position and velocity. The target is not observed.
pub const OBS_DIM: usize = 2;
/// Action: one force along the rail, in units of [`MAX_FORCE`].
pub const ACT_DIM: usize = 1;
/// Episode length in control steps.
pub const HORIZON: usize = 60;
/// Seconds per control step (one integration step).
pub const CONTROL_DT: f32 = 0.05;
/// Force (N) an action of 1 produces on the 1 kg cart.
pub const MAX_FORCE: f32 = 4.0;
/// Viscous damping of the rail (1/s).
pub const DAMPING: f32 = 1.0;
/// Initial position and velocity are drawn uniformly from +-this.
pub const RESET_NOISE: f32 = 0.05;
/// Weight of the action cost in the reward `-distance - ACTION_COST * a^2`.
pub const ACTION_COST: f32 = 0.01;

/// reach-line: 16 train targets -1..=1 evenly, 15 test targets halfway between them; one
/// demo per context, three context draws of five episodes per test task.
pub static SPEC: FamilySpec = FamilySpec {
    name: "reach-line",
    obs_dim: OBS_DIM,
    act_dim: ACT_DIM,
    task_dim: 1,
    metric: MetricKind::MinGoalDistance,
    value_name: "target position (m)",
    value_key: "target",
    value_decimals: 4,
    write_parameter: |task, out| out[0] = task.value() as f32,
    value_tolerance: sim::TASK_VALUE_TOLERANCE,
    train_tasks: || {
        (0..16)
            .map(|k| target(-1.0 + 2.0 * k as f32 / 15.0))
            .collect()
    },
    test_tasks: || {
        (0..15)
            .map(|k| target(-1.0 + (2 * k + 1) as f32 / 15.0))
            .collect()
    },
    task_from_value: |v| {
        if v.abs() <= 2.0 {
            Ok(target(v as f32))
        } else {
            Err("a target lies on the rail, within +-2 m")
        }
    },
    nominal_value: None,
    obs_components: &[
        ObsComponent::Position,
        ObsComponent::Rate { of: 0, scale: 1.0 },
    ],
    eval: EvalDefaults {
        context_sizes: &[1],
        draws: 3,
        rollouts: 5,
        falls_end_episodes: false,
    },
    estimator_accel_std: 2.0,
    view: RunView::Velocity { target: false },
    make_env: |config| Ok(Box::new(ReachLineEnv::new(config))),
};

/// The family's handle.
pub const REACH_LINE: Family = Family::of(&SPEC);

/// Makes `reach-line` known by its name (configurations, demo files, policy files, flags).
/// Idempotent.
pub fn register() -> Result<Family, SimError> {
    REACH_LINE.register()
}

/// The task whose target is at `position` metres.
pub fn target(position: f32) -> Task {
    Task::new(REACH_LINE, position as f64)
}

/// The cart on its rail, reaching the current task's target.
pub struct ReachLineEnv {
    task: Task,
    horizon: usize,
    step: usize,
    obs: [f32; OBS_DIM],
}

impl ReachLineEnv {
    /// An environment reset to the first train target with seed 0.
    pub fn new(config: EnvConfig) -> Self {
        let task = REACH_LINE.train_tasks()[0];
        let mut env = Self {
            task,
            horizon: config.horizon.unwrap_or(HORIZON),
            step: 0,
            obs: [0.0; OBS_DIM],
        };
        env.place(&task, 0);
        env
    }

    fn place(&mut self, task: &Task, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut noise = || rng.random_range(-RESET_NOISE..=RESET_NOISE);
        self.obs = [noise(), noise()];
        self.task = *task;
        self.step = 0;
    }

    fn target(&self) -> f32 {
        self.task.value() as f32
    }
}

impl Environment for ReachLineEnv {
    fn family(&self) -> Family {
        REACH_LINE
    }

    fn control_dt(&self) -> f32 {
        CONTROL_DT
    }

    fn horizon(&self) -> usize {
        self.horizon
    }

    fn task(&self) -> &Task {
        &self.task
    }

    fn reset(&mut self, task: &Task, seed: u64) -> Result<&[f32], SimError> {
        REACH_LINE.check_task(task)?;
        self.place(task, seed);
        Ok(&self.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError> {
        if self.step >= self.horizon {
            return Err(SimError::EpisodeOver { step: self.step });
        }
        let [force] = <[f32; ACT_DIM]>::try_from(action).map_err(|_| SimError::ActionLength {
            family: REACH_LINE.name(),
            expected: ACT_DIM,
            got: action.len(),
        })?;
        if !force.is_finite() {
            return Err(SimError::NonFiniteAction {
                index: 0,
                value: force,
            });
        }
        let force = force.clamp(-1.0, 1.0);
        // Semi-implicit Euler: the velocity first, the position with the new velocity.
        let [x, v] = self.obs;
        let v = v + CONTROL_DT * (MAX_FORCE * force - DAMPING * v);
        self.obs = [x + CONTROL_DT * v, v];
        self.step += 1;
        let distance = (self.obs[0] - self.target()).abs();
        let truncated = self.step == self.horizon;
        Ok(Transition {
            obs: &self.obs,
            reward: -distance - ACTION_COST * force * force,
            done: truncated,
            info: StepInfo {
                step: self.step,
                terminated: false,
                truncated,
                metric_sample: distance,
                forward_velocity: v,
            },
        })
    }

    fn observation(&self) -> &[f32] {
        &self.obs
    }

    fn frame(&self) -> Frame {
        Frame {
            view: View::Top,
            time: self.step as f32 * CONTROL_DT,
            shapes: vec![
                Shape::Circle {
                    center: [self.target(), 0.0],
                    radius: 0.1,
                    role: Role::Goal,
                },
                Shape::Circle {
                    center: [self.obs[0], 0.0],
                    radius: 0.08,
                    role: Role::Robot,
                },
            ],
        }
    }
}

/// The scripted expert: a PD controller on the oracle observation `[x, v, target]`.
pub fn expert(oracle_obs: &[f32], action: &mut [f32]) {
    const KP: f32 = 3.0;
    const KD: f32 = 1.0;
    let [x, v, target] = [oracle_obs[0], oracle_obs[1], oracle_obs[2]];
    action[0] = (KP * (target - x) - KD * v).clamp(-1.0, 1.0);
}

/// `per_task` expert demos of every task of `split`, episode `j` reset with seed `seed + j`,
/// in `sim`'s demo format.
pub fn record_demos(split: Split, per_task: usize, seed: u64) -> Result<DemoDataset, DatasetError> {
    let mut env = ReachLineEnv::new(EnvConfig::default());
    let mut demos = DemoDataset::new(REACH_LINE, split, "scripted-pd");
    for task in REACH_LINE.tasks(split) {
        let trajectories = (0..per_task as u64)
            .map(|j| sim::record_trajectory(&mut env, &task, seed + j, expert))
            .collect::<Result<_, _>>()?;
        demos.tasks.push(TaskDemos { task, trajectories });
    }
    Ok(demos)
}
