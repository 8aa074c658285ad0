//! An expert's run directory, started or resumed: what `smile expert` calls.
//!
//! The same steps as a meta-learner's run ([`train`](super::train)): a new run refuses a
//! directory that holds one, a resume continues the checkpoint with its saved configuration
//! (only the step budget may change) or, for a run killed before its first checkpoint, starts
//! it over with its recorded `config.toml`, the directory's lock is held for the whole
//! training, the configuration is recorded in `config.toml`, and the SAC expert trains
//! through the one fit loop, reporting [`RunEvent`]s: the driver's tail is the meta-learners'
//! (`drive`).

use std::path::{Path, PathBuf};

use super::{RUN_FILE, RunEvent, RunInfo, drive, open_dir, restarting};
use crate::algo::expert::{ExpertConfig, ExpertTrainer};
use crate::algo::{Learner, Progress};
use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::io::run_dir;

/// An expert run to start or resume.
#[derive(Debug, Clone, Default)]
pub struct ExpertRequest {
    /// The run directory.
    pub out: PathBuf,
    /// A new run's configuration; `None` resumes the run in `out` from its checkpoint (one
    /// killed before its first checkpoint starts over with its recorded configuration).
    pub config: Option<ExpertConfig>,
    /// On a resume: the step budget (`None`: the run's), raised to train longer.
    pub total_steps: Option<u64>,
}

/// Starts or resumes the expert run `req` describes, trains it to its step budget, and
/// returns the configuration it trained with (the policy is in `out/policy.safetensors`).
/// A failure during training says at which step, and where the last good checkpoint is.
pub fn train_expert(req: &ExpertRequest, on: &mut dyn FnMut(RunEvent)) -> Result<ExpertConfig> {
    let dir = &req.out;
    if req.config.is_none() && dir.join(RUN_FILE).exists() {
        // A meta-learner's run records how it started; an expert's does not.
        let algo = RunInfo::read(dir).map_or_else(|_| "meta-learner".into(), |r| r.algo);
        return Err(Error::Usage(format!(
            "{} holds a {algo} run ({RUN_FILE}), not an expert's: resume it as the {algo} run \
             it is",
            dir.display()
        )));
    }
    // A resume of a run killed before its first checkpoint starts it over with its recorded
    // configuration, as a meta-learner's does (`run::train`).
    let restart =
        req.config.is_none() && dir.is_dir() && !dir.join(checkpoint::CHECKPOINT_FILE).exists();
    let run = match &req.config {
        Some(cfg) => start(dir, cfg, on)?,
        None if restart => {
            let (cfg, path) = recorded_config(dir, req.total_steps)?;
            let run = start(dir, &cfg, on)?;
            on(restarting(dir, &path, ExpertTrainer::UNIT.word));
            run
        }
        None => ExpertTrainer::resume(dir, req.total_steps)?,
    };
    let resumes = req.config.is_none() && !restart;
    let lock = open_dir(dir, resumes, !restart, on)?;
    let cfg = run.config();
    let what = format!("a SAC expert on {} ({})", cfg.env, cfg.physics);
    // An expert is evaluated on its own task (or the meta-test tasks), not held-out ones.
    let mut on = |e: RunEvent| match e {
        RunEvent::Progress(
            Progress::Eval {
                step, metric, best, ..
            },
            _,
        ) => on(RunEvent::Note(format!(
            "step {step}: deterministic evaluation {metric:.4} (best {best:.4})"
        ))),
        e => on(e),
    };
    let run = drive(run, dir, what, resumes, lock, &mut on)?;
    if let Some(b) = run.best_eval() {
        on(RunEvent::Note(format!(
            "best periodic evaluation: {:.4} at env step {} (policy-best.safetensors); \
             policy.safetensors holds whichever of it and the final weights evaluated better",
            b.metric, b.env_steps
        )));
    }
    Ok(run.config().clone())
}

/// A new run in `dir`, which must not hold one.
fn start(dir: &Path, cfg: &ExpertConfig, on: &mut dyn FnMut(RunEvent)) -> Result<ExpertTrainer> {
    checkpoint::ensure_fresh_run_dir(dir)?;
    if let (Some(v), [task]) = (cfg.task_value, cfg.tasks()?.as_slice()) {
        // sim's tolerant lookup: 0.4909 names test goal 0.490874 exactly.
        on(RunEvent::Note(format!(
            "task value {v}: a per-task expert on {} (value {})",
            task.label(),
            task.value()
        )));
    }
    ExpertTrainer::new(cfg.clone())
}

/// The configuration a resume of the run in `dir`, killed before its first checkpoint, starts
/// over with, and its file: the recorded `config.toml` ([`run_dir::restart_config`], which
/// refuses a finished run whose checkpoint is gone, and a run that recorded no configuration),
/// its step budget replaced by `total_steps` if given.
fn recorded_config(dir: &Path, total_steps: Option<u64>) -> Result<(ExpertConfig, PathBuf)> {
    let path = run_dir::restart_config(dir)?;
    let text = std::fs::read_to_string(&path).map_err(|e| Error::Io {
        path: path.clone(),
        source: e,
    })?;
    let mut cfg: ExpertConfig = crate::io::from_toml_over_defaults(&text)
        .map_err(|e| Error::Config(format!("parsing {}: {e}", path.display())))?;
    cfg.total_steps = total_steps.unwrap_or(cfg.total_steps);
    Ok((cfg, path))
}
