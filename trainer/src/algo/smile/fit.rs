//! SMILe as a [`Learner`] (the hooks of the one fit loop: the iteration, its CPU-second
//! count, the held-out evaluation schedule) and its configuration's [`MetaSettings`].

use std::path::Path;

use sim::Family;

use super::{Smile, SmileConfig};
use crate::algo::fit::{Cadence, Evaluation, Fields, Progress};
use crate::algo::learner::{Algo, Learner, MetaInputs, MetaSettings, Unit};
use crate::algo::setting::Setting;
use crate::data::better;
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::model::DiscStats;

impl Learner for Smile {
    type Config = SmileConfig;
    type Inputs = MetaInputs;
    const UNIT: Unit = Unit {
        plural: "update pairs",
        word: "update",
    };

    fn start(cfg: SmileConfig, inputs: MetaInputs) -> Result<Self> {
        if inputs.expert.is_some() {
            return Err(Error::takes_no_expert(cfg.algo_name()));
        }
        Smile::new(cfg, inputs.data)
    }

    fn resume(dir: &Path, inputs: MetaInputs, wanted: &SmileConfig) -> Result<Self> {
        if inputs.expert.is_some() {
            return Err(Error::takes_no_expert(wanted.algo_name()));
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
            metric: m,
            best: self.best,
            val_mse: None,
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
