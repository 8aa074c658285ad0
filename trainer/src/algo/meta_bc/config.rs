//! Meta-BC / Meta-DAgger hyper-parameters: every field with a doc line and its default.

use serde::{Deserialize, Serialize};
use sim::{EnvConfig, Family};

use crate::algo::learner::{Algo, MetaSettings};
use crate::algo::setting::Setting;
use crate::data::{ContextDraw, EarlyWeight, HeldOut};
use crate::error::{Error, Result};
use crate::model::ContextConfig;

/// The validation signal that keeps the best policy and stops training, both measured on the
/// held-out *train* tasks (never the meta-test tasks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// Action MSE on the held-out tasks' demos (the supervised loss; cheap).
    #[default]
    Mse,
    /// The family's metric of deterministic rollouts on the held-out tasks (reference §7:
    /// on cheetah, validation MSE did not predict rollout quality).
    Rollouts,
}

/// Meta-BC / Meta-DAgger hyper-parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MetaBcConfig {
    /// Task family, written by its name (`cheetah-vel`). Default `point-goal`.
    pub env: Family,
    /// Physics backend of the plant, `rapier` (default) or `mujoco`; the demos must have been
    /// recorded on it. A config written before the MuJoCo backend existed reads as Rapier.
    pub physics: sim::Physics,
    /// Encoder and latent (as SMILe's).
    pub context: ContextConfig,
    /// Policy hidden widths. Default [128, 128] (as SMILe's SAC actor).
    pub policy_hidden: Vec<usize>,
    /// Adam learning rate (encoder and policy). Default 3e-4.
    pub lr: f32,
    /// Tasks per step. Default 8 (ref).
    pub tasks_per_batch: usize,
    /// Expert pairs per task per step. Default 128 (ref).
    pub per_task: usize,
    /// Most context trajectories. Default 4.
    pub max_context: usize,
    /// Most transitions encoded per context trajectory during training, drawn at random
    /// without replacement at every draw (an unbiased estimate of the encoder's per-trajectory
    /// mean); 0 = all of them, as the paper. A CPU-budget knob for unsubsampled demos (a
    /// 1000-step trajectory costs 20x a subsampled one); evaluation always encodes whole
    /// trajectories. Default 0.
    pub context_steps: usize,
    /// Maximum gradient steps. Default 20 000.
    pub total_steps: u64,
    /// Hold out every n-th meta-train task for validation. Default 8.
    pub holdout_every: usize,
    /// Validate every this many steps. Default 250.
    pub eval_every: u64,
    /// What picks the kept policy and drives early stopping. Default `mse`.
    pub select_by: Selection,
    /// Stop after this many validations without improvement (0: never stop). Default 8.
    pub patience: u32,
    /// Deterministic rollouts per held-out task and context when validating. Default 2.
    pub eval_episodes: usize,
    /// Contexts per held-out task when validating by rollouts (draw d uses demos d*k..d*k+k,
    /// `eval_context_size` = k), as SMILe's `eval_contexts`. Default 2 (what Meta-BC always
    /// used; SMILe's default is 4).
    pub eval_contexts: usize,
    /// Trajectories per context when validating (draw d uses demos d*k..d*k+k). Default 1.
    pub eval_context_size: usize,
    /// Meta-DAgger (needs an expert). Default false.
    pub dagger: bool,
    /// Meta-DAgger: relabelled rollouts every this many steps. Default 50.
    pub dagger_every: u64,
    /// Meta-DAgger: rollouts each time. Default 2.
    pub dagger_rollouts: usize,
    /// Checkpoint every this many steps. Default 2000.
    pub checkpoint_every: u64,
    /// Episode length override. Default None.
    pub horizon: Option<usize>,
    /// Seed. Default 0.
    pub seed: u64,
    /// Learner threads: each gradient step runs in a pool of this many threads that splits
    /// its large matrix products (`crate::threads`); the same weights on any count. Default 1.
    #[serde(skip_serializing_if = "crate::threads::is_one")]
    pub learner_threads: usize,
    /// Regress the policy's pre-tanh mean instead of the action it outputs, `tanh(mean)`: the
    /// original code's loss (reference §3, "original bug"), kept only to measure what it did
    /// to the paper's Meta-BC rows (issue 46). Default false (the executed action; configs
    /// that leave it out are written without it).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub pre_tanh_loss: bool,
    /// Train through the device's senses (issue 73): the `fraction` of the states a training
    /// batch feeds the policy are read through this sensor model (noise, then the ADC;
    /// `sim::SensorModel`, the one firmware-sim's loop reads its plant through), with the
    /// demo's action as their label: noise injection on the demos' states. Meta-DAgger's
    /// rollouts act through it too (the expert labels the true state). The context encoder
    /// reads the demos as recorded (the device is taught a demo recorded on the host), and so
    /// does the held-out MSE that keeps the weights. Default none (the recorded states).
    /// Preset: `docs/configs/sensing-noise01-adc12.toml`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensing: Option<crate::data::Sensing>,
    /// Cloning weight on the episodes' first steps (issue 70 item 3; keyframe-weighted
    /// imitation, Wen et al. 2021): a demo transition recorded before step `steps` is drawn
    /// `weight` times as often as a later one. Where the state soon says what the expert
    /// chose (ant-linclass: the torso's side from step 5-9), only the first steps need the
    /// context to predict the action, and they are a small share of the rows. Default none
    /// (every row alike).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub early: Option<EarlyWeight>,
}

impl Default for MetaBcConfig {
    fn default() -> Self {
        Self {
            env: Family::default(),
            physics: sim::Physics::Rapier,
            context: ContextConfig::default(),
            policy_hidden: vec![128, 128],
            lr: 3e-4,
            tasks_per_batch: 8,
            per_task: 128,
            max_context: 4,
            context_steps: 0,
            total_steps: 20_000,
            holdout_every: 8,
            eval_every: 250,
            select_by: Selection::Mse,
            patience: 8,
            eval_episodes: 2,
            eval_contexts: 2,
            eval_context_size: 1,
            dagger: false,
            dagger_every: 50,
            dagger_rollouts: 2,
            checkpoint_every: 2000,
            horizon: None,
            seed: 0,
            learner_threads: 1,
            pre_tanh_loss: false,
            sensing: None,
            early: None,
        }
    }
}

impl MetaBcConfig {
    /// `meta-bc` or `meta-dagger`.
    pub fn algo_name(&self) -> &'static str {
        if self.dagger {
            "meta-dagger"
        } else {
            "meta-bc"
        }
    }

    /// How training draws contexts.
    pub fn context_draw(&self) -> ContextDraw {
        ContextDraw {
            max_trajectories: self.max_context,
            max_steps: self.context_steps,
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

    /// Episode options (the horizon override).
    pub fn env_config(&self) -> EnvConfig {
        EnvConfig::new(self.horizon, self.physics)
    }

    /// Checks the values: positive batch sizes and rates, a finite positive learning rate.
    pub fn validate(&self) -> Result<()> {
        crate::io::require_run(
            ("total_steps", self.total_steps),
            &[
                ("tasks_per_batch", self.tasks_per_batch),
                ("per_task", self.per_task),
                ("max_context", self.max_context),
            ],
            self.horizon,
            self.learner_threads,
        )?;
        self.held_out().check()?;
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::Config(format!(
                "meta-bc lr must be positive, got {}",
                self.lr
            )));
        }
        if self.policy_hidden.contains(&0) {
            return Err(Error::Config(
                "meta-bc policy_hidden widths must be positive".into(),
            ));
        }
        if let Some(sensing) = &self.sensing {
            sensing.check()?;
            if sensing.positions {
                return Err(Error::Config(
                    "[sensing] positions = true is SMILe's: Meta-BC trains on subsampled demo \
                     states, one tick in k, and the estimator needs every tick"
                        .into(),
                ));
            }
        }
        if let Some(early) = self.early {
            early.check("early")?;
        }
        if self.dagger && (self.dagger_every == 0 || self.dagger_rollouts == 0) {
            return Err(Error::Config(
                "dagger_every and dagger_rollouts must be positive".into(),
            ));
        }
        Ok(())
    }
}

impl MetaSettings for MetaBcConfig {
    // Its policy is the one early stopping on held-out data picked: more steps are another
    // selection, a new run.
    const EXTENDS: bool = false;

    fn configure(&mut self, algo: Algo, family: Family) {
        self.env = family;
        self.dagger = algo == Algo::MetaDagger;
    }

    fn set(&mut self, setting: Setting) -> bool {
        match setting {
            Setting::Updates(n) => self.total_steps = n,
            Setting::Seed(s) => self.seed = s,
            Setting::LearnerThreads(n) => self.learner_threads = n,
            Setting::EvalEvery(n) => self.eval_every = n,
            Setting::Hidden(h) => self.policy_hidden = h,
            Setting::Physics(p) => self.physics = p,
            Setting::Sensing(s) => self.sensing = Some(s),
            // SMILe's: Meta-BC has no compute budget, discriminator or SAC.
            Setting::CpuBudget(_)
            | Setting::GpWeight(_)
            | Setting::RewardScale(_)
            | Setting::BcWeight(_) => return false,
        }
        true
    }

    fn budget(&self) -> Vec<Setting> {
        vec![Setting::Updates(self.total_steps)]
    }

    fn validate(&self) -> Result<()> {
        MetaBcConfig::validate(self)
    }

    fn holdout_every(&self) -> usize {
        self.holdout_every
    }
}
