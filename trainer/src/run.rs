//! The one run driver: a run directory started or resumed, what `smile train`, `smile expert`,
//! a sweep's cells and the quickstart call.
//!
//! [`train`] reads the demos, builds the configuration (a TOML file over the algorithm's
//! defaults, the caller's keys over both), loads Meta-DAgger's relabelling expert, starts the
//! learner or resumes it from the directory's checkpoint, records how the run was started
//! ([`RUN_FILE`], `config.toml`), holds the directory's lock, and trains the [`Learner`]
//! through the one fit loop, reporting [`RunEvent`]s. A resumed run keeps the configuration it
//! started with: only its budget ([`MetaSettings::budget`]) may change, and other demos than
//! the run's are refused. [`train_expert`] is the same driver for a SAC expert (no demos, no
//! run record: its configuration is given or recorded). Both end in one tail (`drive`: the
//! recorded configuration, the start event, the loop, a failure named with its step and last
//! checkpoint).

use std::path::{Path, PathBuf};

use sim::{DemoDataset, Family};

use crate::algo::expert::{ExpertConfig, ExpertSet, ExpertTrainer};
use crate::algo::{Algo, Learner, MetaInputs, MetaSettings, Progress, Setting, Unit, fit};
use crate::data::{MetaData, read_demos, read_demos_of};
use crate::error::{Error, Input, Result};
use crate::io::{checkpoint, run_dir};

mod registry;

// The run directory's record, read and written in `io` (the run's files).
pub use crate::io::run_dir::{RUN_FILE, RunInfo};

/// The expert name recorded for point-goal's scripted PD controller.
pub use crate::algo::expert::SCRIPTED_PD;

/// A run to start or resume.
#[derive(Debug, Clone, Default)]
pub struct TrainRequest {
    /// Meta-train demos (`smile demos --split train`); a meta-test file is refused.
    pub demos: PathBuf,
    /// The run directory.
    pub out: PathBuf,
    /// The family; `None`: the demo file's (given, the file must hold it).
    pub family: Option<Family>,
    /// The algorithm; `None`: SMILe for a new run, the recorded one for a resume (given, it
    /// must be the recorded one).
    pub algo: Option<Algo>,
    /// A configuration file (TOML over the algorithm's defaults); a resume reads the run's
    /// `config.toml` instead.
    pub config_file: Option<PathBuf>,
    /// Settings over the file, in order. Its plant, when no [`Setting::Physics`] is given: the
    /// file's, else the demos'.
    pub settings: Vec<Setting>,
    /// Meta-DAgger's relabelling expert: a `smile expert` run directory or policy file, a
    /// folder of per-task experts, or [`SCRIPTED_PD`] (point-goal's default). `None` on a
    /// resume: the recorded one.
    pub expert: Option<PathBuf>,
    /// Continue the run in `out` from its checkpoint.
    pub resume: bool,
}

/// What [`train`] reports.
#[derive(Debug, Clone, PartialEq)]
pub enum RunEvent {
    /// A line for the person watching (the expert used, a warning about an old run).
    Note(String),
    /// Training starts (or continues).
    Started {
        /// What trains, on what, for a person ("smile: 36 training tasks, 4 held-out train
        /// tasks").
        what: String,
        /// The budget, in `unit`s.
        total: u64,
        /// Updates already done (a resume), else 0.
        done: u64,
        /// What the budget counts ("update pairs", one "update").
        unit: Unit,
        /// Whether the run resumed from a checkpoint.
        resumed: bool,
    },
    /// The learner's progress, and one unit's word in messages ("update", "step").
    Progress(Progress, &'static str),
}

/// The algorithm a request runs: the recorded one for a resume (a different `req.algo` is
/// refused), else `req.algo` or SMILe.
pub fn algo_of(req: &TrainRequest) -> Result<Algo> {
    if !req.resume {
        return Ok(req.algo.unwrap_or(Algo::Smile));
    }
    let record = RunInfo::read(&req.out)?.algo;
    let algo: Algo = record
        .parse()
        .map_err(|e: Error| Error::Usage(format!("{}: {e}", req.out.join(RUN_FILE).display())))?;
    if let Some(given) = req.algo.filter(|g| *g != algo) {
        return Err(Error::input(
            Input::Algo,
            format!(
                "{} is a {} run, not {}: resume it without naming the algorithm",
                req.out.display(),
                algo.name(),
                given.name()
            ),
        ));
    }
    Ok(algo)
}

/// Starts or resumes the run `req` describes and trains it to its budget or stopping rule.
pub fn train(req: &TrainRequest, on: &mut dyn FnMut(RunEvent)) -> Result<()> {
    // A demo file of another family than the one asked for is refused here.
    let ds = match req.family {
        Some(family) => read_demos_of(&req.demos, Input::Demos, family)?,
        None => read_demos(&req.demos, Input::Demos)?,
    };
    let demos_sha = checkpoint::sha256_file(&req.demos)?;
    let algo = algo_of(req)?;
    // A run killed before its first checkpoint left nothing to continue: `--resume` starts it
    // over with its recorded configuration (a sweep's rerun does the same without the flag).
    let restart = req.resume && !req.out.join(checkpoint::CHECKPOINT_FILE).exists();
    let restart = restart
        .then(|| run_dir::restart_config(&req.out))
        .transpose()?;
    let expert = if req.resume {
        let rec = RunInfo::read(&req.out)?;
        if let Some(warning) = rec.check_demos(&req.out, &req.demos, &demos_sha)? {
            on(RunEvent::Note(warning));
        }
        req.expert.clone().or(rec.expert_path())
    } else {
        checkpoint::ensure_fresh_run_dir(&req.out)?;
        req.expert.clone()
    };
    let run = Run {
        req,
        restart,
        algo,
        ds: &ds,
        demos_sha,
        expert,
    };
    (registry::Meta::of(algo).train)(&run, on)
}

/// A request with its inputs read.
struct Run<'a> {
    req: &'a TrainRequest,
    /// A `--resume` of a run with no checkpoint: started over from this recorded configuration.
    restart: Option<PathBuf>,
    algo: Algo,
    ds: &'a DemoDataset,
    demos_sha: String,
    expert: Option<PathBuf>,
}

impl Run<'_> {
    /// The configuration: the caller's keys over the run's saved `config.toml` when resuming
    /// (else over the configuration file), over the algorithm's defaults; the plant from
    /// `physics`, else the file's, else the demos'.
    fn config<C: MetaSettings>(&self) -> Result<C> {
        let req = self.req;
        let file = if req.resume {
            Some(req.out.join(run_dir::CONFIG_FILE))
        } else {
            req.config_file.clone()
        };
        let text = match &file {
            Some(p) => std::fs::read_to_string(p).map_err(Error::io(p))?,
            None => String::new(),
        };
        let name = match (&file, req.resume) {
            (Some(p), true) => format!(
                "{} (its {RUN_FILE} names the algorithm whose config this must be)",
                p.display()
            ),
            (Some(p), false) => p.display().to_string(),
            (None, _) => "the defaults".into(),
        };
        let family = self.ds.family;
        let demos = format!("{family} (its demos, {})", req.demos.display());
        let mut cfg: C = registry::parse(&text, Some(&name), &demos, family)?;
        // A new run on MuJoCo demos runs on MuJoCo without being told twice (a file's plant,
        // and then the caller's, still win).
        let table = text.parse::<toml::Table>();
        if !table.is_ok_and(|t| t.contains_key("physics")) {
            cfg.set(Setting::Physics(self.ds.physics));
        }
        cfg.apply(self.algo, &req.settings)?;
        cfg.configure(self.algo, family);
        Ok(cfg)
    }

    /// Meta-DAgger's relabelling expert; the others refuse one.
    fn relabelling_expert(&self, on: &mut dyn FnMut(RunEvent)) -> Result<Option<ExpertSet>> {
        match (self.algo.needs_expert(), &self.expert) {
            (true, given) => {
                let (set, note) = ExpertSet::relabelling(given.as_deref(), self.ds.family)?;
                on(RunEvent::Note(format!("{}: {note}", self.algo)));
                Ok(Some(set))
            }
            (false, Some(p)) => Err(Error::takes_no_expert(self.algo.name(), Some(p))),
            (false, None) => Ok(None),
        }
    }

    fn train<L>(&self, on: &mut dyn FnMut(RunEvent)) -> Result<()>
    where
        L: Learner<Inputs = MetaInputs>,
        L::Config: MetaSettings,
    {
        let req = self.req;
        let cfg: L::Config = self.config()?;
        let expert = self.relabelling_expert(on)?;
        let data =
            MetaData::from_dataset(self.ds, self.ds.family, cfg.holdout_every()).map_err(|e| {
                Error::input(
                    Input::Demos,
                    format!("the demos {}: {e}", req.demos.display()),
                )
            })?;
        let what = format!(
            "{}: {} training tasks, {} held-out train tasks",
            self.algo,
            data.train.len(),
            data.val.len()
        );
        let inputs = MetaInputs { data, expert };
        let resumes = req.resume && self.restart.is_none();
        let run = if resumes {
            let run = L::resume(&req.out, inputs, &cfg)?;
            check_resume(req, &cfg, run.config())?;
            run
        } else {
            L::start(cfg, inputs)?
        };
        // The directory is written only once the inputs were accepted: a refused run leaves
        // nothing behind. The expert recorded: the one given, else the default (point-goal's
        // scripted PD).
        let lock = open_dir(&req.out, resumes, self.restart.as_deref(), L::UNIT, on)?;
        let expert = (self.algo.needs_expert())
            .then(|| self.expert.clone().unwrap_or_else(|| SCRIPTED_PD.into()));
        let (sha, physics) = (self.demos_sha.clone(), self.ds.physics);
        RunInfo::new(self.algo.name(), expert.as_deref(), sha, physics).write(&req.out)?;
        drive(run, &req.out, what, resumes, lock, on).map(drop)
    }
}

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
    let mut recorded = None;
    let run = match &req.config {
        Some(cfg) => start(dir, cfg)?,
        None if restart => {
            let (cfg, path) = recorded_config(dir, req.total_steps)?;
            recorded = Some(path);
            start(dir, &cfg)?
        }
        None => ExpertTrainer::resume(dir, req.total_steps)?,
    };
    let resumes = req.config.is_none() && !restart;
    let lock = open_dir(dir, resumes, recorded.as_deref(), ExpertTrainer::UNIT, on)?;
    let cfg = run.config();
    let what = format!("a SAC expert on {} ({})", cfg.env, cfg.physics);
    let run = drive(run, dir, what, resumes, lock, on)?;
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
fn start(dir: &Path, cfg: &ExpertConfig) -> Result<ExpertTrainer> {
    checkpoint::ensure_fresh_run_dir(dir)?;
    ExpertTrainer::new(cfg.clone())
}

/// The configuration a resume of the run in `dir`, killed before its first checkpoint, starts
/// over with, and its file: the recorded `config.toml` ([`run_dir::restart_config`], which
/// refuses a finished run whose checkpoint is gone, and a run that recorded no configuration),
/// its step budget replaced by `total_steps` if given.
fn recorded_config(dir: &Path, total_steps: Option<u64>) -> Result<(ExpertConfig, PathBuf)> {
    let path = run_dir::restart_config(dir)?;
    let text = std::fs::read_to_string(&path).map_err(Error::io(&path))?;
    let mut cfg: ExpertConfig = crate::io::from_toml_over_defaults(&text)
        .map_err(|e| Error::Config(format!("parsing {}: {e}", path.display())))?;
    cfg.total_steps = total_steps.unwrap_or(cfg.total_steps);
    Ok((cfg, path))
}

/// The tail every run driver ends in, under the run directory's `lock`: records the
/// configuration in `dir/config.toml`, reports the start, trains `run` through the one fit loop
/// and returns it; a failure during training says at which step, and where the last good
/// checkpoint is ([`Error::Stopped`]).
fn drive<L: Learner>(
    mut run: L,
    dir: &Path,
    what: String,
    resumed: bool,
    lock: crate::io::DirLock,
    on: &mut dyn FnMut(RunEvent),
) -> Result<L> {
    run_dir::write_config(dir, run.config())?;
    let unit = L::UNIT;
    on(RunEvent::Started {
        what,
        total: run.cadence().total,
        done: run.done(),
        unit,
        resumed,
    });
    let trained = fit(&mut run, dir, &mut |p| on(RunEvent::Progress(p, unit.word)));
    drop(lock);
    if let Err(e) = trained {
        let ck = dir.join(checkpoint::CHECKPOINT_FILE);
        return Err(Error::Stopped {
            step: run.done(),
            unit: unit.word,
            checkpoint: ck.exists().then_some(ck),
            source: Box::new(e),
        });
    }
    Ok(run)
}

/// Holds `out`'s lock for the whole training ([`run_dir::lock_for_run`]: a second writer is
/// refused), saying when a run interrupted before its first checkpoint starts over: on a
/// `--resume`, from its recorded configuration `restart`, else what a new run cleared there.
fn open_dir(
    out: &Path,
    resumes: bool,
    restart: Option<&Path>,
    unit: Unit,
    on: &mut dyn FnMut(RunEvent),
) -> Result<crate::io::DirLock> {
    let (lock, removed) = run_dir::lock_for_run(out, resumes)?;
    let (out, word) = (out.display(), unit.word);
    let note = match restart {
        Some(cfg) => format!(
            "{out} has no checkpoint yet (its run was interrupted before the first one): \
             starting it over from {word} 0 with its recorded configuration ({})",
            cfg.display()
        ),
        None if removed.is_empty() => return Ok(lock),
        None => format!(
            "{out} held a run interrupted before its first checkpoint (nothing to resume); \
             starting over: removed {}",
            removed.join(", ")
        ),
    };
    on(RunEvent::Note(note));
    Ok(lock)
}

/// On a resume: the configuration asked for must agree with the one the run continues (its
/// checkpoint's, with the budget asked for), and so must its `config.toml` (a reader trusts
/// that file to describe the run). The refusal blames the caller's settings (beyond the
/// budget) that alone change the first key that differs; none: the `config.toml` changed it.
fn check_resume<C: MetaSettings>(req: &TrainRequest, given: &C, running: &C) -> Result<()> {
    let table = |c: &C| -> Result<toml::Table> {
        toml::Table::try_from(c).map_err(|e| Error::Serialise {
            what: "the configuration",
            reason: e.to_string(),
        })
    };
    let (g, r) = (table(given)?, table(running)?);
    let Some((key, was)) = r.iter().find(|(k, v)| g.get(*k) != Some(*v)) else {
        return Ok(());
    };
    let changes = |s: &Setting| {
        let mut c = running.clone();
        c.set(s.clone()) && table(&c).is_ok_and(|t| t.get(key) != Some(was))
    };
    let blamed = req.settings.iter().enumerate();
    let blamed = blamed.filter(|(_, s)| !s.is_budget() && changes(s));
    Err(Error::ResumeChanges {
        run: req.out.clone(),
        key: key.clone(),
        given: blamed.map(|(at, _)| at).collect::<Vec<_>>().into(),
        was: was.to_string(),
        now: g.get(key).map_or("missing".into(), ToString::to_string),
    })
}
