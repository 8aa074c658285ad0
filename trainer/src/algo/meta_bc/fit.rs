//! Meta-BC / Meta-DAgger in the shared fit loop (its [`Fit`] hooks: the step and DAgger's
//! rollouts, the evaluation and patience rule) and its [`MetaLearner`] impl.

use std::path::Path;

use sim::Family;

use super::{MetaBc, MetaBcConfig, Selection};
use crate::algo::expert::ExpertSet;
use crate::algo::fit::{Cadence, Evaluation, Fields, Fit, Progress, finish_meta_policy, fit};
use crate::algo::learner::{Algo, MetaLearner};
use crate::algo::settings::Overrides;
use crate::data::{MetaData, better, quick_eval};
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::model::MetaPolicy;

/// Trains until `total_steps` or the stopping rule through the shared fit loop ([`fit`]);
/// logs `losses/bc_mse`, `eval/val_mse`, `eval/val_metric`; keeps the best weights by
/// `select_by` (lowest validation MSE, or best held-out rollout metric) in
/// `dir/meta_policy.safetensors` and the final ones in `dir/last/`.
pub fn train(run: &mut MetaBc, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
    let (t0, s0) = (std::time::Instant::now(), run.steps);
    fit(&mut MetaBcFit { run, t0, s0 }, dir, on)
}

/// A Meta-BC / Meta-DAgger run inside the fit loop, with this process's clock.
struct MetaBcFit<'a> {
    run: &'a mut MetaBc,
    t0: std::time::Instant,
    s0: u64,
}

impl MetaBcFit<'_> {
    fn at_end(&self) -> bool {
        self.run.steps >= self.run.cfg.total_steps
    }
}

impl Fit for MetaBcFit<'_> {
    fn done(&self) -> u64 {
        self.run.steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            eval_every: self.run.cfg.eval_every,
            eval_at_end: true,
            checkpoint_every: self.run.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn finished(&self) -> bool {
        self.at_end() || self.run.stopped
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let run = &mut *self.run;
        let cfg = &run.cfg;
        if cfg.dagger && run.steps.is_multiple_of(cfg.dagger_every.max(1)) {
            run.dagger_rollouts(cfg.dagger_rollouts)?;
        }
        let mse = run.step()?;
        on(Progress::Steps(run.steps));
        if !run.steps.is_multiple_of(50) {
            return Ok(Vec::new());
        }
        let sps = (run.steps - self.s0) as f64 / self.t0.elapsed().as_secs_f64().max(1e-9);
        Ok(vec![
            ("losses/bc_mse", mse as f64),
            ("charts/sps", sps),
            ("charts/dataset_size", run.dataset_size() as f64),
        ])
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let at_end = self.at_end();
        let run = &mut *self.run;
        let cfg = &run.cfg;
        let val_mse = run.val_mse()?;
        let val_metric = quick_eval(
            &run.meta_policy(),
            &run.data.val,
            cfg.eval_contexts,
            cfg.eval_context_size,
            cfg.eval_episodes,
            cfg.env_config(),
        )?;
        let improved = match cfg.select_by {
            Selection::Mse => val_mse < run.best_mse,
            Selection::Rollouts => {
                better(run.data.family.metric_kind(), val_metric, run.best_metric)
            }
        };
        // Without held-out tasks the last policy is the one kept.
        let keep = improved || (run.data.val.is_empty() && at_end);
        let mut stopped = false;
        if keep {
            (run.best_mse, run.best_metric) = (val_mse, val_metric);
            run.bad_evals = 0;
        } else {
            run.bad_evals += 1;
            if cfg.patience > 0 && run.bad_evals >= cfg.patience {
                run.stopped = true;
                stopped = true;
            }
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/val_mse", val_mse as f64),
                ("eval/val_metric", val_metric as f64),
                ("eval/val_best_mse", run.best_mse as f64),
                ("eval/val_best_metric", run.best_metric as f64),
            ],
            progress: Progress::Eval {
                step: run.steps,
                metric: val_metric,
                best: run.best_metric,
                val_mse: Some(val_mse),
            },
            stopped,
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        self.run.save_checkpoint(dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.run
            .meta_policy()
            .save_marked(dir, Some(self.run.mark(false)))
    }

    fn finish(&mut self, dir: &Path, _log: &mut MetricsLog) -> Result<()> {
        finish_meta_policy(&self.run.meta_policy(), self.run.mark(true), dir, false)
    }
}

impl MetaLearner for MetaBc {
    type Config = MetaBcConfig;
    const STEP_NAME: &'static str = "steps";
    const STEP_WORD: &'static str = "step";
    const RESUMABLE: &'static [&'static str] = &["total_steps"];

    fn configure(cfg: &mut MetaBcConfig, algo: Algo, family: Family) {
        cfg.env = family;
        cfg.dagger = algo == Algo::MetaDagger;
    }

    fn apply(cfg: &mut MetaBcConfig, algo: Algo, o: &Overrides) -> Result<()> {
        let smile_only = [
            ("cpu_budget_s", o.cpu_budget_s.is_some()),
            ("gp_weight", o.gp_weight.is_some()),
            ("sac.reward_scale", o.reward_scale.is_some()),
            ("bc_weight", o.bc_weight.is_some()),
        ];
        if let Some((key, _)) = smile_only.into_iter().find(|(_, given)| *given) {
            return Err(Error::NoSuchSetting {
                key,
                algo: algo.name(),
            });
        }
        Overrides::set(&mut cfg.total_steps, &o.updates);
        Overrides::set(&mut cfg.seed, &o.seed);
        Overrides::set(&mut cfg.learner_threads, &o.learner_threads);
        Overrides::set(&mut cfg.eval_every, &o.eval_every);
        Overrides::set(&mut cfg.policy_hidden, &o.hidden);
        Overrides::set(&mut cfg.physics, &o.physics);
        Ok(())
    }

    fn budget(_: &MetaBcConfig) -> Option<Overrides> {
        // Its policy is the one early stopping on held-out data picked: more steps are
        // another selection, a new run.
        None
    }

    fn validate(cfg: &MetaBcConfig) -> Result<()> {
        cfg.validate()
    }

    fn holdout_every(cfg: &MetaBcConfig) -> usize {
        cfg.holdout_every
    }

    fn start(cfg: MetaBcConfig, data: MetaData, expert: Option<ExpertSet>) -> Result<Self> {
        MetaBc::new(cfg, data, expert)
    }

    fn resume_from(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        wanted: &MetaBcConfig,
    ) -> Result<Self> {
        MetaBc::resume(dir, data, expert, Some(wanted.total_steps))
    }

    fn settings(&self) -> &MetaBcConfig {
        self.config()
    }

    fn total(&self) -> u64 {
        self.config().total_steps
    }

    fn done(&self) -> u64 {
        self.steps()
    }

    fn run(&mut self, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
        crate::algo::meta_bc::train(self, dir, on)
    }

    fn policy(&self) -> MetaPolicy {
        self.meta_policy()
    }
}
