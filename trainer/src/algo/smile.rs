//! SMILe: Scalable Meta Inverse RL (Ghasemipour et al. 2019), state-action and state-only.
//!
//! A context-conditioned AIRL discriminator `D(x, z)` with `x = [norm(s), a]` (or
//! `[norm(s), norm(s')]` state-only) and `z ~ q(z | c)` from the context encoder of
//! [`crate::model::ContextEncoder`]; a SAC policy `pi(a | [norm(s), z])` trained on the reward the
//! discriminator gives. Schedule and batches follow the reference (`docs/reference/smile-reference.md` §1-2):
//!
//! * warm start: one rollout of the untrained policy in every training task;
//! * each iteration (section 3.5, Algorithm 1): `m = rollouts_per_iter` rollouts (a uniform
//!   task, a context of k in 1..=4 of its demos, z sampled, stochastic actions) into that
//!   task's replay buffer, then `d = updates_per_iter` x (1 discriminator+encoder step, 1 SAC
//!   step). With `learner_threads >= 2` the rollouts run beside the pairs and reach the replays
//!   after them ([`Smile::iteration`], module `rollouts`).
//!
//! Discriminator step, on `tasks_per_batch` distinct tasks, each with a fresh context and its
//! z (with gradient into the encoder) attached to `disc_per_task` expert transitions (label 1,
//! the task's demos) and `disc_per_task` policy transitions (label 0, the task's replay):
//!
//! ```text
//! l = clamp(D(x, z), -10, 10)                                  (logit)
//! L_bce = mean[ softplus(l) - y l ]                            (BCE with logits)
//! x~ = u x_E + (1 - u) x_pi,  u ~ U(0, 1) per sample,  z detached
//! L_gp = mean[ (|| d D(x~, z) / d x~ || - 1)^2 ]               (WGAN-GP form)
//! L_D = L_bce + lambda_gp L_gp
//! ```
//! The encoder is trained only through this loss (own Adam, betas (0.9, 0.999)); the
//! discriminator's Adam uses betas (0, 0.999).
//!
//! SAC step on `tasks_per_batch` fresh tasks/contexts, `sac_per_task` replay transitions each,
//! policy input `[norm(s), z]` with z **detached** (SAC never updates the encoder), reward
//! `r = clamp(D(x, z), -10, 10)` (= log D - log(1 - D)), multiplied by `sac.reward_scale`.
//! SAC is v2 (twin Q, targets, learned temperature), the reference's accepted substitute.
//!
//! SMILe + BC (`bc_weight > 0`, beyond the paper): the SAC step's actor loss also clones the
//! demos of the batch's tasks, `sac_per_task` expert transitions `(s_E, a_E)` per task with
//! that task's detached z, the same z its replay rows use:
//!
//! ```text
//! L_pi += w(u) mean ||tanh(mu([norm(s_E), z])) - a_E||^2,
//! w(u) = bc_weight (1 - u / bc_decay_updates)+   (or bc_weight when bc_decay_updates = 0)
//! ```

use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::Environment;

mod config;
mod disc;
mod fit;
mod persist;
mod rollouts;

pub use config::SmileConfig;
pub(crate) use disc::disc_grads;
pub use disc::{DiscBatch, DiscLearner, disc_update};
pub use fit::train;

use crate::algo::sac::{BcTerm, Sac, SacStats};
use crate::data::{
    Batch, BatchVecs, MetaData, TaskReplay, distinct_tasks, quick_eval, run_episode, sample_context,
};
use crate::error::Result;
use crate::model::scalar;
use crate::model::{
    ContextEncoder, ContextSpec, DiscInput, DiscStats, Discriminator, Input, MetaPolicy,
    SharedCols, TrainingMark, policy_input,
};
use crate::optim::{Adam, AdamConfig};
use crate::threads::LearnerPool;
use rollouts::{PlannedEpisode, RolloutJob};

/// A SMILe run: data, networks, optimisers, replay, counters.
pub struct Smile {
    cfg: SmileConfig,
    data: MetaData,
    env: Box<dyn Environment>,
    /// The context encoder (trained by the discriminator loss only).
    pub encoder: ContextEncoder,
    /// The discriminator on `[x, z]`.
    pub disc: Discriminator,
    /// The SAC agent on `[norm(s), z]`.
    pub sac: Sac,
    disc_opt: Adam,
    enc_opt: Adam,
    replay: TaskReplay,
    rng: ChaCha8Rng,
    updates: u64,
    env_steps: u64,
    /// CPU-seconds its training processes have used so far, over every resume (`cpu_budget_s`).
    cpu_s: f64,
    episodes: u64,
    best: f32,
    /// The learner threads of `learner_threads > 1`, started at the first update pair.
    pool: Option<LearnerPool>,
    /// The environment the rollouts beside the pairs step (`learner_threads > 1`; it travels
    /// with each rollout job and comes back with its result).
    rollout_env: Option<Box<dyn Environment>>,
}

/// What one [`Smile::iteration`] did.
#[derive(Debug, Clone, Copy)]
pub struct IterationReport {
    /// The last update pair's statistics (discriminator, SAC, reward mean), if a pair ran.
    pub last: Option<(DiscStats, SacStats, f32)>,
    /// Seconds the learner's thread spent on rollouts: running them (one learner thread), or
    /// planning them and waiting for them after the pairs (two or more).
    pub rollout_s: f64,
}

impl Smile {
    /// A fresh run on `data` (the meta-train demos; see [`MetaData::from_dataset`]).
    pub fn new(cfg: SmileConfig, data: MetaData) -> Result<Self> {
        cfg.validate()?;
        let family = cfg.env;
        data.ensure_fits(family, cfg.physics)?;
        let env = sim::make_env(family, cfg.rollout_env_config())?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let (od, ad) = (family.obs_dim(), family.act_dim());
        let encoder = ContextEncoder::new(od, ad, cfg.context.clone(), &mut rng)?;
        let input = if cfg.context.state_only {
            DiscInput::StateOnly
        } else {
            DiscInput::StateAction
        };
        let disc = Discriminator::new(
            od,
            ad,
            cfg.context.z_dim,
            &cfg.disc_hidden,
            input,
            cfg.logit_clamp,
            &mut rng,
        )?;
        let sac = Sac::new(od + cfg.context.z_dim, ad, cfg.sac.clone(), &mut rng)?;
        let disc_opt = Adam::new(
            disc.vars().to_vec(),
            AdamConfig {
                beta1: 0.0,
                ..AdamConfig::with_lr(cfg.disc_lr)
            },
        );
        let enc_opt = Adam::new(encoder.vars(), AdamConfig::with_lr(cfg.enc_lr));
        let replay = TaskReplay::new(data.train.len(), od, ad, cfg.replay_per_task)?;
        Ok(Self {
            cfg,
            data,
            env,
            encoder,
            disc,
            sac,
            disc_opt,
            enc_opt,
            replay,
            rng,
            updates: 0,
            env_steps: 0,
            cpu_s: 0.0,
            episodes: 0,
            best: f32::NAN,
            pool: None,
            rollout_env: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SmileConfig {
        &self.cfg
    }

    /// Sets the compute budget of the next [`train`] call (`cpu_budget_s`, 0: none); the
    /// one setting besides `total_updates` that a resumed run may change.
    pub fn set_cpu_budget(&mut self, secs: f64) -> Result<()> {
        let mut cfg = self.cfg.clone();
        cfg.cpu_budget_s = secs;
        cfg.validate()?;
        self.cfg = cfg;
        Ok(())
    }

    /// Update pairs done.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Environment steps taken.
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// The data this run trains on.
    pub fn data(&self) -> &MetaData {
        &self.data
    }

    /// The training mark of a policy saved now.
    fn mark(&self, finished: bool) -> TrainingMark {
        TrainingMark {
            updates: self.updates,
            total_updates: self.cfg.total_updates,
            finished,
        }
    }

    /// The current policy as a [`MetaPolicy`] (shares the live weights).
    pub fn meta_policy(&self) -> MetaPolicy {
        MetaPolicy {
            family: self.data.family,
            physics: self.cfg.physics,
            algo: self.cfg.algo_name().into(),
            norm: self.data.norm.clone(),
            encoder: self.encoder.clone(),
            policy: self.sac.actor.clone(),
        }
    }

    /// A fresh context of training task `ti` and its sampled z (a rollout's first draws).
    fn rollout_z(&mut self, ti: usize) -> Result<Vec<f32>> {
        let spec = sample_context(&self.data.train[ti], self.cfg.context_draw(), &mut self.rng);
        let b = self.encoder.batch(&self.data.norm, &[spec])?;
        Ok(self
            .encoder
            .z(&b, true, &mut self.rng)?
            .detach()
            .flatten_all()?
            .to_vec1::<f32>()?)
    }

    /// The reset seed of the next training episode.
    fn episode_seed(&self) -> u64 {
        self.cfg
            .seed
            .wrapping_mul(sim::seeds::TRAINING_SEED_STRIDE)
            .wrapping_add(self.episodes)
    }

    /// One rollout in training task `ti` with a sampled context and z; stored in its replay.
    pub fn rollout(&mut self, ti: usize) -> Result<()> {
        let z = self.rollout_z(ti)?;
        let task = self.data.train[ti].task;
        let seed = self.episode_seed();
        let (actor, norm, rng) = (&self.sac.actor, &self.data.norm, &mut self.rng);
        let replay = self.replay.task_mut(ti);
        let ep = run_episode(
            self.env.as_mut(),
            &task,
            seed,
            &mut |o, a| {
                let mut x = norm.apply(o);
                x.extend_from_slice(&z);
                a.copy_from_slice(&actor.act(&x, false, rng)?);
                Ok(())
            },
            &mut |st| replay.push(st.obs, st.action, 0.0, st.next_obs, st.terminated),
        )?;
        self.env_steps += ep.steps as u64;
        self.episodes += 1;
        Ok(())
    }

    /// One iteration of Algorithm 1: `rollouts_per_iter` rollouts, each in a uniform training
    /// task, then `updates_per_iter` update pairs (fewer where `total_updates` ends the run);
    /// `on_pair` sees the update count after every pair. With `learner_threads >= 2` the
    /// rollouts run beside the pairs on the learner pool and enter the replays after them
    /// (module `rollouts` says how, and the one way that differs from one thread).
    pub fn iteration(&mut self, on_pair: &mut dyn FnMut(u64)) -> Result<IterationReport> {
        let (m, t0) = (self.cfg.rollouts_per_iter, std::time::Instant::now());
        let in_flight = if self.cfg.learner_threads >= 2 && m > 0 {
            let job = self.plan_rollouts(m)?;
            let pool = match self.pool.take() {
                Some(p) => p,
                None => LearnerPool::new(self.cfg.learner_threads)?,
            };
            let in_flight = job.start(&pool);
            self.pool = Some(pool);
            Some(in_flight)
        } else {
            for _ in 0..m {
                let ti = self.rng.random_range(0..self.data.train.len());
                self.rollout(ti)?;
            }
            None
        };
        let mut rollout_s = t0.elapsed().as_secs_f64();
        let mut last = None;
        for _ in 0..self.cfg.updates_per_iter {
            if self.updates >= self.cfg.total_updates {
                break;
            }
            last = Some(self.update_pair()?);
            self.updates += 1;
            on_pair(self.updates);
        }
        if let Some(in_flight) = in_flight {
            let t1 = std::time::Instant::now();
            let done = in_flight.wait()?;
            done.store(&mut self.replay)?;
            self.env_steps += done.steps;
            self.rollout_env = Some(done.env);
            rollout_s += t1.elapsed().as_secs_f64();
        }
        Ok(IterationReport { last, rollout_s })
    }

    /// Plans `n` rollouts (see module `rollouts`): the draws of `n` sequential rollouts from the
    /// run's RNG (task, context, z, for each in turn), then the job's own RNG's seed.
    fn plan_rollouts(&mut self, n: usize) -> Result<RolloutJob> {
        let mut episodes = Vec::with_capacity(n);
        for _ in 0..n {
            let ti = self.rng.random_range(0..self.data.train.len());
            let z = self.rollout_z(ti)?;
            episodes.push(PlannedEpisode {
                task_index: ti,
                task: self.data.train[ti].task,
                seed: self.episode_seed(),
                z,
            });
            self.episodes += 1;
        }
        let env = match self.rollout_env.take() {
            Some(env) => env,
            None => sim::make_env(self.cfg.env, self.cfg.rollout_env_config())?,
        };
        Ok(RolloutJob {
            actor: self.sac.actor.deep_copy()?,
            norm: self.data.norm.clone(),
            env,
            episodes,
            rng: ChaCha8Rng::seed_from_u64(self.rng.random()),
        })
    }

    /// Warm start: one rollout of the current policy in every training task.
    pub fn warm_start(&mut self) -> Result<()> {
        for ti in 0..self.data.train.len() {
            self.rollout(ti)?;
        }
        Ok(())
    }

    /// Samples the discriminator's batch: `tasks_per_batch` distinct tasks, each with a fresh
    /// context and `disc_per_task` expert rows (uniform over its demo transitions) and as many
    /// policy rows (its replay).
    fn sample_disc_batch(&mut self) -> Result<DiscBatch> {
        let (source, _, rng) = self.sac_side();
        source.disc_batch(rng)
    }

    /// One discriminator + encoder step (Algorithm 1's inner loop, first half; the losses are
    /// in the module doc and in [`crate::model::Discriminator`]).
    pub fn disc_step(&mut self) -> Result<DiscStats> {
        let batch = self.sample_disc_batch()?;
        disc_update(
            DiscLearner {
                encoder: &self.encoder,
                disc: &self.disc,
                disc_opt: &mut self.disc_opt,
                enc_opt: &mut self.enc_opt,
                gp_weight: self.cfg.gp_weight,
            },
            &batch,
            self.updates,
            &mut self.rng,
        )
    }

    /// One SAC step on fresh tasks and contexts with the discriminator's reward (Algorithm 1's
    /// inner loop, second half).
    pub fn sac_step(&mut self) -> Result<(SacStats, f32)> {
        let (batch, reward_mean, bc) = self.sac_batch()?;
        let stats = self
            .sac
            .update_with_bc(&batch, bc.as_ref(), &mut self.rng)?;
        Ok((stats, reward_mean))
    }

    /// One update pair: a discriminator (+ encoder) step and a SAC step, one after the other
    /// (`learner_threads = 1`), or with N > 1 learner threads both at once inside the run's
    /// thread pool (SAC's reward then comes from the discriminator before this pair's
    /// update): the two steps are the sides of a `rayon::join`, their large matrix products
    /// are split across the pool, and the side that finishes first steals the other's blocks
    /// (`crate::threads`). Deterministic for a seed: the order of every draw from the run's
    /// RNG is fixed before the two steps start, and a split product equals an unsplit one.
    pub fn update_pair(&mut self) -> Result<(DiscStats, SacStats, f32)> {
        if self.cfg.learner_threads < 2 {
            let ds = self.disc_step()?;
            let (ss, r) = self.sac_step()?;
            return Ok((ds, ss, r));
        }
        let pool = match self.pool.take() {
            Some(p) => p,
            None => LearnerPool::new(self.cfg.learner_threads)?,
        };
        let out = pool.install(|| self.overlapped_pair());
        self.pool = Some(pool);
        out
    }

    /// [`Self::update_pair`] with N > 1 learner threads, run inside the pool: the
    /// discriminator's batch, loss and gradients on one side of a join; the SAC batch (its
    /// reward from the discriminator as it is before this pair) and the SAC step on the other;
    /// then the discriminator's and encoder's optimiser steps. Both sides only read the
    /// networks, data and replay; every random draw has a fixed order (the discriminator side
    /// draws from its own RNG, seeded from the run's RNG before the join; the SAC side draws
    /// from the run's RNG alone). Nothing but that seed runs before the join, so neither core
    /// waits there.
    fn overlapped_pair(&mut self) -> Result<(DiscStats, SacStats, f32)> {
        let mut disc_rng = ChaCha8Rng::seed_from_u64(self.rng.random());
        let update = self.updates;
        let (source, sac, rng) = self.sac_side();
        let (encoder, disc, gp_weight) = (source.encoder, source.disc, source.cfg.gp_weight);
        let (d, s) = rayon::join(
            || {
                let disc_batch = source.disc_batch(&mut disc_rng)?;
                disc_grads(encoder, disc, gp_weight, &disc_batch, update, &mut disc_rng)
            },
            || -> Result<(SacStats, f32)> {
                let (batch, reward_mean, bc) = source.draw(rng)?;
                Ok((sac.update_with_bc(&batch, bc.as_ref(), rng)?, reward_mean))
            },
        );
        let ((grads, ds), (ss, reward_mean)) = (d?, s?);
        self.disc_opt.step(&grads)?;
        self.enc_opt.step(&grads)?;
        Ok((ds, ss, reward_mean))
    }

    /// Samples a SAC batch on fresh tasks and contexts and labels it with the discriminator's
    /// reward; returns it with the reward's mean and, for SMILe + BC, the cloning term's rows.
    fn sac_batch(&mut self) -> Result<(Batch, f32, Option<BcTerm>)> {
        let (source, _, rng) = self.sac_side();
        source.draw(rng)
    }

    /// The run borrowed field by field: what both batches are drawn from (read only, so the
    /// two sides of an overlapped pair may read the same networks at once), the SAC learner
    /// and the run's RNG.
    fn sac_side(&mut self) -> (BatchSource<'_>, &mut Sac, &mut ChaCha8Rng) {
        let Smile {
            cfg,
            data,
            encoder,
            disc,
            replay,
            updates,
            sac,
            rng,
            ..
        } = self;
        let source = BatchSource {
            cfg,
            data,
            encoder,
            disc,
            replay,
            updates: *updates,
        };
        (source, sac, rng)
    }

    /// Deterministic evaluation on the held-out train tasks (contexts of
    /// `eval_context_size` trajectories).
    pub fn validate(&self) -> Result<f32> {
        quick_eval(
            &self.meta_policy(),
            &self.data.val,
            self.cfg.eval_contexts,
            self.cfg.eval_context_size,
            self.cfg.eval_episodes,
            self.cfg.env_config(),
        )
    }
}

/// A transition drawn uniformly from trajectories of `lens` transitions: (trajectory, step).
fn draw_transition(lens: &[usize], rng: &mut impl Rng) -> (usize, usize) {
    let mut k = rng.random_range(0..lens.iter().sum::<usize>());
    let mut j = 0;
    while k >= lens[j] {
        k -= lens[j];
        j += 1;
    }
    (j, k)
}

/// The networks, data and replay that both steps' batches are drawn from, borrowed field by
/// field, so that the two sides of an overlapped pair can draw their batches at once while
/// both read the same networks.
struct BatchSource<'a> {
    cfg: &'a SmileConfig,
    data: &'a MetaData,
    encoder: &'a ContextEncoder,
    disc: &'a Discriminator,
    replay: &'a TaskReplay,
    updates: u64,
}

impl BatchSource<'_> {
    /// [`Smile::sample_disc_batch`]: every random choice drawn from `rng`.
    fn disc_batch(&self, rng: &mut ChaCha8Rng) -> Result<DiscBatch> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, rng);
        let per_task = cfg.disc_per_task;
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        let norm = &self.data.norm;
        let mut specs: Vec<ContextSpec<'_>> = Vec::with_capacity(tasks.len());
        let (mut x_exp, mut x_pol) = (Vec::new(), Vec::new());
        for &ti in &tasks {
            let demos = &self.data.train[ti];
            specs.push(sample_context(demos, cfg.context_draw(), rng));
            // Expert rows: uniform over the task's demo transitions.
            let lens: Vec<usize> = demos.trajectories.iter().map(|tr| tr.len()).collect();
            for _ in 0..per_task {
                let (j, k) = draw_transition(&lens, rng);
                let tr = &demos.trajectories[j];
                self.disc.push_x(
                    norm,
                    &tr.obs[k * od..(k + 1) * od],
                    &tr.actions[k * ad..(k + 1) * ad],
                    &tr.next_obs[k * od..(k + 1) * od],
                    &mut x_exp,
                );
            }
            let mut pol = BatchVecs::default();
            self.replay.task(ti).sample_into(per_task, rng, &mut pol)?;
            for r in 0..per_task {
                self.disc.push_x(
                    norm,
                    &pol.obs[r * od..(r + 1) * od],
                    &pol.act[r * ad..(r + 1) * ad],
                    &pol.next_obs[r * od..(r + 1) * od],
                    &mut x_pol,
                );
            }
        }
        let context = self.encoder.batch(norm, &specs)?;
        DiscBatch::new(context, x_exp, x_pol, tasks.len(), per_task)
    }

    /// [`Smile::sac_batch`]: every random choice drawn from `rng`.
    fn draw(&self, rng: &mut ChaCha8Rng) -> Result<(Batch, f32, Option<BcTerm>)> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, rng);
        let n = cfg.sac_per_task;
        let specs: Vec<ContextSpec<'_>> = tasks
            .iter()
            .map(|&ti| sample_context(&self.data.train[ti], cfg.context_draw(), rng))
            .collect();
        let b = self.encoder.batch(&self.data.norm, &specs)?;
        // z from the discriminator's encoder, detached: SAC never updates the encoder.
        let z = self.encoder.z(&b, true, rng)?.detach().to_vec2::<f32>()?;
        let mut bv = BatchVecs::default();
        let mut z_rows = Vec::with_capacity(tasks.len() * n * z[0].len());
        for (k, &ti) in tasks.iter().enumerate() {
            self.replay.task(ti).sample_into(n, rng, &mut bv)?;
            for _ in 0..n {
                z_rows.extend_from_slice(&z[k]);
            }
        }
        let rows = bv.rew.len();
        let (od, ad, zd) = (
            self.data.family.obs_dim(),
            self.data.family.act_dim(),
            z[0].len(),
        );
        // r = clamp(D([x, z]), -10, 10); the SAC config's reward_scale multiplies it.
        let xzd = self.disc.x_dim() + zd;
        let mut dx = Vec::with_capacity(rows * xzd);
        for r in 0..rows {
            self.disc.push_x(
                &self.data.norm,
                &bv.obs[r * od..(r + 1) * od],
                &bv.act[r * ad..(r + 1) * ad],
                &bv.next_obs[r * od..(r + 1) * od],
                &mut dx,
            );
            dx.extend_from_slice(&z_rows[r * zd..(r + 1) * zd]);
        }
        // Each task's z on its n rows: the first layer's z block once per task.
        let xz = Tensor::from_vec(dx, (rows, xzd), &Device::Cpu)?;
        let rew = self.disc.reward(Input::shared(
            &xz,
            Some(SharedCols {
                start: self.disc.x_dim(),
                len: zd,
                group_rows: n,
            }),
        ))?;
        let reward_mean = scalar(&rew.mean_all()?)?;
        let batch = Batch {
            obs: policy_input(&self.data.norm, &bv.obs, &z_rows, zd)?,
            act: Tensor::from_slice(&bv.act, (rows, ad), &Device::Cpu)?,
            rew,
            next_obs: policy_input(&self.data.norm, &bv.next_obs, &z_rows, zd)?,
            done: Tensor::from_slice(&bv.done, (rows, 1), &Device::Cpu)?,
            z_cols: Some(SharedCols {
                start: od,
                len: zd,
                group_rows: n,
            }),
        };
        // SMILe + BC: the batch's tasks' demos, each row with its task's z. Nothing is drawn
        // when the weight is 0, so such a run is SMILe's, bit for bit.
        let w = self.cfg.bc_weight_at(self.updates);
        let bc = if w > 0.0 {
            let (mut obs, mut act) = (Vec::with_capacity(rows * od), Vec::with_capacity(rows * ad));
            for &ti in &tasks {
                let demos = &self.data.train[ti];
                let lens: Vec<usize> = demos.trajectories.iter().map(|tr| tr.len()).collect();
                for _ in 0..n {
                    let (j, k) = draw_transition(&lens, rng);
                    let tr = &demos.trajectories[j];
                    obs.extend_from_slice(&tr.obs[k * od..(k + 1) * od]);
                    act.extend_from_slice(&tr.actions[k * ad..(k + 1) * ad]);
                }
            }
            Some(BcTerm {
                obs: policy_input(&self.data.norm, &obs, &z_rows, zd)?,
                act: Tensor::from_vec(act, (rows, ad), &Device::Cpu)?,
                weight: w,
            })
        } else {
            None
        };
        Ok((batch, reward_mean, bc))
    }
}
