//! Meta-BC / Meta-DAgger as a [`Learner`] (the hooks of the one fit loop: the step and
//! DAgger's rollouts, the evaluation and patience rule) and its configuration's
//! [`MetaSettings`].

use std::path::Path;

use sim::Family;

use super::{MetaBc, MetaBcConfig, Selection};
use crate::algo::fit::{Cadence, Evaluation, Fields, Progress};
use crate::algo::learner::{Algo, Learner, MetaInputs, MetaSettings, Unit};
use crate::algo::setting::Setting;
use crate::data::{better, quick_eval};
use crate::error::Result;
use crate::io::MetricsLog;

impl Learner for MetaBc {
    type Config = MetaBcConfig;
    type Inputs = MetaInputs;
    const UNIT: Unit = Unit {
        plural: "steps",
        word: "step",
    };

    fn start(cfg: MetaBcConfig, inputs: MetaInputs) -> Result<Self> {
        MetaBc::new(cfg, inputs.data, inputs.expert)
    }

    fn resume(dir: &Path, inputs: MetaInputs, wanted: &MetaBcConfig) -> Result<Self> {
        MetaBc::resume(dir, inputs.data, inputs.expert, Some(wanted.total_steps))
    }

    fn config(&self) -> &MetaBcConfig {
        &self.cfg
    }

    fn done(&self) -> u64 {
        self.steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            total: self.cfg.total_steps,
            eval_every: self.cfg.eval_every,
            eval_at_end: true,
            checkpoint_every: self.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn finished(&self) -> bool {
        self.steps >= self.cfg.total_steps || self.stopped
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let cfg = &self.cfg;
        if cfg.dagger && self.steps.is_multiple_of(cfg.dagger_every.max(1)) {
            self.dagger_rollouts(cfg.dagger_rollouts)?;
        }
        let mse = self.step()?;
        on(Progress::Steps(self.steps));
        if !self.steps.is_multiple_of(50) {
            return Ok(Vec::new());
        }
        Ok(vec![
            ("losses/bc_mse", mse as f64),
            ("charts/dataset_size", self.dataset_size() as f64),
        ])
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let at_end = self.steps >= self.cfg.total_steps;
        let cfg = &self.cfg;
        let val_mse = self.val_mse()?;
        let val_metric = quick_eval(
            &self.meta_policy(),
            &self.data.val,
            cfg.held_out(),
            cfg.env_config(),
        )?;
        let improved = match cfg.select_by {
            Selection::Mse => val_mse < self.best_mse,
            Selection::Rollouts => {
                better(self.data.family.metric_kind(), val_metric, self.best_metric)
            }
        };
        // Without held-out tasks the last policy is the one kept.
        let keep = improved || (self.data.val.is_empty() && at_end);
        if keep {
            (self.best_mse, self.best_metric) = (val_mse, val_metric);
            self.bad_evals = 0;
        } else {
            self.bad_evals += 1;
            if cfg.patience > 0 && self.bad_evals >= cfg.patience {
                // The stopping rule: `finished` now tells the loop.
                self.stopped = true;
            }
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/val_mse", val_mse as f64),
                ("eval/val_metric", val_metric as f64),
                ("eval/val_best_mse", self.best_mse as f64),
                ("eval/val_best_metric", self.best_metric as f64),
            ],
            metric: val_metric,
            best: self.best_metric,
            val_mse: Some(val_mse),
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        MetaBc::save_checkpoint(self, dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.meta_policy().save_marked(dir, Some(self.mark(false)))
    }

    fn finish(&mut self, dir: &Path, _log: &mut MetricsLog) -> Result<()> {
        self.meta_policy().save_final(dir, self.mark(true), false)
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
