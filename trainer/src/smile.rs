//! SMILe: Scalable Meta Inverse RL (Ghasemipour et al. 2019), state-action and state-only.
//!
//! A context-conditioned AIRL discriminator `D(x, z)` with `x = [norm(s), a]` (or
//! `[norm(s), norm(s')]` state-only) and `z ~ q(z | c)` from the context encoder of
//! [`crate::context`]; a SAC policy `pi(a | [norm(s), z])` trained on the reward the
//! discriminator gives. Schedule and batches follow the reference (`smile-reference.md` §1-2):
//!
//! * warm start: one rollout of the untrained policy in every training task;
//! * each iteration: `rollouts_per_iter` rollouts (a uniform task, a context of k in 1..=4 of
//!   its demos, z sampled, stochastic actions) into that task's replay buffer, then
//!   `updates_per_iter` x (1 discriminator+encoder step, 1 SAC step).
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

use std::path::Path;

use candle_core::{DType, Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sim::{EnvConfig, Environment, Family};

use crate::checkpoint;
use crate::context::{ContextConfig, ContextEncoder, ContextSpec, MetaPolicy, policy_input};
use crate::expert::{rng_from_state, rng_state};
use crate::meta_data::{MetaData, better, distinct_tasks, quick_eval, run_episode, sample_context};
use crate::metrics::MetricsLog;
use crate::nn::{Adam, AdamConfig, Mlp};
use crate::replay::{BatchVecs, TaskReplay};
use crate::sac::{Sac, SacConfig, SacCounters};
use crate::{Error, Result};

/// SMILe hyper-parameters. Defaults are the reference's point-goal prototype (§7) scaled for a
/// CPU: encoder 64 -> r 32 -> z 16, discriminator and SAC 2 x 128, reward scale 8, gradient
/// penalty 1, 1 disc : 1 SAC step, 8 tasks per batch; per-task batch sizes 64 (reference 128).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmileConfig {
    /// Task family. Default `point-goal`.
    pub env: String,
    /// Encoder and latent (its `state_only` selects the state-only variant everywhere).
    pub context: ContextConfig,
    /// SAC on `[norm(s), z]`. Default: hidden [128, 128], reward scale 8, learned alpha.
    pub sac: SacConfig,
    /// Discriminator hidden widths. Default [128, 128] (§7; the paper 3 x 512).
    pub disc_hidden: Vec<usize>,
    /// Discriminator learning rate. Default 3e-4.
    pub disc_lr: f32,
    /// Encoder learning rate. Default 3e-4.
    pub enc_lr: f32,
    /// Gradient-penalty weight lambda_gp. Default 1 (§7: 1 beat the paper's 10 on point-goal).
    pub gp_weight: f32,
    /// Logit clamp. Default 10.
    pub logit_clamp: f32,
    /// Distinct tasks per discriminator / SAC batch. Default 8.
    pub tasks_per_batch: usize,
    /// Expert and policy transitions per task in a discriminator batch. Default 64 (ref 128).
    pub disc_per_task: usize,
    /// Replay transitions per task in a SAC batch. Default 64 (ref 128).
    pub sac_per_task: usize,
    /// Most context trajectories (contexts use k in 1..=this). Default 4.
    pub max_context: usize,
    /// Rollouts per iteration. Default 5 (ref).
    pub rollouts_per_iter: usize,
    /// Update pairs per iteration. Default 100 (ref).
    pub updates_per_iter: usize,
    /// Total update pairs. Default 15 000 (§7: 12k-22k reached <= 0.15 on point-goal).
    pub total_updates: u64,
    /// Replay capacity per task. Default 20 000.
    pub replay_per_task: usize,
    /// Hold out every n-th meta-train task for validation (0: none). Default 8.
    pub holdout_every: usize,
    /// Evaluate on the held-out train tasks every this many updates (0: never). Default 1000.
    pub eval_every: u64,
    /// Deterministic episodes per held-out task and context in that evaluation. Default 2.
    pub eval_episodes: usize,
    /// Checkpoint every this many updates (at iteration ends). Default 2000.
    pub checkpoint_every: u64,
    /// Episode length override. Default None.
    pub horizon: Option<usize>,
    /// Seed of everything. Default 0.
    pub seed: u64,
}

impl Default for SmileConfig {
    fn default() -> Self {
        Self {
            env: "point-goal".into(),
            context: ContextConfig::default(),
            sac: SacConfig {
                hidden: vec![128, 128],
                reward_scale: 8.0,
                ..SacConfig::default()
            },
            disc_hidden: vec![128, 128],
            disc_lr: 3e-4,
            enc_lr: 3e-4,
            gp_weight: 1.0,
            logit_clamp: 10.0,
            tasks_per_batch: 8,
            disc_per_task: 64,
            sac_per_task: 64,
            max_context: 4,
            rollouts_per_iter: 5,
            updates_per_iter: 100,
            total_updates: 15_000,
            replay_per_task: 20_000,
            holdout_every: 8,
            eval_every: 1000,
            eval_episodes: 2,
            checkpoint_every: 2000,
            horizon: None,
            seed: 0,
        }
    }
}

impl SmileConfig {
    /// The family named by `env`.
    pub fn family(&self) -> Result<Family> {
        self.env
            .parse::<Family>()
            .map_err(|e| Error::Config(e.to_string()))
    }

    /// Episode options.
    pub fn env_config(&self) -> EnvConfig {
        EnvConfig {
            horizon: self.horizon,
            ..EnvConfig::default()
        }
    }

    /// Reject values that cannot train.
    pub fn validate(&self) -> Result<()> {
        self.family()?;
        self.sac.validate()?;
        if self.tasks_per_batch == 0
            || self.disc_per_task == 0
            || self.sac_per_task == 0
            || self.max_context == 0
            || self.updates_per_iter == 0
        {
            return Err(Error::Config(
                "smile batch sizes and counts must be positive".into(),
            ));
        }
        if self.gp_weight < 0.0 || self.logit_clamp <= 0.0 {
            return Err(Error::Config(
                "gp_weight must be >= 0 and logit_clamp > 0".into(),
            ));
        }
        Ok(())
    }

    /// Algorithm name as used on the command line.
    pub fn algo_name(&self) -> &'static str {
        if self.context.state_only {
            "smile-state-only"
        } else {
            "smile"
        }
    }
}

/// `dD/dx` of a ReLU MLP with a scalar output, per row, as a differentiable function of the
/// weights (for the gradient penalty; candle has no double backward through our fused
/// layers). With row-vector layers `h_{l+1} = relu(h_l W_l + b_l)`:
/// `g = (((1 W_L^T) . m_{L-1}) W_{L-1}^T . ... . m_0) W_0^T`, where `m_l = 1[pre-activation > 0]`
/// (constants: ReLU's second derivative is zero almost everywhere, so this equals PyTorch's
/// `create_graph=True` gradient).
pub fn input_gradient(net: &Mlp, x: &Tensor) -> Result<Tensor> {
    let vars = net.vars();
    let n = vars.len() / 2;
    let mut masks = Vec::with_capacity(n - 1);
    let mut h = x.detach();
    for l in 0..n - 1 {
        let pre = h
            .matmul(&vars[2 * l].as_tensor().detach())?
            .broadcast_add(&vars[2 * l + 1].as_tensor().detach())?;
        masks.push(pre.gt(0.0)?.to_dtype(DType::F32)?);
        h = pre.relu()?;
    }
    let rows = x.dim(0)?;
    let w_last = vars[2 * (n - 1)].as_tensor(); // (h, 1)
    let mut g = Tensor::ones((rows, 1), DType::F32, &Device::Cpu)?.matmul(&w_last.t()?)?;
    for l in (0..n - 1).rev() {
        g = (g * &masks[l])?.matmul(&vars[2 * l].as_tensor().t()?)?;
    }
    Ok(g)
}

/// BCE with logits, `mean[max(l, 0) - l y + ln(1 + e^{-|l|})]`.
pub fn bce_with_logits(logits: &Tensor, labels: &Tensor) -> Result<Tensor> {
    let softplus = (logits.relu()? + logits.abs()?.neg()?.exp()?.affine(1.0, 1.0)?.log()?)?;
    Ok((softplus - (logits * labels)?)?.mean_all()?)
}

/// Scalars of one discriminator step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DiscStats {
    /// `losses/disc_bce`.
    pub bce: f32,
    /// `losses/disc_gp`.
    pub gp: f32,
    /// `charts/disc_acc_expert`: fraction of expert rows with logit > 0.
    pub acc_expert: f32,
    /// `charts/disc_acc_policy`: fraction of policy rows with logit < 0.
    pub acc_policy: f32,
}

/// Events reported to the caller of [`train`].
#[derive(Debug, Clone, Copy)]
pub enum Event {
    /// Update pairs done so far.
    Updates(u64),
    /// A held-out-train-task evaluation: (updates, metric, best so far).
    Eval(u64, f32, f32),
    /// A checkpoint was written at this update count.
    Checkpoint(u64),
}

/// A SMILe run: data, networks, optimisers, replay, counters.
pub struct Smile {
    cfg: SmileConfig,
    data: MetaData,
    env: Box<dyn Environment>,
    /// The context encoder (trained by the discriminator loss only).
    pub encoder: ContextEncoder,
    /// The discriminator on `[x, z]`.
    pub disc: Mlp,
    /// The SAC agent on `[norm(s), z]`.
    pub sac: Sac,
    disc_opt: Adam,
    enc_opt: Adam,
    replay: TaskReplay,
    rng: ChaCha8Rng,
    updates: u64,
    env_steps: u64,
    episodes: u64,
    best: f32,
}

fn sim_err(e: impl std::fmt::Display) -> Error {
    Error::Sim(e.to_string())
}

fn scalar(t: &Tensor) -> Result<f32> {
    Ok(t.flatten_all()?.to_vec1::<f32>()?[0])
}

impl Smile {
    /// A fresh run on `data` (the meta-train demos; see [`MetaData::from_dataset`]).
    pub fn new(cfg: SmileConfig, data: MetaData) -> Result<Self> {
        cfg.validate()?;
        let family = cfg.family()?;
        if data.family != family {
            return Err(Error::Config(format!(
                "demos are {}, config says {family}",
                data.family
            )));
        }
        let env = sim::make_env(family, cfg.env_config()).map_err(sim_err)?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let (od, ad) = (family.obs_dim(), family.act_dim());
        let encoder = ContextEncoder::new(od, ad, cfg.context.clone(), &mut rng)?;
        let x_dim = if cfg.context.state_only {
            2 * od
        } else {
            od + ad
        };
        let mut dw = vec![x_dim + cfg.context.z_dim];
        dw.extend_from_slice(&cfg.disc_hidden);
        dw.push(1);
        let disc = Mlp::new(&dw, &mut rng)?;
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
            episodes: 0,
            best: f32::NAN,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SmileConfig {
        &self.cfg
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

    /// The current policy as a [`MetaPolicy`] (shares the live weights).
    pub fn meta_policy(&self) -> MetaPolicy {
        MetaPolicy {
            family: self.data.family,
            algo: self.cfg.algo_name().into(),
            norm: self.data.norm.clone(),
            encoder: self.encoder.clone(),
            policy: self.sac.actor.clone(),
        }
    }

    fn x_dim(&self) -> usize {
        let od = self.data.family.obs_dim();
        if self.cfg.context.state_only {
            2 * od
        } else {
            od + self.data.family.act_dim()
        }
    }

    /// Appends the discriminator's `x` of one transition: `[norm(s), a]` or `[norm(s), norm(s')]`.
    fn push_x(&self, s: &[f32], a: &[f32], s2: &[f32], out: &mut Vec<f32>) {
        self.data.norm.push(s, out);
        if self.cfg.context.state_only {
            self.data.norm.push(s2, out);
        } else {
            out.extend_from_slice(a);
        }
    }

    /// One rollout in training task `ti` with a sampled context and z; stored in its replay.
    pub fn rollout(&mut self, ti: usize) -> Result<()> {
        let spec = sample_context(&self.data.train[ti], self.cfg.max_context, &mut self.rng);
        let b = self.encoder.batch(&self.data.norm, &[spec])?;
        let z = self
            .encoder
            .z(&b, true, &mut self.rng)?
            .detach()
            .flatten_all()?
            .to_vec1::<f32>()?;
        let task = self.data.train[ti].task;
        let seed = self
            .cfg
            .seed
            .wrapping_mul(1_000_003)
            .wrapping_add(self.episodes);
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

    /// Warm start: one rollout of the current policy in every training task.
    pub fn warm_start(&mut self) -> Result<()> {
        for ti in 0..self.data.train.len() {
            self.rollout(ti)?;
        }
        Ok(())
    }

    /// One discriminator + encoder step (see the module doc for the loss).
    pub fn disc_step(&mut self) -> Result<DiscStats> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, &mut self.rng);
        let (t, n) = (tasks.len(), cfg.disc_per_task);
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        let mut specs: Vec<ContextSpec<'_>> = Vec::with_capacity(t);
        let (mut x_exp, mut x_pol) = (Vec::new(), Vec::new());
        for &ti in &tasks {
            let demos = &self.data.train[ti];
            specs.push(sample_context(demos, cfg.max_context, &mut self.rng));
            // Expert rows: uniform over the task's demo transitions.
            let lens: Vec<usize> = demos.trajectories.iter().map(|tr| tr.len()).collect();
            let total: usize = lens.iter().sum();
            for _ in 0..n {
                let mut k = self.rng.random_range(0..total);
                let mut j = 0;
                while k >= lens[j] {
                    k -= lens[j];
                    j += 1;
                }
                let tr = &demos.trajectories[j];
                let (s, a, s2) = (
                    &tr.obs[k * od..(k + 1) * od],
                    &tr.actions[k * ad..(k + 1) * ad],
                    &tr.next_obs[k * od..(k + 1) * od],
                );
                self.data.norm.push(s, &mut x_exp);
                if cfg.context.state_only {
                    self.data.norm.push(s2, &mut x_exp);
                } else {
                    x_exp.extend_from_slice(a);
                }
            }
            let mut pol = BatchVecs::default();
            self.replay
                .task(ti)
                .sample_into(n, &mut self.rng, &mut pol)?;
            for r in 0..n {
                let (s, a, s2) = (
                    &pol.obs[r * od..(r + 1) * od],
                    &pol.act[r * ad..(r + 1) * ad],
                    &pol.next_obs[r * od..(r + 1) * od],
                );
                self.data.norm.push(s, &mut x_pol);
                if cfg.context.state_only {
                    self.data.norm.push(s2, &mut x_pol);
                } else {
                    x_pol.extend_from_slice(a);
                }
            }
        }
        let dev = &Device::Cpu;
        let xd = self.x_dim();
        let b = self.encoder.batch(&self.data.norm, &specs)?;
        let z = self.encoder.z(&b, true, &mut self.rng)?; // (t, z), gradient into the encoder
        // Row r of each half belongs to task r / n: broadcast z with a one-hot matrix.
        let mut onehot = vec![0.0f32; t * n * t];
        for r in 0..t * n {
            onehot[r * t + r / n] = 1.0;
        }
        let onehot = Tensor::from_vec(onehot, (t * n, t), dev)?;
        let z_rows = onehot.matmul(&z)?; // (t n, z)
        let xe = Tensor::from_vec(x_exp, (t * n, xd), dev)?;
        let xp = Tensor::from_vec(x_pol, (t * n, xd), dev)?;
        let inp = Tensor::cat(
            &[
                &Tensor::cat(&[&xe, &z_rows], 1)?,
                &Tensor::cat(&[&xp, &z_rows], 1)?,
            ],
            0,
        )?;
        let c = cfg.logit_clamp as f64;
        let logits = self.disc.forward(&inp)?.clamp(-c, c)?; // (2 t n, 1)
        let labels = Tensor::cat(
            &[
                Tensor::ones((t * n, 1), DType::F32, dev)?,
                Tensor::zeros((t * n, 1), DType::F32, dev)?,
            ],
            0,
        )?;
        // L_bce = mean[softplus(l) - y l]
        let bce = bce_with_logits(&logits, &labels)?;
        // L_gp = mean[(||dD/dx~|| - 1)^2], x~ = u x_E + (1 - u) x_pi, z detached
        let mut loss = bce.clone();
        let mut gp_v = 0.0;
        if cfg.gp_weight > 0.0 {
            let u: Vec<f32> = (0..t * n).map(|_| self.rng.random::<f32>()).collect();
            let u = Tensor::from_vec(u, (t * n, 1), dev)?;
            let x_mix = (xe.broadcast_mul(&u)? + xp.broadcast_mul(&u.affine(-1.0, 1.0)?)?)?;
            let mix = Tensor::cat(&[&x_mix, &z_rows.detach()], 1)?;
            let g = input_gradient(&self.disc, &mix)?.narrow(1, 0, xd)?;
            let norm = (g.sqr()?.sum_keepdim(1)? + 1e-12)?.sqrt()?;
            let gp = (norm - 1.0)?.sqr()?.mean_all()?;
            gp_v = scalar(&gp)?;
            loss = (loss + (gp * cfg.gp_weight as f64)?)?;
        }
        let bce_v = scalar(&bce)?;
        for (what, v) in [("losses/disc_bce", bce_v), ("losses/disc_gp", gp_v)] {
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    what,
                    value: v,
                    update: self.updates,
                });
            }
        }
        let grads = loss.backward()?;
        self.disc_opt.step(&grads)?;
        self.enc_opt.step(&grads)?;
        let l = logits.detach().flatten_all()?.to_vec1::<f32>()?;
        let acc_e = l[..t * n].iter().filter(|v| **v > 0.0).count() as f32 / (t * n) as f32;
        let acc_p = l[t * n..].iter().filter(|v| **v < 0.0).count() as f32 / (t * n) as f32;
        Ok(DiscStats {
            bce: bce_v,
            gp: gp_v,
            acc_expert: acc_e,
            acc_policy: acc_p,
        })
    }

    /// One SAC step on fresh tasks and contexts with the discriminator's reward.
    pub fn sac_step(&mut self) -> Result<(crate::sac::SacStats, f32)> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, &mut self.rng);
        let n = cfg.sac_per_task;
        let specs: Vec<ContextSpec<'_>> = tasks
            .iter()
            .map(|&ti| sample_context(&self.data.train[ti], cfg.max_context, &mut self.rng))
            .collect();
        let b = self.encoder.batch(&self.data.norm, &specs)?;
        // z from the discriminator's encoder, detached: SAC never updates the encoder.
        let z = self
            .encoder
            .z(&b, true, &mut self.rng)?
            .detach()
            .to_vec2::<f32>()?;
        let mut bv = BatchVecs::default();
        let mut z_rows = Vec::with_capacity(tasks.len() * n * z[0].len());
        for (k, &ti) in tasks.iter().enumerate() {
            self.replay
                .task(ti)
                .sample_into(n, &mut self.rng, &mut bv)?;
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
        let mut dx = Vec::with_capacity(rows * (self.x_dim() + zd));
        for r in 0..rows {
            self.push_x(
                &bv.obs[r * od..(r + 1) * od],
                &bv.act[r * ad..(r + 1) * ad],
                &bv.next_obs[r * od..(r + 1) * od],
                &mut dx,
            );
            dx.extend_from_slice(&z_rows[r * zd..(r + 1) * zd]);
        }
        let dx = Tensor::from_vec(dx, (rows, self.x_dim() + zd), &Device::Cpu)?;
        let c = cfg.logit_clamp as f64;
        let rew = self.disc.forward_const_weights(&dx)?.clamp(-c, c)?.detach();
        let reward_mean = scalar(&rew.mean_all()?)?;
        let batch = crate::replay::Batch {
            obs: policy_input(&self.data.norm, &bv.obs, &z_rows, zd)?,
            act: Tensor::from_slice(&bv.act, (rows, ad), &Device::Cpu)?,
            rew,
            next_obs: policy_input(&self.data.norm, &bv.next_obs, &z_rows, zd)?,
            done: Tensor::from_slice(&bv.done, (rows, 1), &Device::Cpu)?,
        };
        let stats = self.sac.update(&batch, &mut self.rng)?;
        Ok((stats, reward_mean))
    }

    /// Deterministic evaluation on the held-out train tasks (1 context trajectory, 2 contexts).
    pub fn validate(&self) -> Result<f32> {
        quick_eval(
            &self.meta_policy(),
            &self.data.val,
            2,
            self.cfg.eval_episodes,
            self.cfg.env_config(),
        )
    }

    /// Writes the checkpoint (every tensor, the RNG, the counters and the config) to `dir`.
    pub fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        let mut ts: Vec<(String, Tensor)> = Vec::new();
        let mut put = |p: &str, m: &Mlp| {
            for (i, v) in m.vars().iter().enumerate() {
                ts.push((format!("{p}.{i}"), v.as_tensor().detach()));
            }
        };
        put("phi", &self.encoder.phi);
        put("head", &self.encoder.head);
        put("disc", &self.disc);
        let (sac_ts, sac_counters) = self.sac.state_tensors()?;
        ts.extend(sac_ts.into_iter().map(|(k, v)| (format!("sac.{k}"), v)));
        let mut steps = [0u64; 2];
        for (k, (name, opt)) in [("disc_opt", &self.disc_opt), ("enc_opt", &self.enc_opt)]
            .into_iter()
            .enumerate()
        {
            let (m, v, s) = opt.state()?;
            for (i, t) in m.into_iter().enumerate() {
                ts.push((format!("{name}.m.{i}"), t));
            }
            for (i, t) in v.into_iter().enumerate() {
                ts.push((format!("{name}.v.{i}"), t));
            }
            steps[k] = s;
        }
        ts.extend(self.replay.to_tensors("replay")?);
        let meta = serde_json::json!({
            "kind": "smile-run",
            "config": self.cfg,
            "norm": self.data.norm,
            "sac_counters": sac_counters,
            "adam_steps": steps,
            "updates": self.updates,
            "env_steps": self.env_steps,
            "episodes": self.episodes,
            "best": if self.best.is_nan() { serde_json::Value::Null } else { self.best.into() },
            "rng": rng_state(&self.rng),
        });
        checkpoint::save(dir, &ts, &meta)?;
        Ok(())
    }

    /// Resumes the run checkpointed in `dir` on the same `data`; `total_updates` overrides the
    /// saved target.
    pub fn resume(dir: &Path, data: MetaData, total_updates: Option<u64>) -> Result<Self> {
        let ck = checkpoint::load(dir)?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("smile-run") {
            return Err(Error::Checkpoint {
                path: ck.path().into(),
                reason: "not a SMILe run".into(),
            });
        }
        let mut cfg: SmileConfig = ck.meta_field("config")?;
        if let Some(t) = total_updates {
            cfg.total_updates = t;
        }
        let mut run = Self::new(cfg, data)?;
        let wrap = |e: Error| Error::Checkpoint {
            path: ck.path().to_path_buf(),
            reason: format!("does not match this configuration or data: {e}"),
        };
        let get = |n: &str| ck.get(n);
        let load = |p: &str, m: &Mlp| -> Result<()> {
            let ts = (0..m.vars().len())
                .map(|i| get(&format!("{p}.{i}")))
                .collect::<Result<Vec<_>>>()?;
            m.load_from(&ts)
        };
        load("phi", &run.encoder.phi).map_err(wrap)?;
        load("head", &run.encoder.head).map_err(wrap)?;
        load("disc", &run.disc).map_err(wrap)?;
        let counters: SacCounters = ck.meta_field("sac_counters")?;
        run.sac
            .load_state(&|n| ck.get(&format!("sac.{n}")), counters)
            .map_err(wrap)?;
        let steps: [u64; 2] = ck.meta_field("adam_steps")?;
        for (k, (name, opt)) in [
            ("disc_opt", &mut run.disc_opt),
            ("enc_opt", &mut run.enc_opt),
        ]
        .into_iter()
        .enumerate()
        {
            let n = if k == 0 {
                run.disc.vars().len()
            } else {
                run.encoder.vars().len()
            };
            let m = (0..n)
                .map(|i| get(&format!("{name}.m.{i}")))
                .collect::<Result<Vec<_>>>()?;
            let v = (0..n)
                .map(|i| get(&format!("{name}.v.{i}")))
                .collect::<Result<Vec<_>>>()?;
            opt.set_state(&m, &v, steps[k]).map_err(wrap)?;
        }
        run.replay.load_tensors("replay", &get).map_err(wrap)?;
        run.updates = ck.meta_field("updates")?;
        run.env_steps = ck.meta_field("env_steps")?;
        run.episodes = ck.meta_field("episodes")?;
        run.best = ck.meta_field::<Option<f32>>("best")?.unwrap_or(f32::NAN);
        run.rng = rng_from_state(&ck.meta_field("rng")?).map_err(wrap)?;
        Ok(run)
    }
}

/// Trains until `total_updates`, logging to `dir/metrics.jsonl`, evaluating on held-out train
/// tasks every `eval_every` updates (the best policy so far is saved as
/// `dir/meta_policy.safetensors`; the final one as `dir/last/meta_policy.safetensors`) and
/// checkpointing every `checkpoint_every` updates and at the end.
pub fn train(run: &mut Smile, dir: &Path, on: &mut dyn FnMut(Event)) -> Result<()> {
    let mut log = MetricsLog::open(dir)?;
    let kind = run.data.family.metric_kind();
    if run.updates == 0 && run.replay.total_len() == 0 {
        run.warm_start()?;
    }
    let cfg = run.cfg.clone();
    let (t0, u0) = (std::time::Instant::now(), run.updates);
    let mut next_ckpt =
        (run.updates / cfg.checkpoint_every.max(1) + 1) * cfg.checkpoint_every.max(1);
    let mut next_eval = run
        .updates
        .checked_div(cfg.eval_every)
        .map_or(u64::MAX, |k| (k + 1) * cfg.eval_every);
    if !run.data.val.is_empty() && run.updates == 0 {
        // The untrained policy as the first point of the validation curve.
        let m = run.validate()?;
        log.log(0, &[("eval/val_metric", m as f64)])?;
    }
    while run.updates < cfg.total_updates {
        for _ in 0..cfg.rollouts_per_iter {
            let ti = run.rng.random_range(0..run.data.train.len());
            run.rollout(ti)?;
        }
        let (mut ds, mut ss, mut rm) = (DiscStats::default(), None, 0.0);
        for _ in 0..cfg.updates_per_iter {
            if run.updates >= cfg.total_updates {
                break;
            }
            ds = run.disc_step()?;
            let (s, r) = run.sac_step()?;
            ss = Some(s);
            rm = r;
            run.updates += 1;
            on(Event::Updates(run.updates));
        }
        let ups = (run.updates - u0) as f64 / t0.elapsed().as_secs_f64().max(1e-9);
        let mut fields = vec![
            ("losses/disc_bce", ds.bce as f64),
            ("losses/disc_gp", ds.gp as f64),
            ("charts/disc_acc_expert", ds.acc_expert as f64),
            ("charts/disc_acc_policy", ds.acc_policy as f64),
            ("charts/reward_mean", rm as f64),
            ("charts/sps", ups),
            ("charts/env_steps", run.env_steps as f64),
        ];
        if let Some(s) = &ss {
            fields.extend(crate::metrics::sac_fields(s));
        }
        log.log(run.updates, &fields)?;
        if run.updates >= next_eval || (run.updates >= cfg.total_updates && cfg.eval_every > 0) {
            next_eval = (run.updates / cfg.eval_every + 1) * cfg.eval_every;
            if !run.data.val.is_empty() {
                let m = run.validate()?;
                if better(kind, m, run.best) {
                    run.best = m;
                    run.meta_policy().save(dir)?;
                }
                log.log(
                    run.updates,
                    &[
                        ("eval/val_metric", m as f64),
                        ("eval/val_best", run.best as f64),
                    ],
                )?;
                on(Event::Eval(run.updates, m, run.best));
            }
        }
        if run.updates >= next_ckpt || run.updates >= cfg.total_updates {
            run.save_checkpoint(dir)?;
            next_ckpt =
                (run.updates / cfg.checkpoint_every.max(1) + 1) * cfg.checkpoint_every.max(1);
            on(Event::Checkpoint(run.updates));
        }
    }
    let last = dir.join("last");
    std::fs::create_dir_all(&last).map_err(|e| Error::Io {
        path: last.clone(),
        source: e,
    })?;
    run.meta_policy().save(&last)?;
    if run.data.val.is_empty() || !dir.join(crate::context::META_POLICY_FILE).exists() {
        run.meta_policy().save(dir)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Var;

    #[test]
    fn input_gradient_matches_autograd() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let net = Mlp::new(&[5, 7, 6, 1], &mut rng).unwrap();
        let x: Vec<f32> = (0..20)
            .map(|i| ((i * 37 % 11) as f32 - 5.0) * 0.3)
            .collect();
        let xv = Var::from_tensor(&Tensor::from_vec(x, (4, 5), &Device::Cpu).unwrap()).unwrap();
        let grads = net
            .forward(xv.as_tensor())
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let auto = grads.get(xv.as_tensor()).unwrap().to_vec2::<f32>().unwrap();
        let ours = input_gradient(&net, xv.as_tensor())
            .unwrap()
            .to_vec2::<f32>()
            .unwrap();
        for (a, b) in auto.iter().flatten().zip(ours.iter().flatten()) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // And it is differentiable in the weights: the penalty has weight gradients.
        let gp = input_gradient(&net, xv.as_tensor())
            .unwrap()
            .sqr()
            .unwrap()
            .sum_all()
            .unwrap();
        let g = gp.backward().unwrap();
        assert!(g.get(net.vars()[0].as_tensor()).is_some());
        assert!(g.get(net.vars()[4].as_tensor()).is_some());
    }
}
