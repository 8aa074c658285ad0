//! Soft actor-critic, SAC v2 (Haarnoja et al. 2018, "Soft Actor-Critic Algorithms and
//! Applications"): twin Q critics with Polyak-averaged targets, a tanh-Gaussian actor and a
//! learned temperature. The paper's original SMILe code used SAC v1 with a fixed temperature
//! and a reward scale; that is available as `learn_alpha = false` + `reward_scale`.
//!
//! One update on a batch `(s, a, r, s', d)`:
//!
//! 1. critic:      `y = c r + gamma (1 - d) (min_j Q'_j(s', a') - alpha log pi(a'|s'))`,
//!    `a' ~ pi(.|s')`; `L_Q = sum_j mean (Q_j(s, a) - y)^2`
//! 2. actor:       `L_pi = mean (alpha log pi(a~|s) - min_j Q_j(s, a~))`, `a~ = tanh(mu + sigma eps)`;
//!    the critic weights are constants here, so no critic gradient is computed.
//!    With an auxiliary cloning term ([`ActorTerm`], SMILe + BC) on expert rows `(s_E, a_E)`:
//!    `L_pi += w mean_rows ||tanh(mu(s_E)) - a_E||^2` (squared error summed over action dims).
//! 3. temperature: `L_alpha = mean -log(alpha) (log pi(a~|s) + H_target)`
//! 4. targets:     `theta'_j <- (1 - tau) theta'_j + tau theta_j`

use candle_core::{Device, Tensor, Var};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::data::Batch;
use crate::error::{Error, Result};
use crate::model::{FrozenMlp, Input, Mlp, SharedCols, TanhGaussianPolicy, TensorLookup, scalar};
use crate::optim::{Adam, AdamConfig};

/// SAC hyper-parameters. Every field has a default; sources: Haarnoja et al. 2018 (SAC v2,
/// "SAC-v2"), the SMILe reference implementation (`docs/reference/smile-reference.md` §2,
/// "ref"), and this project's PyTorch prototypes (reference §7, "proto").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SacConfig {
    /// Hidden widths of the actor and of each critic. Default `[256, 256]` (SAC-v2; proto's
    /// HalfCheetah expert; ref used 3 x 256).
    pub hidden: Vec<usize>,
    /// Hidden widths of the actor when they differ from the critics' (`hidden`). Default
    /// None: the actor uses `hidden` (ref's ant policy was 3 x 512 beside 3 x 256 critics).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actor_hidden: Option<Vec<usize>>,
    /// Discount factor. Default 0.99 (SAC-v2, ref).
    pub gamma: f32,
    /// Polyak rate of the target critics. Default 0.005 (SAC-v2, ref).
    pub tau: f32,
    /// Actor learning rate. Default 3e-4 (SAC-v2, ref).
    pub actor_lr: f32,
    /// Critic learning rate. Default 3e-4 (SAC-v2, ref).
    pub critic_lr: f32,
    /// Temperature learning rate. Default 3e-4 (SAC-v2).
    pub alpha_lr: f32,
    /// Minibatch size. Default 256 (SAC-v2; proto expert used 128).
    pub batch_size: usize,
    /// Learn the temperature (SAC v2). Default true; false = fixed `init_alpha` (ref, SAC v1
    /// style, with `reward_scale` acting as inverse temperature).
    pub learn_alpha: bool,
    /// Initial (or fixed) temperature alpha. Default 1.0 (SAC-v2 implementations; ref fixed 1).
    pub init_alpha: f32,
    /// Entropy target; `None` means `-act_dim`. Default None (SAC-v2).
    pub target_entropy: Option<f32>,
    /// Multiplier c on rewards in the critic target. Default 1.0 (ref grid {4..24} for SMILe
    /// with fixed alpha).
    pub reward_scale: f32,
    /// Lower clamp of the policy's log-sigma. Default -20 (ref).
    pub log_std_min: f32,
    /// Upper clamp of the policy's log-sigma. Default 2 (ref).
    pub log_std_max: f32,
    /// Weight of `mean(mu^2) + mean(log_sigma^2)` added to the actor loss. Default 0 (SAC-v2;
    /// ref's SAC v1 used 1e-3).
    pub policy_reg: f32,
}

impl Default for SacConfig {
    fn default() -> Self {
        Self {
            hidden: vec![256, 256],
            actor_hidden: None,
            gamma: 0.99,
            tau: 0.005,
            actor_lr: 3e-4,
            critic_lr: 3e-4,
            alpha_lr: 3e-4,
            batch_size: 256,
            learn_alpha: true,
            init_alpha: 1.0,
            target_entropy: None,
            reward_scale: 1.0,
            log_std_min: -20.0,
            log_std_max: 2.0,
            policy_reg: 0.0,
        }
    }
}

impl SacConfig {
    /// Reject values that cannot train: every number finite, rates and scales positive, each
    /// message naming the key and its allowed range.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Config(m));
        if self.hidden.is_empty() || self.hidden.contains(&0) {
            return bad("sac.hidden needs at least one positive width".into());
        }
        if let Some(h) = self
            .actor_hidden
            .as_ref()
            .filter(|h| h.is_empty() || h.contains(&0))
        {
            return bad(format!(
                "sac.actor_hidden needs at least one positive width, not {h:?}"
            ));
        }
        for (key, v) in [("sac.gamma", self.gamma), ("sac.tau", self.tau)] {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("{key} must lie in [0, 1], not {v}"));
            }
        }
        for (key, v) in [
            ("sac.actor_lr", self.actor_lr),
            ("sac.critic_lr", self.critic_lr),
            ("sac.alpha_lr", self.alpha_lr),
            ("sac.init_alpha", self.init_alpha),
            ("sac.reward_scale", self.reward_scale),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{key} must be a finite number > 0, not {v}"));
            }
        }
        if !(self.policy_reg.is_finite() && self.policy_reg >= 0.0) {
            return bad(format!(
                "sac.policy_reg must be a finite number >= 0, not {}",
                self.policy_reg
            ));
        }
        if let Some(t) = self.target_entropy.filter(|t| !t.is_finite()) {
            return bad(format!("sac.target_entropy must be finite, not {t}"));
        }
        if self.batch_size == 0 {
            return bad("sac.batch_size must be positive".into());
        }
        if !(self.log_std_min.is_finite()
            && self.log_std_max.is_finite()
            && self.log_std_min < self.log_std_max)
        {
            return bad(format!(
                "sac.log_std_min ({}) must be finite and below sac.log_std_max ({})",
                self.log_std_min, self.log_std_max
            ));
        }
        Ok(())
    }
}

/// Scalars reported by one update, under the names CleanRL's SAC logs them with (so a CleanRL
/// user overlaying the curves reads each one as what it is).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SacStats {
    /// `losses/qf_loss`: the critics' mean squared TD error, averaged over the two critics.
    pub qf_loss: f32,
    /// `losses/qf1_values`: mean Q1(s, a) on the batch.
    pub qf1_mean: f32,
    /// `losses/actor_loss`.
    pub actor_loss: f32,
    /// `losses/alpha_loss`: the temperature's loss (0 with a fixed temperature).
    pub alpha_loss: f32,
    /// `charts/alpha`: the temperature's value used in this update.
    pub alpha: f32,
    /// `charts/entropy`: `-mean log pi(a~|s)`.
    pub entropy: f32,
    /// `losses/bc`: the cloning term's `mean ||tanh(mu(s_E)) - a_E||^2` before its weight
    /// (`None` without an [`ActorTerm`]).
    pub bc_loss: Option<f32>,
}

impl SacStats {
    /// The statistics of one update from its steps' reports.
    pub fn of(alpha: f32, critic: CriticStep, actor: ActorStep, alpha_loss: f32) -> Self {
        Self {
            qf_loss: critic.qf_loss,
            qf1_mean: critic.qf1_mean,
            actor_loss: actor.actor_loss,
            alpha_loss,
            alpha,
            entropy: -actor.mean_logp,
            bc_loss: actor.term,
        }
    }

    /// The scalars under their metric names, for the metrics log.
    pub fn fields(&self) -> Vec<(&'static str, f64)> {
        let mut f = vec![
            ("losses/qf_loss", self.qf_loss as f64),
            ("losses/qf1_values", self.qf1_mean as f64),
            ("losses/actor_loss", self.actor_loss as f64),
            ("losses/alpha_loss", self.alpha_loss as f64),
            ("charts/alpha", self.alpha as f64),
            ("charts/entropy", self.entropy as f64),
        ];
        if let Some(bc) = self.bc_loss {
            f.push(("losses/bc", bc as f64));
        }
        f
    }
}

/// A term added to the actor's loss (SMILe + BC's cloning term, written beside its equation in
/// `algo/smile.rs`): given the actor, the term's weighted loss (a scalar on the actor's graph)
/// and its value before the weight, logged as `losses/bc`.
pub type ActorTerm<'a> = &'a dyn Fn(&TanhGaussianPolicy) -> Result<(Tensor, f32)>;

/// What [`Sac::critic_step`] reports.
#[derive(Debug, Clone, Copy)]
pub struct CriticStep {
    /// The critics' mean squared TD error, averaged over the two critics.
    pub qf_loss: f32,
    /// Mean Q1(s, a) on the batch.
    pub qf1_mean: f32,
}

/// What [`Sac::actor_step`] reports.
#[derive(Debug, Clone, Copy)]
pub struct ActorStep {
    /// The actor's loss, its term included.
    pub actor_loss: f32,
    /// The added term's value before its weight (`None` without one).
    pub term: Option<f32>,
    /// `mean log pi(a~|s)` on the batch (the temperature's step reads it).
    pub mean_logp: f32,
}

/// A SAC agent: actor, twin critics, their targets, optimisers and temperature.
#[derive(Debug, Clone)]
pub struct Sac {
    cfg: SacConfig,
    /// The policy.
    pub actor: TanhGaussianPolicy,
    /// First critic `Q1(s, a)` on `[s, a]`.
    pub q1: Mlp,
    /// Second critic.
    pub q2: Mlp,
    q1_targ: FrozenMlp,
    q2_targ: FrozenMlp,
    log_alpha: Var,
    actor_opt: Adam,
    critic_opt: Adam,
    alpha_opt: Adam,
    target_entropy: f32,
    updates: u64,
}

impl Sac {
    /// A fresh agent for `obs_dim`-dimensional observations and `act_dim` actions in `(-1, 1)`.
    /// All initial weights are drawn from `rng`.
    pub fn new(obs_dim: usize, act_dim: usize, cfg: SacConfig, rng: &mut impl Rng) -> Result<Self> {
        cfg.validate()?;
        let bounds = (cfg.log_std_min, cfg.log_std_max);
        let actor_widths = cfg.actor_hidden.as_ref().unwrap_or(&cfg.hidden);
        let actor = TanhGaussianPolicy::new(obs_dim, act_dim, actor_widths, bounds, rng)?;
        let mut qw = vec![obs_dim + act_dim];
        qw.extend_from_slice(&cfg.hidden);
        qw.push(1);
        let (q1, q2) = (Mlp::new(&qw, rng)?, Mlp::new(&qw, rng)?);
        let (q1_targ, q2_targ) = (q1.frozen_copy()?, q2.frozen_copy()?);
        let log_alpha = Var::from_tensor(&Tensor::new(&[cfg.init_alpha.ln()], &Device::Cpu)?)?;
        let actor_opt = Adam::new(
            actor.net().vars().to_vec(),
            AdamConfig::with_lr(cfg.actor_lr),
        );
        let critic_vars = [q1.vars(), q2.vars()].concat();
        let critic_opt = Adam::new(critic_vars, AdamConfig::with_lr(cfg.critic_lr));
        let alpha_opt = Adam::new(vec![log_alpha.clone()], AdamConfig::with_lr(cfg.alpha_lr));
        let target_entropy = cfg.target_entropy.unwrap_or(-(act_dim as f32));
        Ok(Self {
            cfg,
            actor,
            q1,
            q2,
            q1_targ,
            q2_targ,
            log_alpha,
            actor_opt,
            critic_opt,
            alpha_opt,
            target_entropy,
            updates: 0,
        })
    }

    /// The hyper-parameters.
    pub fn config(&self) -> &SacConfig {
        &self.cfg
    }

    /// Number of updates performed.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Current temperature alpha.
    pub fn alpha(&self) -> Result<f32> {
        Ok(scalar(self.log_alpha.as_tensor())?.exp())
    }

    /// `min(Q1, Q2)` on `[s, a]` (with gradients into the critics' weights if `const_weights` is
    /// false).
    fn q_min(
        &self,
        s: &Tensor,
        a: &Tensor,
        z_cols: Option<SharedCols>,
        const_weights: bool,
    ) -> Result<Tensor> {
        let sa = Tensor::cat(&[s, a], 1)?;
        let sa = Input::shared(&sa, z_cols); // [s, a] keeps s's columns first
        let q = |net: &Mlp| {
            if const_weights {
                net.forward_const_weights(sa)
            } else {
                net.forward(sa)
            }
        };
        let (q1, q2) = crate::threads::join(|| q(&self.q1), || q(&self.q2));
        Ok(q1?.minimum(&q2?)?)
    }

    fn finite(&self, what: &'static str, value: f32) -> Result<f32> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(Error::NonFinite {
                what,
                value,
                update: self.updates,
            })
        }
    }

    /// One SAC update (critic, actor, temperature, targets) on `b`. Noise comes from `rng`.
    ///
    /// A non-finite loss aborts before the corresponding optimiser step with
    /// [`Error::NonFinite`]. SMILe runs the same four steps with its cloning term on the
    /// actor's (`algo/smile.rs`, `sac_update`).
    pub fn update(&mut self, b: &Batch, rng: &mut impl Rng) -> Result<SacStats> {
        let alpha = self.begin_update()?;
        let critic = self.critic_step(b, alpha, rng)?;
        let actor = self.actor_step(b, alpha, None, rng)?;
        let alpha_loss = self.temperature_step(actor.mean_logp)?;
        self.target_step()?;
        Ok(SacStats::of(alpha, critic, actor, alpha_loss))
    }

    /// Counts the update and returns the temperature its steps use (read before any step).
    pub fn begin_update(&mut self) -> Result<f32> {
        self.updates += 1;
        self.alpha()
    }

    /// Step 1 of the module doc, the critics' loss and their optimiser step.
    pub fn critic_step(&mut self, b: &Batch, alpha: f32, rng: &mut impl Rng) -> Result<CriticStep> {
        let (gamma, c) = (self.cfg.gamma as f64, self.cfg.reward_scale as f64);
        // (Where the batch is task-major with each task's z on its rows, every network's first
        // layer computes the z block once per task: `Batch::z_cols`.)
        let zc = b.z_cols;
        // y = c r + gamma (1 - d) (min_j Q'_j(s', a') - alpha log pi(a'|s')), a' ~ pi(.|s')
        // read as the actor reads s' (through the sensors where it trains so: `actor_view`)
        let next = self
            .actor
            .sample_const(Input::shared(b.actor_next_obs(), zc), rng)?;
        let next_sa = Tensor::cat(&[&b.next_obs, &next.action], 1)?;
        let next_sa = Input::shared(&next_sa, zc);
        let (q1_targ, q2_targ) = crate::threads::join(
            || self.q1_targ.forward(next_sa),
            || self.q2_targ.forward(next_sa),
        );
        let q_targ = q1_targ?.minimum(&q2_targ?)?;
        let soft_v = (q_targ - (next.log_prob * alpha as f64)?)?;
        let not_done = b.done.affine(-gamma, gamma)?; // gamma (1 - d)
        let y = ((&b.rew * c)? + (not_done * soft_v)?)?.detach();
        // L_Q = mean (Q1(s,a) - y)^2 + mean (Q2(s,a) - y)^2
        // Each critic's weights get gradient from its own term only, so the two terms' backward
        // passes are separate and their gradients the same bits as one backward of the sum;
        // inside a learner pool the two critics run as the sides of a join.
        let sa = Tensor::cat(&[&b.obs, &b.act], 1)?;
        let critic = |q: &Mlp| -> Result<(Tensor, f32, candle_core::backprop::GradStore)> {
            let qv = q.forward(Input::shared(&sa, zc))?;
            let loss = (&qv - &y)?.sqr()?.mean_all()?;
            let v = scalar(&loss)?;
            let grads = if v.is_finite() {
                loss.backward()?
            } else {
                candle_core::backprop::GradStore::default()
            };
            Ok((qv, v, grads))
        };
        let (c1, c2) = crate::threads::join(|| critic(&self.q1), || critic(&self.q2));
        let ((q1, l1, mut grads), (_, l2, g2)) = (c1?, c2?);
        // Summed over the two critics for the step; logged as their mean, as CleanRL does.
        let qf_loss = self.finite("losses/qf_loss", l1 + l2)? / 2.0;
        grads.extend(g2)?;
        self.critic_opt.step(&grads)?;
        Ok(CriticStep {
            qf_loss,
            qf1_mean: scalar(&q1.mean_all()?)?,
        })
    }

    /// Step 2 of the module doc, the actor's loss (with `term` added: SMILe + BC's cloning
    /// term) and its optimiser step.
    pub fn actor_step(
        &mut self,
        b: &Batch,
        alpha: f32,
        term: Option<ActorTerm<'_>>,
        rng: &mut impl Rng,
    ) -> Result<ActorStep> {
        // L_pi = mean (alpha log pi(a~|s) - min_j Q_j(s, a~)), critic weights constant; the
        // actor reads s as it acts (through the sensors: `actor_view`), the critics the truth
        let cur = self
            .actor
            .sample(Input::shared(b.actor_obs(), b.z_cols), rng)?;
        let q_pi = self.q_min(&b.obs, &cur.action, b.z_cols, true)?;
        let mut actor_loss = ((&cur.log_prob * alpha as f64)? - q_pi)?.mean_all()?;
        if self.cfg.policy_reg > 0.0 {
            let reg = (cur.mean.sqr()?.mean_all()? + cur.log_std.sqr()?.mean_all()?)?;
            actor_loss = (actor_loss + (reg * self.cfg.policy_reg as f64)?)?;
        }
        let mut term_v = None;
        if let Some(term) = term {
            let (weighted, v) = term(&self.actor)?;
            term_v = Some(self.finite("losses/bc", v)?);
            actor_loss = (actor_loss + weighted)?;
        }
        let actor_loss_v = self.finite("losses/actor_loss", scalar(&actor_loss)?)?;
        self.actor_opt.backward_step(&actor_loss)?;
        Ok(ActorStep {
            actor_loss: actor_loss_v,
            term: term_v,
            mean_logp: scalar(&cur.log_prob.mean_all()?)?,
        })
    }

    /// Step 3 of the module doc, the temperature's loss and step (none with a fixed one):
    /// `L_alpha = -log(alpha) * (mean log pi(a~|s) + H_target)`. Returns the loss (0 if fixed).
    pub fn temperature_step(&mut self, mean_logp: f32) -> Result<f32> {
        if !self.cfg.learn_alpha {
            return Ok(0.0);
        }
        let alpha_loss =
            (self.log_alpha.as_tensor() * -(mean_logp + self.target_entropy) as f64)?.sum_all()?;
        let v = self.finite("losses/alpha_loss", scalar(&alpha_loss)?)?;
        self.alpha_opt.backward_step(&alpha_loss)?;
        Ok(v)
    }

    /// Step 4 of the module doc: `theta' <- (1 - tau) theta' + tau theta`.
    pub fn target_step(&mut self) -> Result<()> {
        self.q1_targ.polyak_update(&self.q1, self.cfg.tau)?;
        self.q2_targ.polyak_update(&self.q2, self.cfg.tau)?;
        Ok(())
    }

    /// Every tensor of the agent's state by a stable name: networks, targets, Adam moments and
    /// the temperature. Counters (Adam steps, updates) are returned separately.
    pub fn state_tensors(&self) -> Result<(Vec<(String, Tensor)>, SacCounters)> {
        let mut out = Vec::new();
        let mut put = |prefix: &str, ts: Vec<Tensor>| {
            for (i, t) in ts.into_iter().enumerate() {
                out.push((format!("{prefix}.{i}"), t));
            }
        };
        let vars = |m: &Mlp| {
            m.vars()
                .iter()
                .map(|v| v.as_tensor().detach())
                .collect::<Vec<_>>()
        };
        put("actor", vars(self.actor.net()));
        put("q1", vars(&self.q1));
        put("q2", vars(&self.q2));
        put("q1_targ", self.q1_targ.params().to_vec());
        put("q2_targ", self.q2_targ.params().to_vec());
        put("log_alpha", vec![self.log_alpha.as_tensor().detach()]);
        let steps = [
            self.actor_opt.save_into("actor_opt", &mut out)?,
            self.critic_opt.save_into("critic_opt", &mut out)?,
            self.alpha_opt.save_into("alpha_opt", &mut out)?,
        ];
        Ok((
            out,
            SacCounters {
                updates: self.updates,
                adam_steps: steps,
            },
        ))
    }

    /// Restore the state written by [`Sac::state_tensors`]; `get` looks a tensor up by name.
    /// Shapes must match this agent's configuration.
    pub fn load_state(&mut self, get: TensorLookup, counters: SacCounters) -> Result<()> {
        let many = |prefix: &str, n: usize| -> Result<Vec<Tensor>> {
            (0..n).map(|i| get(&format!("{prefix}.{i}"))).collect()
        };
        let n_net = self.q1.vars().len();
        let n_act = self.actor.net().vars().len();
        self.actor.net().load_from(&many("actor", n_act)?)?;
        self.q1.load_from(&many("q1", n_net)?)?;
        self.q2.load_from(&many("q2", n_net)?)?;
        self.q1_targ.load_from(&many("q1_targ", n_net)?)?;
        self.q2_targ.load_from(&many("q2_targ", n_net)?)?;
        let la = get("log_alpha.0")?;
        if la.dims() != self.log_alpha.dims() {
            return Err(Error::Shape("log_alpha".into()));
        }
        self.log_alpha.set(&la)?;
        let [actor, critic, alpha] = counters.adam_steps;
        self.actor_opt.load_from("actor_opt", get, actor)?;
        self.critic_opt.load_from("critic_opt", get, critic)?;
        self.alpha_opt.load_from("alpha_opt", get, alpha)?;
        self.updates = counters.updates;
        Ok(())
    }
}

/// Step counters of a [`Sac`] agent, saved beside its tensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SacCounters {
    /// Updates performed.
    pub updates: u64,
    /// Adam step counts of the actor, critic and temperature optimisers.
    pub adam_steps: [u64; 3],
}
