//! A SAC expert in the shared fit loop ([`fit`]): one episode per unit of work, its periodic
//! deterministic evaluation (keep-best), its checkpoint, and its policy file at the end.

use std::path::Path;

use sim::Task;

use super::{BEST_POLICY_FILE, ExpertTrainer, evaluate};
use crate::algo::fit::{Cadence, Evaluation, Fields, Fit, Progress, fit};
use crate::data::better;
use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::io::checkpoint::POLICY_FILE;

/// Trains until `total_steps` through the shared fit loop: metrics in `dir/metrics.jsonl`,
/// a checkpoint at the first episode end after every `checkpoint_every` env steps and at the
/// end, a deterministic evaluation after every `eval_every` (with `keep_best`, the best one's
/// weights in `dir/policy-best.safetensors`), then the policy in `dir/policy.safetensors`. A
/// non-finite loss returns [`Error::NonFinite`]; the last checkpoint on disk is the last good
/// one.
pub fn train(run: &mut ExpertTrainer, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
    let eval_tasks = match (run.cfg.task_index, run.cfg.task_value) {
        (None, None) => run.family.test_tasks(),
        _ => run.tasks.clone(),
    };
    let (t0, s0) = (std::time::Instant::now(), run.env_steps);
    fit(
        &mut ExpertFit {
            run,
            eval_tasks,
            t0,
            s0,
        },
        dir,
        on,
    )
}

/// An expert run inside the fit loop, with the tasks it is evaluated on and this process's
/// clock.
struct ExpertFit<'a> {
    run: &'a mut ExpertTrainer,
    /// The meta-test tasks, or the expert's own task.
    eval_tasks: Vec<Task>,
    t0: std::time::Instant,
    s0: u64,
}

impl ExpertFit<'_> {
    /// The current actor, deterministic, on the evaluation tasks.
    fn evaluate_now(&self) -> Result<super::EvalReport> {
        let cfg = &self.run.cfg;
        evaluate(
            &self.run.expert(),
            &self.eval_tasks,
            cfg.eval_episodes,
            cfg.env_config(),
        )
    }
}

impl Fit for ExpertFit<'_> {
    fn done(&self) -> u64 {
        self.run.env_steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            eval_every: self.run.cfg.eval_every,
            eval_at_end: false,
            checkpoint_every: self.run.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn finished(&self) -> bool {
        self.run.finished()
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let run = &mut *self.run;
        let rep = run.run_episode(&mut |s| on(Progress::Steps(s)))?;
        let sps = (rep.env_steps - self.s0) as f64 / self.t0.elapsed().as_secs_f64().max(1e-9);
        let mut fields = vec![
            ("charts/episodic_return", rep.episodic_return as f64),
            ("charts/metric", rep.metric as f64),
            ("charts/sps", sps),
            ("charts/updates", run.sac.updates() as f64),
        ];
        if let Some(s) = &rep.last_update {
            fields.extend(s.fields());
        }
        on(Progress::Episode {
            step: rep.env_steps,
            episodic_return: rep.episodic_return,
            metric: rep.metric,
            sps,
        });
        Ok(fields)
    }

    // Deterministic, on its own environment: does not touch the run's state or RNG.
    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let ev = self.evaluate_now()?;
        let run = &mut *self.run;
        let keep = run.cfg.keep_best
            && run
                .best
                .is_none_or(|b| better(run.family.metric_kind(), ev.mean, b.metric));
        if keep {
            run.best = Some(super::BestEval {
                metric: ev.mean,
                env_steps: run.env_steps,
            });
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/metric", ev.mean as f64),
                ("eval/final_sample", ev.final_sample_mean as f64),
            ],
            progress: Progress::Eval {
                step: run.env_steps,
                metric: ev.mean,
                best: run.best.map_or(ev.mean, |b| b.metric),
                val_mse: None,
            },
            stopped: false,
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        self.run.save_checkpoint(dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.run.export_policy_as(dir, BEST_POLICY_FILE)
    }

    /// `policy.safetensors`: the final weights, or with `keep_best` the best-evaluated ones
    /// if the final weights evaluate worse (the same tasks and episodes as the periodic
    /// evaluations).
    fn finish(&mut self, dir: &Path, log: &mut MetricsLog) -> Result<()> {
        let run = &*self.run;
        let best_file = dir.join(BEST_POLICY_FILE);
        let best = match run.best {
            Some(b) if run.cfg.keep_best && best_file.exists() => b,
            _ => return run.export_policy(dir),
        };
        let last = self.evaluate_now()?;
        log.log(run.env_steps, &[("eval/metric", last.mean as f64)])?;
        if better(run.family.metric_kind(), best.metric, last.mean) {
            let io = |e: std::io::Error| Error::Io {
                path: dir.join(POLICY_FILE),
                source: e,
            };
            let tmp = dir.join(".policy-best-copy");
            std::fs::copy(&best_file, &tmp).map_err(io)?;
            std::fs::rename(&tmp, dir.join(POLICY_FILE)).map_err(io)
        } else {
            run.export_policy(dir)
        }
    }
}
