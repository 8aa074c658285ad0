//! The one fit loop every learner trains through, as burn's `Learner::fit` or SB3's `learn`:
//! the metrics log, evaluations, checkpoints, the kept policy, progress, the compute budget
//! (CPU-seconds across the run's processes) and the end of the run are here once; the outline
//! is [`Learner`]'s doc.

use std::path::Path;

use crate::algo::learner::Learner;
use crate::error::{Error, Result};
use crate::io::MetricsLog;

/// What a learner reports while it trains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// Units of work done so far: SMILe's update pairs, Meta-BC's gradient steps, an
    /// expert's env steps.
    Steps(u64),
    /// An expert's episode ended.
    Episode {
        /// Env steps done.
        step: u64,
        /// The episode's undiscounted return.
        episodic_return: f32,
        /// The family's metric for the episode.
        metric: f32,
    },
    /// An evaluation, after this many units of work.
    Eval {
        /// Units of work done.
        step: u64,
        /// What it found.
        score: Score,
    },
    /// A checkpoint was written at this step.
    Checkpoint(u64),
    /// The learner's stopping rule ended training at this step (Meta-BC's patience), before
    /// its budget; reported after the evaluation that decided it.
    Stopped(u64),
}

/// Metric names and values for one line of the metrics log.
pub type Fields = Vec<(&'static str, f64)>;

/// One evaluation, as a learner judged it.
pub struct Evaluation {
    /// Whether the current policy is now the one to keep.
    pub keep: bool,
    /// What to log.
    pub fields: Fields,
    /// What to report.
    pub score: Score,
}

/// What an evaluation found, for a person.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// What the metric measures ("held-out train-task metric", "deterministic evaluation").
    pub what: &'static str,
    /// The family's metric now.
    pub metric: f32,
    /// The metric of the policy kept so far.
    pub best: f32,
    /// Meta-BC: the action MSE on the held-out tasks' demos.
    pub val_mse: Option<f32>,
}

/// When a learner wants its evaluations and checkpoints, in its own units of work.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cadence {
    /// The budget: units of work to do.
    pub total: u64,
    /// An evaluation once the work done reaches each multiple of this; 0: never.
    pub eval_every: u64,
    /// Also evaluate when training ends (when `eval_every` > 0).
    pub eval_at_end: bool,
    /// A checkpoint at each multiple of this (at least 1), and always when training ends.
    pub checkpoint_every: u64,
    /// A compute budget in CPU-seconds of every process of the run (0: none): training ends
    /// at the first unit of work that reaches it.
    pub cpu_budget_s: f64,
}

/// The run's CPU-seconds as a clock: `before` (its earlier processes', from its checkpoint)
/// plus this process's since the fit began, warm start and first evaluation included. A
/// `budget` on a platform that reports no CPU time is refused.
fn cpu_clock(before: f64, budget: f64) -> Result<impl Fn() -> f64> {
    let start = crate::threads::process_cpu_seconds();
    if budget > 0.0 && start.is_none() {
        return Err(Error::Config(
            "cpu_budget_s is set, but this platform does not report the process's CPU time".into(),
        ));
    }
    Ok(move || {
        let now = crate::threads::process_cpu_seconds();
        before + now.zip(start).map_or(0.0, |(now, start)| now - start)
    })
}

/// The next multiple of `every` after `done`: where an event falls due again. `every` 0 is
/// never.
fn next_multiple(done: u64, every: u64) -> u64 {
    done.checked_div(every)
        .map_or(u64::MAX, |k| (k + 1).saturating_mul(every))
}

/// One recurring event of the loop: due at each multiple of `every` that the work reaches
/// (a unit of work may pass several; the event happens once) and, if asked, at the end.
struct Schedule {
    every: u64,
    next: u64,
    at_end: bool,
}

impl Schedule {
    fn new(every: u64, done: u64, at_end: bool) -> Self {
        let at_end = at_end && every > 0;
        Self {
            every,
            next: next_multiple(done, every),
            at_end,
        }
    }

    /// Whether the event is due after `done` units (`finished`: training has ended); moves
    /// the schedule on when it is.
    fn due(&mut self, done: u64, finished: bool) -> bool {
        let due = done >= self.next || (finished && self.at_end);
        if due {
            self.next = next_multiple(done, self.every);
        }
        due
    }
}

/// Trains `run` in `dir` to its end: the metrics log `dir/metrics.jsonl`, evaluations and
/// checkpoints at the learner's [`Cadence`], the kept policy at each evaluation that judges it
/// best, then the learner's final files ([`Learner::finish`]). A resumed learner continues its
/// log, schedules and compute count where its checkpoint left them.
pub fn fit<L: Learner>(run: &mut L, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
    let cadence = run.cadence();
    let before = run.cpu_seconds_mut().map_or(0.0, |s| *s);
    let cpu_seconds = cpu_clock(before, cadence.cpu_budget_s)?;
    let mut log = MetricsLog::open_at(dir, run.done())?;
    run.begin(&mut log)?;
    // The units per second since this process started training (`charts/sps`).
    let (t0, done0) = (std::time::Instant::now(), run.done());
    let mut evals = Schedule::new(cadence.eval_every, run.done(), cadence.eval_at_end);
    let mut checkpoints = Schedule::new(cadence.checkpoint_every.max(1), run.done(), true);
    let mut finished = run.finished();
    while !finished {
        let mut fields = run.advance(on)?;
        let cpu_s = cpu_seconds();
        if let Some(count) = run.cpu_seconds_mut() {
            *count = cpu_s;
            fields.push(("charts/cpu_s", cpu_s));
        }
        let ended = run.finished();
        finished = ended || (cadence.cpu_budget_s > 0.0 && cpu_s >= cadence.cpu_budget_s);
        if !fields.is_empty() {
            let secs = t0.elapsed().as_secs_f64().max(1e-9);
            fields.push(("charts/sps", run.done().saturating_sub(done0) as f64 / secs));
            log.log(run.done(), &fields)?;
        }
        if evals.due(run.done(), finished)
            && let Some(ev) = run.evaluate()?
        {
            if ev.keep {
                run.save_kept(dir)?;
            }
            log.log(run.done(), &ev.fields)?;
            on(Progress::Eval {
                step: run.done(),
                score: ev.score,
            });
            // The learner's stopping rule (Meta-BC's patience) ended training with this
            // evaluation: no further unit of work.
            if !ended && run.finished() {
                finished = true;
                on(Progress::Stopped(run.done()));
            }
        }
        if checkpoints.due(run.done(), finished) {
            run.save_checkpoint(dir)?;
            on(Progress::Checkpoint(run.done()));
        }
    }
    run.finish(dir, &mut log)
}
