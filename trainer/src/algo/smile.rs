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
//!   after them ([`Smile::iteration`], module `overlap`).
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
//!
//! This file is the algorithm, read top to bottom: the run, its rollouts, iteration and update
//! pair, its hooks in the one fit loop ([`Learner`]), then the pair's two halves with each loss
//! above its optimiser step (the discriminator's here; SAC's critic, actor and temperature
//! steps called in order, their arithmetic in [`crate::algo::sac`], SMILe + BC's cloning term
//! here). No thread is named in the math: around it, `batch` draws both halves' batches,
//! `overlap` runs a pair's halves, the discriminator loss's parts and the rollouts at once on N
//! learner threads, `persist` checkpoints a run and `config` holds its settings (and how the
//! typed settings land in them, [`MetaSettings`](crate::MetaSettings)).

use std::path::Path;

use candle_core::backprop::GradStore;
use candle_core::{DType, Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::Environment;

mod batch;
mod config;
mod overlap;
mod persist;
#[cfg(test)]
mod tests;

pub use batch::DiscBatch;
pub use config::SmileConfig;

use crate::algo::fit::{Cadence, Evaluation, Fields, Progress, Score};
use crate::algo::learner::{Learner, MetaInputs, Unit};
use crate::algo::sac::{ActorStep, Sac, SacStats};
use crate::data::{MetaData, TaskReplay, better, quick_eval, sample_context, sensed_episode};
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::model::{
    ContextEncoder, DiscInput, DiscStats, Discriminator, Input, MetaPolicy, SharedCols,
    TanhGaussianPolicy, TrainingMark, bce_with_logits, scalar,
};
use crate::optim::{Adam, AdamConfig};
use crate::threads::LearnerPool;
use batch::{BatchSource, DemoRows};

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
    /// SMILe + BC's `[bc_early]`: each training task's demo rows, the first steps' repeated.
    bc_rows: Option<Vec<Vec<(usize, usize)>>>,
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
        // Position-only sensing keeps the states as the policy read them beside the true ones.
        let mut replay = TaskReplay::new(data.train.len(), od, ad, cfg.replay_per_task)?;
        if cfg.sensing.is_some_and(|s| s.positions) {
            replay = replay.with_views();
        }
        let bc_rows = cfg.bc_early.map(|e| {
            let rows = |td| batch::weighted_rows(td, e);
            data.train.iter().map(rows).collect()
        });
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
            bc_rows,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SmileConfig {
        &self.cfg
    }

    /// Sets the compute budget of the next [`fit`](crate::fit) call (`cpu_budget_s`, 0: none); the
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
        let cfg = &self.cfg;
        self.data
            .meta_policy(cfg.physics, cfg.algo_name(), &self.encoder, &self.sac.actor)
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
        let ep = sensed_episode(
            self.env.as_mut(),
            &task,
            seed,
            self.cfg.sensing.as_ref(),
            &mut |o, a| {
                let mut x = norm.apply(o);
                x.extend_from_slice(&z);
                a.copy_from_slice(&actor.act(&x, false, rng)?);
                Ok(())
            },
            &mut |st| {
                replay.push(
                    st.obs,
                    st.action,
                    0.0,
                    st.next_obs,
                    st.terminated,
                    st.sensed,
                )
            },
        )?;
        self.env_steps += ep.steps as u64;
        self.episodes += 1;
        Ok(())
    }

    /// One iteration of Algorithm 1: `rollouts_per_iter` rollouts, each in a uniform training
    /// task, then `updates_per_iter` update pairs (fewer where `total_updates` ends the run);
    /// `on_pair` sees the update count after every pair. With `learner_threads >= 2` the
    /// rollouts run beside the pairs on the learner pool and enter the replays after them
    /// (module `overlap` says how, and the one way that differs from one thread).
    pub fn iteration(&mut self, on_pair: &mut dyn FnMut(u64)) -> Result<IterationReport> {
        let (m, t0) = (self.cfg.rollouts_per_iter, std::time::Instant::now());
        let in_flight = if self.cfg.learner_threads >= 2 && m > 0 {
            Some(self.start_rollouts(m)?)
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
            self.land_rollouts(in_flight)?;
            rollout_s += t1.elapsed().as_secs_f64();
        }
        Ok(IterationReport { last, rollout_s })
    }

    /// Warm start: one rollout of the current policy in every training task.
    pub fn warm_start(&mut self) -> Result<()> {
        for ti in 0..self.data.train.len() {
            self.rollout(ti)?;
        }
        Ok(())
    }

    /// One update pair: a discriminator (+ encoder) step, then a SAC step; with N > 1 learner
    /// threads both at once inside the run's thread pool, SAC's reward then coming from the
    /// discriminator as it is before this pair's step (module `overlap`). Deterministic for a
    /// seed and thread count.
    pub fn update_pair(&mut self) -> Result<(DiscStats, SacStats, f32)> {
        if self.cfg.learner_threads >= 2 {
            return self.overlapped_pair();
        }
        let ds = self.disc_step()?;
        let (ss, r) = self.sac_step()?;
        Ok((ds, ss, r))
    }

    /// One discriminator + encoder step (Algorithm 1's inner loop, first half).
    pub fn disc_step(&mut self) -> Result<DiscStats> {
        let (source, _, rng) = self.parts();
        let batch = source.disc_batch(rng)?;
        let learner = DiscLearner {
            encoder: &self.encoder,
            disc: &self.disc,
            disc_opt: &mut self.disc_opt,
            enc_opt: &mut self.enc_opt,
            gp_weight: self.cfg.gp_weight,
        };
        disc_update(learner, &batch, self.updates, &mut self.rng)
    }

    /// One SAC step on fresh tasks and contexts with the discriminator's reward (Algorithm 1's
    /// inner loop, second half); returns its statistics and the reward's mean.
    pub fn sac_step(&mut self) -> Result<(SacStats, f32)> {
        let (source, sac, rng) = self.parts();
        sac_update(&source, sac, rng)
    }

    /// The run borrowed field by field: what both batches are drawn from (read only, so the
    /// two halves of an overlapped pair may read the same networks at once), the SAC learner
    /// and the run's RNG.
    fn parts(&mut self) -> (BatchSource<'_>, &mut Sac, &mut ChaCha8Rng) {
        let Smile {
            cfg,
            data,
            encoder,
            disc,
            replay,
            updates,
            sac,
            rng,
            bc_rows,
            ..
        } = self;
        let source = BatchSource {
            cfg,
            data,
            encoder,
            disc,
            replay,
            updates: *updates,
            bc_rows: bc_rows.as_deref(),
        };
        (source, sac, rng)
    }

    /// Deterministic evaluation on the held-out train tasks (contexts of
    /// `eval_context_size` trajectories).
    pub fn validate(&self) -> Result<f32> {
        let cfg = &self.cfg;
        quick_eval(
            &self.meta_policy(),
            &self.data.val,
            cfg.held_out(),
            cfg.env_config(),
        )
    }
}

// ---------------------------------------------------------------------------------------------
// The run in the one fit loop: Algorithm 1's iteration is its unit of work, the held-out
// metric its evaluation (keep-best), its checkpoint and meta-policy files its state.

impl Learner for Smile {
    type Config = SmileConfig;
    type Inputs = MetaInputs;
    const UNIT: Unit = Unit {
        plural: "update pairs",
        word: "update",
    };

    fn start(cfg: SmileConfig, inputs: MetaInputs) -> Result<Self> {
        if inputs.expert.is_some() {
            return Err(Error::takes_no_expert(cfg.algo_name(), None));
        }
        Smile::new(cfg, inputs.data)
    }

    fn resume(dir: &Path, inputs: MetaInputs, wanted: &SmileConfig) -> Result<Self> {
        if inputs.expert.is_some() {
            return Err(Error::takes_no_expert(wanted.algo_name(), None));
        }
        let mut run = Smile::resume(dir, inputs.data, Some(wanted.total_updates))?;
        run.set_cpu_budget(wanted.cpu_budget_s)?;
        Ok(run)
    }

    fn config(&self) -> &SmileConfig {
        &self.cfg
    }

    fn done(&self) -> u64 {
        self.updates
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            total: self.cfg.total_updates,
            eval_every: self.cfg.eval_every,
            eval_at_end: true,
            checkpoint_every: self.cfg.checkpoint_every,
            cpu_budget_s: self.cfg.cpu_budget_s,
        }
    }

    fn begin(&mut self, log: &mut MetricsLog) -> Result<()> {
        if self.updates == 0 && self.replay.total_len() == 0 {
            self.warm_start()?;
        }
        if !self.data.val.is_empty() && self.updates == 0 {
            // The untrained policy as the first point of the validation curve.
            let m = self.validate()?;
            log.log(0, &[("eval/val_metric", m as f64)])?;
        }
        Ok(())
    }

    fn cpu_seconds_mut(&mut self) -> Option<&mut f64> {
        Some(&mut self.cpu_s)
    }

    // Algorithm 1: each iteration adds m trajectories to the task replays, then alternates d
    // times between the discriminator (+ encoder) and the policy.
    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let report = self.iteration(&mut |u| on(Progress::Steps(u)))?;
        let (ds, ss, rm) = match report.last {
            Some((d, s, r)) => (d, Some(s), r),
            None => (DiscStats::default(), None, 0.0),
        };
        let cfg = &self.cfg;
        let mut fields = vec![
            ("losses/disc_bce", ds.bce as f64),
            ("losses/disc_gp", ds.gp as f64),
            ("charts/disc_acc_expert", ds.acc_expert as f64),
            ("charts/disc_acc_policy", ds.acc_policy as f64),
            ("charts/reward_mean", rm as f64),
            ("charts/env_steps", self.env_steps as f64),
        ];
        if let Some(s) = &ss {
            fields.extend(s.fields());
        }
        if cfg.bc_weight > 0.0 {
            // The weight of the pair just done.
            let w = cfg.bc_weight_at(self.updates.saturating_sub(1));
            fields.push(("charts/bc_weight", w as f64));
        }
        Ok(fields)
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        if self.data.val.is_empty() {
            return Ok(None);
        }
        let m = self.validate()?;
        let keep = better(self.data.family.metric_kind(), m, self.best);
        if keep {
            self.best = m;
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/val_metric", m as f64),
                ("eval/val_best", self.best as f64),
            ],
            score: Score {
                what: "held-out train-task metric",
                metric: m,
                best: self.best,
                val_mse: None,
            },
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        Smile::save_checkpoint(self, dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.meta_policy().save_marked(dir, Some(self.mark(false)))
    }

    fn finish(&mut self, dir: &Path, _log: &mut MetricsLog) -> Result<()> {
        let replaces = self.data.val.is_empty();
        self.meta_policy()
            .save_final(dir, self.mark(true), replaces)
    }
}

// ---------------------------------------------------------------------------------------------
// The discriminator's half: L_D = L_bce + lambda_gp L_gp, then its two optimisers' step.

/// What one discriminator + encoder update changes: the networks and their optimisers.
pub struct DiscLearner<'a> {
    /// The context encoder (trained only through this loss).
    pub encoder: &'a ContextEncoder,
    /// The discriminator.
    pub disc: &'a Discriminator,
    /// The discriminator's optimiser (betas (0, 0.999) in the authors' recipe).
    pub disc_opt: &'a mut Adam,
    /// The encoder's optimiser.
    pub enc_opt: &'a mut Adam,
    /// The gradient penalty's weight (`gp_weight`).
    pub gp_weight: f32,
}

/// One discriminator + encoder update on `batch` (shared by [`Smile::disc_step`] and
/// `smile bench --workload disc`); `update` only names the step in a non-finite-loss error.
pub fn disc_update(
    l: DiscLearner<'_>,
    batch: &DiscBatch,
    update: u64,
    rng: &mut impl Rng,
) -> Result<DiscStats> {
    // L_D = L_bce + lambda_gp L_gp (disc_loss)
    let (grads, stats) = disc_loss(l.encoder, l.disc, l.gp_weight, batch, update, rng)?;
    // One backward pass, two optimisers: the discriminator (betas (0, 0.999)) and the
    // encoder (trained only through this loss).
    l.disc_opt.step(&grads)?;
    l.enc_opt.step(&grads)?;
    Ok(stats)
}

/// `L_D = L_bce + lambda_gp L_gp` of one discriminator + encoder update (the module doc) and
/// its gradients, the networks only read (an overlapped pair computes them while the SAC half
/// reads the same networks for its reward, and steps the optimisers after both are done).
///
/// `L_bce` and `L_gp` share no node but the discriminator's weights (the penalty's `z` is
/// detached), so their gradients come from separate backward passes, added afterwards; inside
/// a learner pool they run at once (`overlap::bce_and_penalty`). Deterministic for a thread
/// count; one thread and a pool differ in the last bits (the penalty's split).
fn disc_loss(
    encoder: &ContextEncoder,
    disc: &Discriminator,
    gp_weight: f32,
    batch: &DiscBatch,
    update: u64,
    rng: &mut impl Rng,
) -> Result<(GradStore, DiscStats)> {
    let rows = batch.tasks * batch.per_task;
    // z ~ q(z | c) per task, with gradient into the encoder, on each of its task's rows
    let z = encoder.z(&batch.context, true, rng)?; // (t, z)
    let z_rows = batch.z_rows(&z)?; // (t n, z)
    // x~ = u x_E + (1 - u) x_pi: the penalty's mixing weights, u ~ U(0, 1) per row
    let u = if gp_weight > 0.0 {
        let u: Vec<f32> = (0..rows).map(|_| rng.random::<f32>()).collect();
        Some(Tensor::from_vec(u, (rows, 1), &Device::Cpu)?)
    } else {
        None
    };
    let bce = || bce_grads(disc, batch, &z_rows, update);
    let gp = |(start, len)| match &u {
        Some(u) if len > 0 => {
            gp_grads(disc, batch, &z_rows, u, (start, len), gp_weight, update).map(Some)
        }
        _ => Ok(None),
    };
    let ((mut grads, bce_v, lg), gp_parts) = overlap::bce_and_penalty(bce, gp, batch)?;
    let mut gp_v = 0.0;
    for (gp_grads, v) in gp_parts.into_iter().flatten() {
        // dL_D/dtheta = dL_bce/dtheta + lambda_gp dL_gp/dtheta
        grads.extend(gp_grads)?;
        gp_v += v; // each share was checked finite before its backward
    }
    let acc_e = lg[..rows].iter().filter(|v| **v > 0.0).count() as f32 / rows as f32;
    let acc_p = lg[rows..].iter().filter(|v| **v < 0.0).count() as f32 / rows as f32;
    let stats = DiscStats {
        bce: bce_v,
        gp: gp_v,
        acc_expert: acc_e,
        acc_policy: acc_p,
    };
    Ok((grads, stats))
}

/// `L_bce`'s gradients (discriminator and encoder), its value and the batch's logits.
fn bce_grads(
    disc: &Discriminator,
    batch: &DiscBatch,
    z_rows: &Tensor,
    update: u64,
) -> Result<(GradStore, f32, Vec<f32>)> {
    let rows = batch.tasks * batch.per_task;
    let inp = Tensor::cat(
        &[
            &Tensor::cat(&[&batch.x_expert, z_rows], 1)?,
            &Tensor::cat(&[&batch.x_policy, z_rows], 1)?,
        ],
        0,
    )?;
    // (2 t n, 1): expert rows, then policy rows; each task's z on its n rows of each half, so
    // the first layer computes the z block once per n rows.
    let zd = z_rows.dim(1)?;
    let shared = SharedCols {
        start: inp.dim(1)? - zd,
        len: zd,
        group_rows: batch.per_task,
    };
    let logits = disc.logits(Input::shared(&inp, Some(shared)))?;
    let labels = Tensor::cat(
        &[
            Tensor::ones((rows, 1), DType::F32, &Device::Cpu)?,
            Tensor::zeros((rows, 1), DType::F32, &Device::Cpu)?,
        ],
        0,
    )?;
    // L_bce = mean[softplus(l) - y l]
    let bce = bce_with_logits(&logits, &labels)?;
    let v = finite("losses/disc_bce", scalar(&bce)?, update)?;
    let grads = bce.backward()?;
    Ok((grads, v, logits.detach().flatten_all()?.to_vec1::<f32>()?))
}

/// The gradients of `lambda_gp L_gp`'s share from the rows `(start, len)` (the
/// discriminator's only) and that share of `L_gp`.
fn gp_grads(
    disc: &Discriminator,
    batch: &DiscBatch,
    z_rows: &Tensor,
    u: &Tensor,
    (start, len): (usize, usize),
    gp_weight: f32,
    update: u64,
) -> Result<(GradStore, f32)> {
    // L_gp = mean[(||dD/dx~|| - 1)^2], x~ = u x_E + (1 - u) x_pi, z detached; these rows'
    // share of it is their mean times len / rows.
    let share = len as f64 / (batch.tasks * batch.per_task) as f64;
    let rows = |t: &Tensor| t.narrow(0, start, len);
    let gp = (disc.gradient_penalty(
        &rows(&batch.x_expert)?,
        &rows(&batch.x_policy)?,
        &rows(z_rows)?,
        &rows(u)?,
        Some(batch.per_task),
    )? * share)?;
    let v = finite("losses/disc_gp", scalar(&gp)?, update)?;
    Ok(((gp * gp_weight as f64)?.backward()?, v))
}

/// `v`, or the non-finite-loss error naming `what` and the update.
fn finite(what: &'static str, v: f32, update: u64) -> Result<f32> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::NonFinite {
            what,
            value: v,
            update,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// The SAC half: the reward, then the critics', the actor's (with SMILe + BC's cloning term) and
// the temperature's losses, each above its optimiser step (the arithmetic in `algo/sac.rs`,
// shared with the experts' SAC).

/// One SAC update on a fresh batch from `source`, rewarded by its discriminator; returns its
/// statistics and the reward's mean.
fn sac_update(
    source: &BatchSource<'_>,
    sac: &mut Sac,
    rng: &mut ChaCha8Rng,
) -> Result<(SacStats, f32)> {
    // r = clamp(D([x, z]), -10, 10) on replay rows, z detached: SAC never updates the encoder
    let (batch, reward_mean, demos) = source.sac_batch(rng)?;
    let alpha = sac.begin_update()?;
    // L_Q = sum_j mean (Q_j(s, a) - y)^2, y = c r + gamma (1 - d)(min_j Q'_j(s', a') - alpha log pi(a'|s'))
    let critic = sac.critic_step(&batch, alpha, rng)?;
    // L_pi = mean (alpha log pi(a~|s) - min_j Q_j(s, a~))  [+ w(u) L_bc, SMILe + BC]
    let actor = actor_step(sac, &batch, demos.as_ref(), alpha, rng)?;
    // L_alpha = -log(alpha) (mean log pi(a~|s) + H_target)
    let alpha_loss = sac.temperature_step(actor.mean_logp)?;
    // theta'_j <- (1 - tau) theta'_j + tau theta_j
    sac.target_step()?;
    Ok((SacStats::of(alpha, critic, actor, alpha_loss), reward_mean))
}

/// SAC's actor step with SMILe + BC's cloning term on the batch's tasks' demos (each row with
/// its task's z), where the run has one:
/// `L_bc = mean_rows ||tanh(mu([norm(s_E), z])) - a_E||^2`, added to `L_pi` with weight `w(u)`.
fn actor_step(
    sac: &mut Sac,
    batch: &crate::data::Batch,
    demos: Option<&DemoRows>,
    alpha: f32,
    rng: &mut ChaCha8Rng,
) -> Result<ActorStep> {
    let Some(d) = demos else {
        return sac.actor_step(batch, alpha, None, rng);
    };
    let cloning = |actor: &TanhGaussianPolicy| -> Result<(Tensor, f32)> {
        let err = (actor.mean_action(&d.obs)? - &d.act)?;
        let l_bc = err.sqr()?.sum_keepdim(1)?.mean_all()?;
        let v = scalar(&l_bc)?;
        Ok(((l_bc * d.weight as f64)?, v))
    };
    sac.actor_step(batch, alpha, Some(&cloning), rng)
}
