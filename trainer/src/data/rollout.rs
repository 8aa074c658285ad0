//! Episode rollouts of a context-conditioned policy, and the quick deterministic evaluation
//! the meta-learners select their kept weights with.

use sim::{EnvConfig, Environment, EpisodeMetric, MetricKind, Task, TaskDemos, Trajectory};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::error::Result;
use crate::model::MetaPolicy;

/// `true` if `a` is a better value than `b` for a metric of this kind (NaN is never better).
pub fn better(kind: MetricKind, a: f32, b: f32) -> bool {
    if a.is_nan() {
        return false;
    }
    if b.is_nan() {
        return true;
    }
    if kind.lower_is_better() { a < b } else { a > b }
}

/// One step of a rollout as seen by a callback.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    /// Observation before the step.
    pub obs: &'a [f32],
    /// Oracle observation before the step (observation + task parameter).
    pub oracle: &'a [f32],
    /// Action taken (after clipping to [-1, 1]).
    pub action: &'a [f32],
    /// Observation after the step.
    pub next_obs: &'a [f32],
    /// True terminal (not a time-limit truncation).
    pub terminated: bool,
    /// The state and next state as the policy read them, where it reads the plant through
    /// position-only sensing ([`crate::data::sensed_episode`]); `None` otherwise.
    pub sensed: Option<(&'a [f32], &'a [f32])>,
}

/// Outcome of one episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// The family's metric (min distance, mean |v - v*|, return).
    pub metric: f32,
    /// Undiscounted return.
    pub ret: f32,
    /// Steps taken.
    pub steps: usize,
    /// Classification families: whether the episode made no decision (a no-op).
    pub no_op: Option<bool>,
}

/// A policy callback: `act(obs, action)` writes the action for a raw observation.
pub type ActFn<'a> = dyn FnMut(&[f32], &mut [f32]) -> Result<()> + 'a;

/// Runs one episode of `task` from reset seed `seed`; `act(obs, action)` chooses actions and
/// `on_step` sees every transition.
pub fn run_episode(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    act: &mut ActFn<'_>,
    on_step: &mut dyn FnMut(&Step<'_>) -> Result<()>,
) -> Result<Episode> {
    let mut obs = env.reset(task, seed)?.to_vec();
    let mut oracle = vec![0.0f32; env.oracle_obs_dim()];
    let mut action = vec![0.0f32; env.act_dim()];
    let mut metric = EpisodeMetric::new(env.family());
    let (mut ret, mut steps) = (0.0f32, 0usize);
    loop {
        env.oracle_observation(&mut oracle)?;
        act(&obs, &mut action)?;
        for a in action.iter_mut() {
            *a = a.clamp(-1.0, 1.0);
        }
        let tr = env.step(&action)?;
        metric.record(&tr.info);
        ret += tr.reward;
        steps += 1;
        let done = tr.done;
        on_step(&Step {
            obs: &obs,
            oracle: &oracle,
            action: &action,
            next_obs: tr.obs,
            terminated: tr.info.terminated,
            sensed: None,
        })?;
        obs.copy_from_slice(tr.obs);
        if done {
            return Ok(Episode {
                metric: metric.value(),
                ret,
                steps,
                no_op: metric.no_op(),
            });
        }
    }
}

/// How a meta-learner's held-out evaluation draws its contexts and rollouts: its
/// configuration's `eval_contexts`, `eval_context_size` and `eval_episodes`, the same keys in
/// SMILe's and Meta-BC's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeldOut {
    /// Context draws per task.
    pub contexts: usize,
    /// Trajectories in a context (at most the task's demos).
    pub context_size: usize,
    /// Rollouts per context.
    pub episodes: usize,
}

impl HeldOut {
    /// Refuses a zero (or absurd) count, naming its configuration key.
    pub(crate) fn check(&self) -> Result<()> {
        crate::io::require_positive(&[
            ("eval_contexts", self.contexts as u64),
            ("eval_context_size", self.context_size as u64),
            ("eval_episodes", self.episodes as u64),
        ])
    }
}

/// Mean metric of deterministic rollouts of `mp` on `tasks`: per task, `protocol.contexts`
/// draws of `protocol.context_size` context trajectories (draw d: trajectories d*k .. d*k + k,
/// wrapping) and `protocol.episodes` rollouts each; z = posterior mean.
pub fn quick_eval(
    mp: &MetaPolicy,
    tasks: &[TaskDemos],
    protocol: HeldOut,
    env_cfg: EnvConfig,
) -> Result<f32> {
    let HeldOut {
        contexts,
        context_size,
        episodes,
    } = protocol;
    if tasks.is_empty() {
        return Ok(f32::NAN);
    }
    let mut env = sim::make_env(mp.family, env_cfg)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    use rand::SeedableRng;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for td in tasks {
        let trajs: Vec<&Trajectory> = td.trajectories.iter().filter(|t| !t.is_empty()).collect();
        if trajs.is_empty() {
            return Err(crate::error::Error::Data(format!(
                "held-out task {} has no demos to form a context",
                td.task.label()
            )));
        }
        let k = context_size.clamp(1, trajs.len());
        for d in 0..contexts.max(1) {
            // Context d: the k trajectories from d * k on, in order (wrapping around).
            let context: Vec<&Trajectory> =
                (0..k).map(|j| trajs[(d * k + j) % trajs.len()]).collect();
            let z = mp.latent(&context)?;
            for e in 0..episodes.max(1) {
                let seed = sim::seeds::VALIDATION_SEED + (d * 1000 + e) as u64;
                let ep = run_episode(
                    env.as_mut(),
                    &td.task,
                    seed,
                    &mut |o, a| {
                        a.copy_from_slice(&mp.act(o, &z, true, &mut rng)?);
                        Ok(())
                    },
                    &mut |_| Ok(()),
                )?;
                sum += ep.metric as f64;
                n += 1;
            }
        }
    }
    Ok((sum / n as f64) as f32)
}

/// Offset of the action-noise streams' seeds from their episodes' seeds.
const ACTION_NOISE_SEED_OFFSET: u64 = 500_000_000;

/// Gaussian action noise of one episode (`eval::Protocol::action_noise`, `evaluate_under_noise`); none at sigma 0.
pub struct ActionNoise {
    sigma: f32,
    rng: ChaCha8Rng,
}

impl ActionNoise {
    /// Noise of standard deviation `sigma` for the episode of reset seed `seed`.
    pub fn new(sigma: f32, seed: u64) -> Self {
        Self {
            sigma,
            rng: ChaCha8Rng::seed_from_u64(ACTION_NOISE_SEED_OFFSET + seed),
        }
    }

    /// Adds sigma N(0, 1) to every entry of `action` (the plant clips afterwards).
    pub fn add_to(&mut self, action: &mut [f32]) {
        if self.sigma > 0.0 {
            for a in action {
                let n: f32 = StandardNormal.sample(&mut self.rng);
                *a += self.sigma * n;
            }
        }
    }
}
