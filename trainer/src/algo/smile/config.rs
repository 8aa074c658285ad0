//! SMILe's hyper-parameters.

use serde::{Deserialize, Serialize};
use sim::{EnvConfig, Family};

use crate::algo::learner::{Algo, MetaSettings};
use crate::algo::sac::SacConfig;
use crate::algo::setting::Setting;
use crate::data::{ContextDraw, HeldOut};
use crate::error::{Error, Result};
use crate::model::ContextConfig;

/// SMILe hyper-parameters. Defaults are the reference's point-goal prototype (§7) scaled for a
/// CPU: encoder 64 -> r 32 -> 64 x 64 head -> z 16, discriminator and SAC 2 x 128, reward
/// scale 8, gradient penalty 1, 1 disc : 1 SAC step, 8 tasks per batch; per-task batch sizes
/// 64 (reference 128).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmileConfig {
    /// Task family, written by its name (`cheetah-vel`). Default `point-goal`.
    pub env: Family,
    /// Physics backend of the plant, `rapier` (default) or `mujoco`; the demos must have been
    /// recorded on it. A config written before the MuJoCo backend existed reads as Rapier.
    pub physics: sim::Physics,
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
    /// Most transitions encoded per context trajectory during training, drawn at random
    /// without replacement at every draw (an unbiased estimate of the encoder's per-trajectory
    /// mean); 0 = all of them, as the paper. A CPU-budget knob for unsubsampled demos (a
    /// 1000-step trajectory costs 20x a subsampled one); evaluation always encodes whole
    /// trajectories. Default 0.
    pub context_steps: usize,
    /// Rollouts per iteration, the paper's `m` (section 3.5, Algorithm 1). Default 5 (ref).
    pub rollouts_per_iter: usize,
    /// Update pairs (1 discriminator + 1 SAC step) per iteration, the paper's `d`. Default
    /// 100 (ref).
    pub updates_per_iter: usize,
    /// Total update pairs. Default 30 000: on point-goal the kept policy still improved
    /// between 15k and 30k (seed 0: test 0.156 -> 0.118; docs/RESULTS.md).
    pub total_updates: u64,
    /// Replay capacity per task. Default 20 000.
    pub replay_per_task: usize,
    /// Hold out every n-th meta-train task for validation (0: none). Default 8.
    pub holdout_every: usize,
    /// Evaluate on the held-out train tasks every this many updates (0: never). Default 1000.
    pub eval_every: u64,
    /// Context draws (one demo each, in order) per held-out task in that evaluation. Default 4
    /// (every demo of a 4-demo task once): this evaluation picks the kept policy, and with 2
    /// draws its noise made the pick optimistic.
    pub eval_contexts: usize,
    /// Deterministic episodes per held-out task and context in that evaluation. Default 3.
    pub eval_episodes: usize,
    /// Trajectories per context in that evaluation (draw d uses demos d*k..d*k+k). Default 1,
    /// the paper's one-demo protocol; ant-linclass, whose task needs several demos, uses 4.
    pub eval_context_size: usize,
    /// Learner threads (cores the updates use): 1 runs each update pair as Algorithm 1 does
    /// (discriminator step, then the SAC step on the updated discriminator's reward); N > 1
    /// runs the discriminator step *while* the SAC step runs, so SAC's reward comes from the
    /// discriminator before this pair's update (one update older), in a pool of N threads
    /// that also splits every large matrix product of both steps (`crate::threads`), and the
    /// iteration's rollouts run on the pool beside its pairs, entering the replays after them
    /// (`Smile::iteration`). Deterministic for a seed and the same on any N > 1 (the
    /// discriminator step and the rollouts have their own RNGs drawn from the run's; a split
    /// product equals an unsplit one). Measured in docs/BENCHMARKS.md ("The authors' shapes
    /// after ...": 1.78-1.88x on two cores). Each thread needs a free core: `smile sweep`
    /// counts them when it packs cells. Default 1.
    pub learner_threads: usize,
    /// Checkpoint every this many updates (at iteration ends). Default 2000.
    pub checkpoint_every: u64,
    /// A compute budget: stop at the end of the first iteration after the run has used this
    /// many CPU-seconds (user + system, every thread, summed over its resumes: the checkpoint
    /// keeps the count), then evaluate, checkpoint and finish as at `total_updates`. Comparisons at
    /// equal compute then hold on a machine shared with other work, where wall-clock ones do
    /// not (issue 32: the authors' widths against narrow ones). 0: no budget. Like
    /// `total_updates` it may change on `--resume`. Default 0.
    #[serde(skip_serializing_if = "is_zero_f64")]
    pub cpu_budget_s: f64,
    /// SMILe + BC (beyond the paper; issue 29): weight `w` of an auxiliary cloning term
    /// `w mean ||tanh(mu([norm(s_E), z])) - a_E||^2` on SAC's actor loss, over `sac_per_task`
    /// expert transitions of each task of the SAC batch, z that task's detached latent
    /// (as in BC-augmented GAIL, Jena et al. 2020). State-action only: the state-only
    /// variant has no expert actions. 0 is SMILe itself, bit for bit. Default 0.
    #[serde(skip_serializing_if = "is_zero_f32")]
    pub bc_weight: f32,
    /// Decay `bc_weight` linearly to 0 over this many update pairs (0: keep it constant);
    /// after that the run is plain SMILe. Default 0.
    #[serde(skip_serializing_if = "is_zero_u64")]
    pub bc_decay_updates: u64,
    /// SMILe + BC: the cloning rows' weight on the episodes' first steps, as Meta-BC's
    /// `[early]` (issue 70 item 3): a demo transition recorded before step `steps` is drawn
    /// `weight` times as often. Needs `bc_weight > 0`. Default none (every row alike).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bc_early: Option<crate::data::EarlyWeight>,
    /// walker-dyn: end the *training* rollouts when the walker falls. AIRL's reward is signed
    /// (log D - log(1 - D)): early in training the policy's transitions score below zero, and
    /// with termination the quickest way to stop losing reward is to fall. Without it a fallen
    /// walker keeps collecting the discriminator's verdict on lying on the ground. Evaluation
    /// always ends episodes as the family defines (a fall ends a walker-dyn episode). Not in
    /// the reference. Default false.
    pub rollout_termination: bool,
    /// Episode length override. Default None.
    pub horizon: Option<usize>,
    /// Seed of everything. Default 0.
    pub seed: u64,
    /// Train through the device's senses (issue 73; not in the paper or the reference): the
    /// training rollouts act on the plant as the device's sensors read it (noise, then the
    /// ADC: `sim::SensorModel`, the one firmware-sim's loop reads through, seeded with each
    /// episode's reset seed), and SAC's actor, in its own loss and in the critics' targets,
    /// reads the replay's states through the same model (the `fraction` of rows), as does
    /// SMILe + BC's cloning term. The discriminator, the critics and the context encoder read
    /// the true states and the demos as recorded (an asymmetric actor-critic: the device runs
    /// only the policy, and is taught demos recorded on the host). Default none. Preset:
    /// `docs/configs/sensing-noise01-adc12.toml`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensing: Option<crate::data::Sensing>,
}

// Settings that are off are not written, so plain SMILe runs' config.toml and checkpoints
// read as they did before these settings existed.
fn is_zero_f32(v: &f32) -> bool {
    *v == 0.0
}

fn is_zero_u64(v: &u64) -> bool {
    *v == 0
}

fn is_zero_f64(v: &f64) -> bool {
    *v == 0.0
}

impl Default for SmileConfig {
    fn default() -> Self {
        Self {
            env: Family::default(),
            physics: sim::Physics::Rapier,
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
            context_steps: 0,
            rollouts_per_iter: 5,
            updates_per_iter: 100,
            total_updates: 30_000,
            replay_per_task: 20_000,
            holdout_every: 8,
            eval_every: 1000,
            eval_contexts: 4,
            eval_episodes: 3,
            eval_context_size: 1,
            learner_threads: 1,
            checkpoint_every: 2000,
            cpu_budget_s: 0.0,
            bc_weight: 0.0,
            bc_early: None,
            bc_decay_updates: 0,
            rollout_termination: false,
            horizon: None,
            seed: 0,
            sensing: None,
        }
    }
}

impl SmileConfig {
    /// How training draws contexts.
    pub fn context_draw(&self) -> ContextDraw {
        ContextDraw {
            max_trajectories: self.max_context,
            max_steps: self.context_steps,
        }
    }

    /// Episode options of the evaluations (the family's own termination).
    pub fn env_config(&self) -> EnvConfig {
        EnvConfig::new(self.horizon, self.physics)
    }

    /// Episode options of the training rollouts (`rollout_termination`).
    pub fn rollout_env_config(&self) -> EnvConfig {
        EnvConfig {
            healthy_termination: self.rollout_termination,
            ..self.env_config()
        }
    }

    /// The held-out evaluation's contexts and rollouts (`eval_contexts`,
    /// `eval_context_size`, `eval_episodes`).
    pub fn held_out(&self) -> HeldOut {
        HeldOut {
            contexts: self.eval_contexts,
            context_size: self.eval_context_size,
            episodes: self.eval_episodes,
        }
    }

    /// Reject values that cannot train.
    pub fn validate(&self) -> Result<()> {
        self.sac.validate()?;
        crate::io::require_run(
            ("total_updates", self.total_updates),
            &[
                ("tasks_per_batch", self.tasks_per_batch),
                ("disc_per_task", self.disc_per_task),
                ("sac_per_task", self.sac_per_task),
                ("updates_per_iter", self.updates_per_iter),
                ("max_context", self.max_context),
                ("replay_per_task", self.replay_per_task),
                ("rollouts_per_iter", self.rollouts_per_iter),
            ],
            self.horizon,
            self.learner_threads,
        )?;
        self.held_out().check()?;
        for (key, v, min_ok) in [
            ("gp_weight", self.gp_weight, self.gp_weight >= 0.0),
            ("logit_clamp", self.logit_clamp, self.logit_clamp > 0.0),
            ("disc_lr", self.disc_lr, self.disc_lr > 0.0),
            ("enc_lr", self.enc_lr, self.enc_lr > 0.0),
            ("bc_weight", self.bc_weight, self.bc_weight >= 0.0),
        ] {
            if !(v.is_finite() && min_ok) {
                let range = if matches!(key, "gp_weight" | "bc_weight") {
                    ">= 0"
                } else {
                    "> 0"
                };
                return Err(Error::Config(format!(
                    "{key} must be a finite number {range}, not {v}"
                )));
            }
        }
        if !(self.cpu_budget_s.is_finite() && self.cpu_budget_s >= 0.0) {
            return Err(Error::Config(format!(
                "cpu_budget_s must be a finite number of seconds >= 0 (0: none), not {}",
                self.cpu_budget_s
            )));
        }
        if let Some(sensing) = &self.sensing {
            sensing.check()?;
        }
        if let Some(early) = self.bc_early {
            early.check("bc_early")?;
            if self.bc_weight <= 0.0 {
                return Err(Error::Config(
                    "[bc_early] weights SMILe + BC's cloning rows: set bc_weight > 0, or leave \
                     [bc_early] out"
                        .into(),
                ));
            }
        }
        if self.bc_weight > 0.0 && self.context.state_only {
            return Err(Error::Config(
                "bc_weight > 0 (SMILe + BC) clones the expert's actions, and the state-only \
                 variant has none: set bc_weight = 0 or train state-action SMILe"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The cloning term's weight for the update pair after `updates` pairs: `bc_weight`,
    /// decayed linearly to 0 over `bc_decay_updates` pairs when that is set.
    pub fn bc_weight_at(&self, updates: u64) -> f32 {
        if self.bc_decay_updates == 0 {
            return self.bc_weight;
        }
        let left = 1.0 - updates as f64 / self.bc_decay_updates as f64;
        (self.bc_weight as f64 * left.max(0.0)) as f32
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

impl MetaSettings for SmileConfig {
    const EXTENDS: bool = true;

    fn configure(&mut self, algo: Algo, family: Family) {
        self.env = family;
        self.context.state_only = algo == Algo::SmileStateOnly;
    }

    fn set(&mut self, setting: Setting) -> bool {
        match setting {
            Setting::Updates(n) => self.total_updates = n,
            Setting::CpuBudget(s) => self.cpu_budget_s = s,
            Setting::Seed(s) => self.seed = s,
            Setting::LearnerThreads(n) => self.learner_threads = n,
            Setting::EvalEvery(n) => self.eval_every = n,
            Setting::Hidden(h) => (self.sac.hidden, self.disc_hidden) = (h.clone(), h),
            Setting::GpWeight(w) => self.gp_weight = w,
            Setting::RewardScale(r) => self.sac.reward_scale = r,
            Setting::BcWeight(w) => self.bc_weight = w,
            Setting::Physics(p) => self.physics = p,
            Setting::Sensing(s) => self.sensing = Some(s),
        }
        true
    }

    fn budget(&self) -> Vec<Setting> {
        vec![
            Setting::Updates(self.total_updates),
            Setting::CpuBudget(self.cpu_budget_s),
        ]
    }

    fn validate(&self) -> Result<()> {
        SmileConfig::validate(self)
    }

    fn holdout_every(&self) -> usize {
        self.holdout_every
    }
}
