//! A SAC expert as a [`Learner`] of the one fit loop: one episode per unit of work, its
//! periodic deterministic evaluation (keep-best), its checkpoint, and its policy file at the
//! end. A non-finite loss returns [`Error::NonFinite`]; the last checkpoint on disk is the last
//! good one.

use std::path::Path;

use super::{BEST_POLICY_FILE, ExpertConfig, ExpertTrainer, evaluate};
use crate::algo::fit::{Cadence, Evaluation, Fields, Progress};
use crate::algo::learner::{Learner, Unit};
use crate::data::better;
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::io::checkpoint::POLICY_FILE;

impl ExpertTrainer {
    /// The current actor, deterministic, on the evaluation tasks: the meta-test tasks, or the
    /// expert's own task.
    fn evaluate_now(&self) -> Result<super::EvalReport> {
        let cfg = &self.cfg;
        let eval_tasks = match (cfg.task_index, cfg.task_value) {
            (None, None) => self.family.test_tasks(),
            _ => self.tasks.clone(),
        };
        evaluate(
            &self.expert(),
            &eval_tasks,
            cfg.eval_episodes,
            cfg.env_config(),
        )
    }
}

impl Learner for ExpertTrainer {
    type Config = ExpertConfig;
    type Inputs = ();
    const UNIT: Unit = Unit {
        plural: "env steps",
        word: "env step",
    };

    fn start(cfg: ExpertConfig, (): ()) -> Result<Self> {
        ExpertTrainer::new(cfg)
    }

    fn resume(dir: &Path, (): (), wanted: &ExpertConfig) -> Result<Self> {
        ExpertTrainer::resume(dir, Some(wanted.total_steps))
    }

    fn config(&self) -> &ExpertConfig {
        &self.cfg
    }

    fn done(&self) -> u64 {
        self.env_steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            total: self.cfg.total_steps,
            eval_every: self.cfg.eval_every,
            eval_at_end: false,
            checkpoint_every: self.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let rep = self.run_episode(&mut |s| on(Progress::Steps(s)))?;
        let mut fields = vec![
            ("charts/episodic_return", rep.episodic_return as f64),
            ("charts/metric", rep.metric as f64),
            ("charts/updates", self.sac.updates() as f64),
        ];
        if let Some(s) = &rep.last_update {
            fields.extend(s.fields());
        }
        on(Progress::Episode {
            step: rep.env_steps,
            episodic_return: rep.episodic_return,
            metric: rep.metric,
        });
        Ok(fields)
    }

    // Deterministic, on its own environment: does not touch the run's state or RNG.
    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let ev = self.evaluate_now()?;
        let keep = self.cfg.keep_best
            && self
                .best
                .is_none_or(|b| better(self.family.metric_kind(), ev.mean, b.metric));
        if keep {
            self.best = Some(super::BestEval {
                metric: ev.mean,
                env_steps: self.env_steps,
            });
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/metric", ev.mean as f64),
                ("eval/final_sample", ev.final_sample_mean as f64),
            ],
            metric: ev.mean,
            best: self.best.map_or(ev.mean, |b| b.metric),
            val_mse: None,
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        ExpertTrainer::save_checkpoint(self, dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.export_policy_as(dir, BEST_POLICY_FILE)
    }

    /// `policy.safetensors`: the final weights, or with `keep_best` the best-evaluated ones
    /// if the final weights evaluate worse (the same tasks and episodes as the periodic
    /// evaluations).
    fn finish(&mut self, dir: &Path, log: &mut MetricsLog) -> Result<()> {
        let best_file = dir.join(BEST_POLICY_FILE);
        let best = match self.best {
            Some(b) if self.cfg.keep_best && best_file.exists() => b,
            _ => return self.export_policy(dir),
        };
        let last = self.evaluate_now()?;
        log.log(self.env_steps, &[("eval/metric", last.mean as f64)])?;
        if better(self.family.metric_kind(), best.metric, last.mean) {
            let bytes = std::fs::read(&best_file).map_err(|e| Error::Io {
                path: best_file.clone(),
                source: e,
            })?;
            crate::io::checkpoint::write_atomic(&dir.join(POLICY_FILE), &bytes)
        } else {
            self.export_policy(dir)
        }
    }
}
