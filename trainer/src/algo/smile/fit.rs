//! SMILe in the shared fit loop (its [`Fit`] hooks: the iteration, its CPU-second count, the
//! held-out evaluation schedule) and its [`MetaLearner`] impl.

use std::path::Path;

use sim::Family;

use super::{Smile, SmileConfig};
use crate::algo::expert::ExpertSet;
use crate::algo::fit::{Cadence, Evaluation, Fields, Fit, Progress, finish_meta_policy, fit};
use crate::algo::learner::{Algo, MetaLearner};
use crate::algo::settings::Overrides;
use crate::data::{MetaData, better};
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::model::{DiscStats, MetaPolicy};

/// Trains until `total_updates` (or the `cpu_budget_s` compute budget) through the shared fit
/// loop ([`fit`]): metrics in `dir/metrics.jsonl`, an evaluation on held-out train tasks every
/// `eval_every` updates (the best policy so far in `dir/meta_policy.safetensors`; the final
/// one in `dir/last/`), a checkpoint every `checkpoint_every` updates and at the end.
pub fn train(run: &mut Smile, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
    let u0 = run.updates;
    let mut f = SmileFit {
        run,
        t0: std::time::Instant::now(),
        u0,
    };
    fit(&mut f, dir, on)
}

/// A SMILe run inside the fit loop, with its throughput clock.
struct SmileFit<'a> {
    run: &'a mut Smile,
    /// Wall clock and update count when this process started training.
    t0: std::time::Instant,
    u0: u64,
}

impl Fit for SmileFit<'_> {
    fn done(&self) -> u64 {
        self.run.updates
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            eval_every: self.run.cfg.eval_every,
            eval_at_end: true,
            checkpoint_every: self.run.cfg.checkpoint_every,
            cpu_budget_s: self.run.cfg.cpu_budget_s,
        }
    }

    fn begin(&mut self, log: &mut MetricsLog) -> Result<()> {
        let run = &mut *self.run;
        if run.updates == 0 && run.replay.total_len() == 0 {
            run.warm_start()?;
        }
        (self.t0, self.u0) = (std::time::Instant::now(), run.updates);
        if !run.data.val.is_empty() && run.updates == 0 {
            // The untrained policy as the first point of the validation curve.
            let m = run.validate()?;
            log.log(0, &[("eval/val_metric", m as f64)])?;
        }
        Ok(())
    }

    fn finished(&self) -> bool {
        self.run.updates >= self.run.cfg.total_updates
    }

    fn cpu_before(&self) -> f64 {
        self.run.cpu_s
    }

    fn counted(&mut self, cpu_s: f64) -> Option<(&'static str, f64)> {
        self.run.cpu_s = cpu_s;
        Some(("charts/cpu_s", cpu_s))
    }

    // Algorithm 1: each iteration adds m trajectories to the task replays, then alternates d
    // times between the discriminator (+ encoder) and the policy.
    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let run = &mut *self.run;
        let report = run.iteration(&mut |u| on(Progress::Steps(u)))?;
        let (ds, ss, rm) = match report.last {
            Some((d, s, r)) => (d, Some(s), r),
            None => (DiscStats::default(), None, 0.0),
        };
        let ups = (run.updates - self.u0) as f64 / self.t0.elapsed().as_secs_f64().max(1e-9);
        let cfg = &run.cfg;
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
            fields.extend(s.fields());
        }
        if cfg.bc_weight > 0.0 {
            // The weight of the pair just done.
            let w = cfg.bc_weight_at(run.updates.saturating_sub(1));
            fields.push(("charts/bc_weight", w as f64));
        }
        Ok(fields)
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let run = &mut *self.run;
        if run.data.val.is_empty() {
            return Ok(None);
        }
        let m = run.validate()?;
        let keep = better(run.data.family.metric_kind(), m, run.best);
        if keep {
            run.best = m;
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/val_metric", m as f64),
                ("eval/val_best", run.best as f64),
            ],
            progress: Progress::Eval {
                step: run.updates,
                metric: m,
                best: run.best,
                val_mse: None,
            },
            stopped: false,
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
        let replaces = self.run.data.val.is_empty();
        finish_meta_policy(&self.run.meta_policy(), self.run.mark(true), dir, replaces)
    }
}

impl MetaLearner for Smile {
    type Config = SmileConfig;
    const STEP_NAME: &'static str = "update pairs";
    const STEP_WORD: &'static str = "update";
    const RESUMABLE: &'static [&'static str] = &["total_updates", "cpu_budget_s"];

    fn configure(cfg: &mut SmileConfig, algo: Algo, family: Family) {
        cfg.env = family;
        cfg.context.state_only = algo == Algo::SmileStateOnly;
    }

    fn apply(cfg: &mut SmileConfig, _: Algo, o: &Overrides) -> Result<()> {
        Overrides::set(&mut cfg.total_updates, &o.updates);
        Overrides::set(&mut cfg.cpu_budget_s, &o.cpu_budget_s);
        Overrides::set(&mut cfg.seed, &o.seed);
        Overrides::set(&mut cfg.learner_threads, &o.learner_threads);
        Overrides::set(&mut cfg.eval_every, &o.eval_every);
        Overrides::set(&mut cfg.sac.hidden, &o.hidden);
        Overrides::set(&mut cfg.disc_hidden, &o.hidden);
        Overrides::set(&mut cfg.gp_weight, &o.gp_weight);
        Overrides::set(&mut cfg.sac.reward_scale, &o.reward_scale);
        Overrides::set(&mut cfg.bc_weight, &o.bc_weight);
        Overrides::set(&mut cfg.physics, &o.physics);
        Ok(())
    }

    fn budget(cfg: &SmileConfig) -> Option<Overrides> {
        Some(Overrides {
            updates: Some(cfg.total_updates),
            cpu_budget_s: Some(cfg.cpu_budget_s),
            ..Overrides::default()
        })
    }

    fn validate(cfg: &SmileConfig) -> Result<()> {
        cfg.validate()
    }

    fn holdout_every(cfg: &SmileConfig) -> usize {
        cfg.holdout_every
    }

    fn start(cfg: SmileConfig, data: MetaData, expert: Option<ExpertSet>) -> Result<Self> {
        refuse_expert(cfg.algo_name(), expert.is_some())?;
        Smile::new(cfg, data)
    }

    fn resume_from(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        wanted: &SmileConfig,
    ) -> Result<Self> {
        refuse_expert("smile", expert.is_some())?;
        let mut run = Smile::resume(dir, data, Some(wanted.total_updates))?;
        run.set_cpu_budget(wanted.cpu_budget_s)?;
        Ok(run)
    }

    fn settings(&self) -> &SmileConfig {
        self.config()
    }

    fn total(&self) -> u64 {
        self.config().total_updates
    }

    fn done(&self) -> u64 {
        self.updates()
    }

    fn run(&mut self, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
        crate::algo::smile::train(self, dir, on)
    }

    fn policy(&self) -> MetaPolicy {
        self.meta_policy()
    }
}

/// Refuses an expert given to an algorithm that learns from the demos alone.
fn refuse_expert(algo: &str, given: bool) -> Result<()> {
    if given {
        return Err(Error::Config(format!(
            "{algo} learns from the demos alone and takes no expert (Meta-DAgger does)"
        )));
    }
    Ok(())
}
