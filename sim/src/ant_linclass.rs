//! ant-linclass: few-shot linear classification by the [`crate::ant`] quadruped (the paper's
//! Table 2, right). A task is a hyperplane through the origin of R^4 (its unit normal w).
//! Each episode the ant starts at (0, 0) and observes, after its own 29 entries, an ordered
//! pair of points of [-1, 1]^4, one on each side of the hyperplane, in random order. It must
//! walk to [`TARGETS`]`[0]` = (1.41, 1.41) when the first point is on the positive side
//! (w . p > 0) and to [`TARGETS`]`[1]` = (-1.41, 1.41) otherwise. The decision is the first
//! target whose [`DECISION_RADIUS`] the torso enters; 50-step episodes, no termination.
//!
//! One demonstration shows one labelled pair, so a learner that never sees w must combine
//! several demonstrations to classify a new pair: contexts of 1 to 8 demos.
//!
//! - Splits: 64 meta-train hyperplanes (seeds 0..64), 32 meta-test ones (seeds 10000..10032);
//!   the task's value is its seed, its parameter (the oracle's) is w.
//! - Reward: 1 per step inside the decision radius of the correct target, else 0 (the
//!   reference's sparse reward; SMILe and Meta-BC never read it).
//! - Metric ([`crate::MetricKind::ClassificationSuccess`]): per step the latched decision,
//!   1 correct, -1 wrong, 0 none yet ([`Decision`]); per episode the success (1 or 0) and
//!   whether no decision was made (a no-op, [`crate::EpisodeMetric::no_op`]).
//! - The expert is scripted ([`scripted_target`]): it classifies with the true w and drives a
//!   learned ant-goal expert to the chosen target ([`goal_expert_input`]), as the paper drove
//!   two of its Ant-goal experts.
//!
//! The reference also appends the two (constant) target positions to the observation; they
//! carry no information, so they are left out.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::ant::AntEpisode;
use crate::error::SimError;
use crate::family::{
    EnvConfig, Environment, EvalDefaults, Family, FamilySpec, MetricKind, RunView, Task, Transition,
};
use crate::render::{Frame, Role, Shape};
use crate::sensing::ObsComponent;
use crate::spec::{LEGGED_ACCEL_STD, seed_of};

/// Default episode length (control steps of 0.05 s), as in the paper.
pub const HORIZON: usize = 50;
/// Dimension of the points to classify, and the task's hyperplane from its seed (in their own
/// module so that `task.rs` needs nothing of this environment).
pub use crate::hyperplane::{POINT_DIM, hyperplane_normal};
/// Observation: the ant's 29 entries ([`crate::ant::obs`]), then the first point, then the
/// second point.
pub const OBS_DIM: usize = crate::ant::OBS_DIM + 2 * POINT_DIM;
/// Index of the first point in the observation (4 entries); the second follows it.
pub const FIRST_POINT: usize = crate::ant::OBS_DIM;
/// Index of the second point in the observation (4 entries).
pub const SECOND_POINT: usize = FIRST_POINT + POINT_DIM;
/// The two targets: `[0]` for "the first point is positive", `[1]` for "negative" (m).
pub const TARGETS: [[f32; 2]; 2] = [[1.41, 1.41], [-1.41, 1.41]];
/// A decision is made when the torso comes within this distance of a target (m).
pub const DECISION_RADIUS: f32 = 0.5;
/// Meta-train hyperplane seeds are `TRAIN_SEED_BASE + i`, i in 0..[`TRAIN_TASKS`].
pub const TRAIN_SEED_BASE: u64 = 0;
/// Meta-test hyperplane seeds are `TEST_SEED_BASE + i`, i in 0..[`TEST_TASKS`].
pub const TEST_SEED_BASE: u64 = 10_000;
/// Number of meta-train tasks (the paper's).
pub const TRAIN_TASKS: u64 = 64;
/// Number of meta-test tasks (the paper's).
pub const TEST_TASKS: u64 = 32;

/// The latched decision, defined beside the metric that decodes it.
pub use crate::env::Decision;

fn dot(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The episode's pair for hyperplane `hyperplane_seed` (unit normal `normal`) and reset seed
/// `seed`: points drawn uniformly from [-1, 1]^4 until one lies on each side, then put in
/// random order. Returns (first, second, whether the first is the positive one). The draws
/// depend on the task as well as the reset seed: with the reset seed alone, every task's
/// episode `seed` would start from the same first point, and demos recorded with seeds
/// 0..16 would show all 64 tasks the same handful of points.
pub fn draw_pair(
    normal: &[f32; POINT_DIM],
    hyperplane_seed: u64,
    seed: u64,
) -> ([f32; POINT_DIM], [f32; POINT_DIM], bool) {
    let task = hyperplane_seed.wrapping_mul(0x9E37_79B9_7F4A_7C15); // golden-ratio mixing
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ task ^ 0x5041_4952_5041_4952); // "PAIRPAIR"
    let (mut positive, mut negative) = (None, None);
    while positive.is_none() || negative.is_none() {
        let p: [f32; POINT_DIM] = std::array::from_fn(|_| rng.random_range(-1.0f32..=1.0));
        let side = dot(normal, &p);
        if side > 0.0 && positive.is_none() {
            positive = Some(p);
        } else if side < 0.0 && negative.is_none() {
            negative = Some(p);
        }
    }
    let (positive, negative) = (positive.unwrap_or_default(), negative.unwrap_or_default());
    if rng.random_bool(0.5) {
        (positive, negative, true)
    } else {
        (negative, positive, false)
    }
}

/// The target the scripted expert walks to, from an oracle observation (observation, then w):
/// [`TARGETS`]`[0]` when the first point is on w's positive side, else `[1]`.
pub fn scripted_target(oracle_obs: &[f32]) -> Result<[f32; 2], SimError> {
    let expected = Family::ANT_LINCLASS.oracle_obs_dim();
    if oracle_obs.len() != expected {
        return Err(SimError::BufferLength {
            expected,
            got: oracle_obs.len(),
        });
    }
    let first = &oracle_obs[FIRST_POINT..FIRST_POINT + POINT_DIM];
    let normal = &oracle_obs[OBS_DIM..];
    Ok(if dot(normal, first) > 0.0 {
        TARGETS[0]
    } else {
        TARGETS[1]
    })
}

/// The scripted expert aims its ant-goal expert at the chosen target times this: a goal
/// further out makes it walk through the decision radius sooner. Tuned on 2026-12-01 with the
/// shipped ant-goal expert on the evaluation of `smile expert --kind scripted-linclass
/// --eval-episodes 10` (1.00 at 1.2), whose 320 episodes are 20 distinct walks (its seeds
/// repeat across tasks). On 320 distinct walks and today's float path (2026-12-07,
/// `docs/results/linclass-walk-end/README.md`): 0.881 / 0.866 / 0.881 / 0.819 / 0.788 at
/// 1.0 / 1.1 / 1.2 / 1.3 / 1.4 (`smile expert --distinct-starts`), flat to 1.2. A failure is a
/// no-op (too slow, stopped short or beside, or past), the wrong target on at most 1 walk in
/// 320. The default of `smile expert --kind scripted-linclass --aim-scale`: the MuJoCo ant-goal
/// expert wants its own (`assets/experts/ant-linclass-mujoco/README.md`).
pub const AIM_SCALE: f32 = 1.2;

/// Writes the ant-goal oracle observation (the ant's 29 entries, then the goal (x, y)) that
/// makes an ant-goal expert walk towards [`scripted_target`], aimed `aim_scale` times as far
/// ([`AIM_SCALE`] by default): how the scripted classifier drives a learned locomotion expert.
/// `out` has length `Family::ANT_GOAL.oracle_obs_dim()`.
pub fn goal_expert_input(
    oracle_obs: &[f32],
    aim_scale: f32,
    out: &mut [f32],
) -> Result<(), SimError> {
    let target = scripted_target(oracle_obs)?;
    let expected = Family::ANT_GOAL.oracle_obs_dim();
    if out.len() != expected {
        return Err(SimError::BufferLength {
            expected,
            got: out.len(),
        });
    }
    let ant = crate::ant::OBS_DIM;
    out[..ant].copy_from_slice(&oracle_obs[..ant]);
    out[ant..].copy_from_slice(&target.map(|t| t * aim_scale));
    Ok(())
}

/// The ant-linclass environment.
pub struct AntLinClassEnv {
    ant: AntEpisode,
    task: Task,
    /// Index into [`TARGETS`] of this episode's correct target.
    correct: usize,
    decision: Decision,
    obs: [f32; OBS_DIM],
}

impl AntLinClassEnv {
    /// An ant-linclass environment on `config.physics` reset to the first train task with
    /// seed 0.
    pub fn new(config: EnvConfig) -> Result<Self, SimError> {
        let task = Family::ANT_LINCLASS.train_tasks()[0];
        let mut env = Self {
            ant: AntEpisode::new(Family::ANT_LINCLASS, config, HORIZON)?,
            task,
            correct: 0,
            decision: Decision::Undecided,
            obs: [0.0; OBS_DIM],
        };
        env.reset(&task, 0)?;
        Ok(env)
    }

    /// Torso (x, y) position (m).
    pub fn torso_xy(&self) -> [f32; 2] {
        self.ant.torso_xy()
    }

    /// This episode's correct target.
    pub fn correct_target(&self) -> [f32; 2] {
        TARGETS[self.correct]
    }

    /// The decision so far.
    pub fn decision(&self) -> Decision {
        self.decision
    }
}

impl Environment for AntLinClassEnv {
    fn family(&self) -> Family {
        Family::ANT_LINCLASS
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
        Family::ANT_LINCLASS.check_task(task)?;
        let (Some(normal), Some(hyperplane_seed)) =
            (task.linclass_normal(), task.hyperplane_seed())
        else {
            return Err(SimError::InvalidTask {
                family: Family::ANT_LINCLASS.name(),
                reason: "not a hyperplane task".into(),
            });
        };
        self.task = *task;
        let (first, second, first_positive) = draw_pair(&normal, hyperplane_seed, seed);
        self.correct = if first_positive { 0 } else { 1 };
        self.decision = Decision::Undecided;
        self.ant.reset(seed);
        self.obs[..FIRST_POINT].copy_from_slice(&self.ant.obs);
        self.obs[FIRST_POINT..SECOND_POINT].copy_from_slice(&first);
        self.obs[SECOND_POINT..].copy_from_slice(&second);
        Ok(&self.obs)
    }

    fn step(&mut self, action: &[f32]) -> Result<Transition<'_>, SimError> {
        let forward_velocity = self.ant.physics_step(action)?;
        self.obs[..FIRST_POINT].copy_from_slice(&self.ant.obs);
        let at_correct = self.ant.torso_distance(TARGETS[self.correct]) <= DECISION_RADIUS;
        if self.decision == Decision::Undecided {
            let at_wrong = self.ant.torso_distance(TARGETS[1 - self.correct]) <= DECISION_RADIUS;
            // The targets are 2.82 apart: the torso is never within 0.5 of both.
            if at_correct {
                self.decision = Decision::Correct;
            } else if at_wrong {
                self.decision = Decision::Wrong;
            }
        }
        let reward = if at_correct { 1.0 } else { 0.0 };
        let metric_sample = self.decision.sample();
        Ok(self
            .ant
            .clock
            .transition(&self.obs, reward, false, metric_sample, forward_velocity))
    }

    fn observation(&self) -> &[f32] {
        &self.obs
    }

    fn frame(&self) -> Frame {
        // The correct target filled, the other as a ring.
        let target = |i: usize| {
            let (center, radius) = (TARGETS[i], DECISION_RADIUS);
            if i == self.correct {
                Shape::Circle {
                    center,
                    radius,
                    role: Role::Goal,
                }
            } else {
                Shape::Ring {
                    center,
                    radius,
                    role: Role::Guide,
                }
            }
        };
        self.ant.frame(vec![target(0), target(1)])
    }
}

// ---------------------------------------------------------------------------------------------
// The family's declaration (`families.rs` lists it), its constant and its tasks.

/// ant-linclass: 64 train and 32 test hyperplane seeds; aggregating demos is what this family
/// tests, so the success is read per context size (1, 2, 4, 8).
pub(crate) const SPEC: FamilySpec = FamilySpec {
    name: "ant-linclass",
    obs_dim: OBS_DIM,
    act_dim: crate::ant::ACT_DIM,
    task_dim: POINT_DIM,
    metric: MetricKind::ClassificationSuccess,
    value_name: "hyperplane seed",
    value_tolerance: 0.0,
    value_key: "hyperplane_seed",
    value_decimals: 0,
    write_parameter: |task, out| out.copy_from_slice(&task.linclass_normal().unwrap_or_default()),
    train_tasks: || {
        (0..TRAIN_TASKS)
            .map(|i| Task::ant_linclass(TRAIN_SEED_BASE + i))
            .collect()
    },
    test_tasks: || {
        (0..TEST_TASKS)
            .map(|i| Task::ant_linclass(TEST_SEED_BASE + i))
            .collect()
    },
    task_from_value: |v| {
        seed_of(v)
            .map(Task::ant_linclass)
            .ok_or("a hyperplane seed must be a non-negative integer")
    },
    nominal_value: None,
    obs_components: &OBS_COMPONENTS,
    eval: EvalDefaults {
        context_sizes: &[1, 2, 4, 8],
        draws: 3,
        rollouts: 5,
        falls_end_episodes: false,
    },
    estimator_accel_std: LEGGED_ACCEL_STD,
    view: RunView::Velocity { target: false },
    make_env: |config| Ok(Box::new(AntLinClassEnv::new(config)?)),
};

impl Family {
    /// ant-linclass, declared by this module's `SPEC`.
    pub const ANT_LINCLASS: Family = Family::of(&SPEC);
}

impl Task {
    /// An ant-linclass task whose hyperplane is drawn from `hyperplane_seed`.
    pub fn ant_linclass(hyperplane_seed: u64) -> Task {
        Task::new(Family::ANT_LINCLASS, hyperplane_seed as f64)
    }

    /// The seed of an ant-linclass task's hyperplane (`None` for other families).
    pub fn hyperplane_seed(&self) -> Option<u64> {
        (self.family() == Family::ANT_LINCLASS).then_some(self.value() as u64)
    }

    /// The unit normal of an ant-linclass task's hyperplane (`None` for other families).
    pub fn linclass_normal(&self) -> Option<[f32; POINT_DIM]> {
        self.hyperplane_seed()
            .map(crate::hyperplane::hyperplane_normal)
    }
}

/// ant-linclass: the ant's entries, then the two points to classify, which the device is given
/// (as data, not measured by a sensor): passed through.
pub(crate) const OBS_COMPONENTS: [ObsComponent; OBS_DIM] = {
    let mut table = [ObsComponent::Direct; OBS_DIM];
    const ANT: [ObsComponent; crate::ant::OBS_DIM] = crate::ant::OBS_COMPONENTS;
    let mut i = 0;
    while i < ANT.len() {
        table[i] = ANT[i];
        i += 1;
    }
    table
};

#[cfg(test)]
mod tests;
