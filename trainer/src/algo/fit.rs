//! The one fit loop every meta-learner trains through, in the way of burn's `Learner::fit` or
//! SB3's `learn`: the metrics log, progress, held-out evaluation and keeping the best policy,
//! checkpoints, the budget and the learner's own stopping rule, and the final policies
//! (`last/` and the kept one) are written here once. A learner is its update step and its
//! models; it tells the loop when its evaluations and checkpoints are due through [`Fit`].
//!
//! ```text
//! begin                      (warm start, the untrained policy's evaluation)
//! while !finished:
//!     advance                (SMILe: one iteration of Algorithm 1; Meta-BC: one step)
//!     log its metrics
//!     if eval_due: evaluate; keep the policy if best; log; report
//!     if checkpoint_due: checkpoint; report
//! last/meta_policy.safetensors, the kept policy marked finished
//! ```

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::MetricsLog;
use crate::model::{META_POLICY_FILE, MetaPolicy, TrainingMark};

/// What a learner reports while it trains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// Updates done so far: SMILe's update pairs, Meta-BC's gradient steps.
    Steps(u64),
    /// An evaluation on the held-out train tasks.
    Eval {
        /// Updates done.
        step: u64,
        /// The family's metric now.
        metric: f32,
        /// The metric of the policy kept so far.
        best: f32,
        /// Meta-BC: the action MSE on the held-out tasks' demos.
        val_mse: Option<f32>,
    },
    /// A checkpoint was written at this step.
    Checkpoint(u64),
    /// The learner's stopping rule ended training at this step (Meta-BC's patience).
    Stopped(u64),
}

/// Metric names and values for one line of the metrics log.
pub(crate) type Fields = Vec<(&'static str, f64)>;

/// One held-out evaluation, as a learner judged it.
pub(crate) struct Evaluation {
    /// Whether the current policy is now the one to keep.
    pub keep: bool,
    /// What to log.
    pub fields: Fields,
    /// The event to report.
    pub progress: Progress,
    /// Whether the learner's stopping rule ended training with this evaluation.
    pub stopped: bool,
}

/// A learner inside [`fit`]: its steps and its rules. The loop's own state (clocks, the next
/// evaluation) lives in the implementing type, a learner borrowed for one fit.
pub(crate) trait Fit {
    /// Updates done.
    fn done(&self) -> u64;

    /// Before the loop: a warm start, the untrained policy's evaluation.
    fn begin(&mut self, log: &mut MetricsLog) -> Result<()>;

    /// Whether training is over: the budget, a compute budget or the stopping rule.
    fn finished(&self) -> bool;

    /// One unit of work; returns the metrics to log at [`Fit::done`] (none: no line).
    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields>;

    /// Whether a held-out evaluation is due now (the learner moves its schedule on).
    fn eval_due(&mut self) -> bool;

    /// The held-out evaluation; `None` when there is nothing to evaluate on.
    fn evaluate(&mut self) -> Result<Option<Evaluation>>;

    /// Whether a checkpoint is due now (the learner moves its schedule on).
    fn checkpoint_due(&mut self) -> bool;

    /// Writes the checkpoint to `dir`.
    fn save_checkpoint(&self, dir: &Path) -> Result<()>;

    /// The current policy.
    fn policy(&self) -> MetaPolicy;

    /// The training mark of a policy saved now.
    fn mark(&self, finished: bool) -> TrainingMark;

    /// Whether the final policy replaces a kept one at the end (SMILe without held-out
    /// tasks, whose evaluations keep nothing).
    fn final_replaces_kept(&self) -> bool {
        false
    }
}

/// Trains `run` in `dir` to its end: the metrics log `dir/metrics.jsonl`, the best held-out
/// policy in `dir/meta_policy.safetensors` (marked finished at the end), the last one in
/// `dir/last/`, checkpoints as the learner schedules them.
pub(crate) fn fit(run: &mut impl Fit, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
    let mut log = MetricsLog::open_at(dir, run.done())?;
    run.begin(&mut log)?;
    while !run.finished() {
        let fields = run.advance(on)?;
        if !fields.is_empty() {
            log.log(run.done(), &fields)?;
        }
        if run.eval_due()
            && let Some(ev) = run.evaluate()?
        {
            if ev.keep {
                run.policy().save_marked(dir, Some(run.mark(false)))?;
            }
            if ev.stopped {
                on(Progress::Stopped(run.done()));
            }
            log.log(run.done(), &ev.fields)?;
            on(ev.progress);
        }
        if run.checkpoint_due() {
            run.save_checkpoint(dir)?;
            on(Progress::Checkpoint(run.done()));
        }
    }
    let last = dir.join("last");
    std::fs::create_dir_all(&last).map_err(|e| Error::Io {
        path: last.clone(),
        source: e,
    })?;
    run.policy().save_marked(&last, Some(run.mark(true)))?;
    if run.final_replaces_kept() || !dir.join(META_POLICY_FILE).exists() {
        run.policy().save_marked(dir, Some(run.mark(true)))?;
    } else {
        // The kept (best) policy was written mid-run, marked unfinished: now it is final.
        MetaPolicy::mark_finished(dir)?;
    }
    Ok(())
}
