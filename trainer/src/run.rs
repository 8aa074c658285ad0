//! A meta-learner's run directory, started or resumed: what `smile train` and a sweep's cells
//! both call.
//!
//! [`train`] reads the demos, builds the configuration (a TOML file over the algorithm's
//! defaults, the caller's keys over both), loads Meta-DAgger's relabelling expert, starts the
//! learner or resumes it from the directory's checkpoint, records how the run was started
//! ([`RUN_FILE`], `config.toml`), holds the directory's lock, and trains the [`Learner`]
//! through the one fit loop, reporting [`RunEvent`]s. A resumed run keeps the configuration it
//! started with: only its budget ([`MetaSettings::budget`]) may change, and other demos than
//! the run's are refused. [`train_expert`] is the same driver for a SAC expert: both end in
//! one tail (`drive`: the recorded configuration, the start event, the loop, a failure named
//! with its step and last checkpoint).

use std::path::{Path, PathBuf};

use sim::{DemoDataset, Family};

use crate::algo::expert::ExpertSet;
use crate::algo::{Algo, Learner, MetaInputs, MetaSettings, Progress, Setting, fit};
use crate::data::{MetaData, read_demos, read_demos_of};
use crate::error::{Error, Input, Result};
use crate::io::{checkpoint, run_dir};

mod expert;
mod registry;
pub use expert::{ExpertRequest, train_expert};

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
        /// What the budget counts ("update pairs", "steps").
        unit: &'static str,
        /// One unit in messages ("update", "step").
        word: &'static str,
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
    let learner = registry::Meta::of(algo);
    if restart {
        let cfg = run_dir::restart_config(&req.out)?;
        on(restarting(&req.out, &cfg, learner.unit.word));
    }
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
    (learner.train)(&run, on)
}

/// The note of a `--resume` that starts the run in `dir`, killed before its first checkpoint,
/// over from its recorded configuration `cfg` (`word`: one unit of its budget).
fn restarting(dir: &Path, cfg: &Path, word: &str) -> RunEvent {
    RunEvent::Note(format!(
        "{} has no checkpoint yet (its run was interrupted before the first one): starting it \
         over from {word} 0 with its recorded configuration ({})",
        dir.display(),
        cfg.display()
    ))
}

/// A request with its inputs read.
struct Run<'a> {
    req: &'a TrainRequest,
    /// A `--resume` of a run that has no checkpoint: started over with its configuration.
    restart: bool,
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
            Some(p) => std::fs::read_to_string(p).map_err(|e| Error::Io {
                path: p.clone(),
                source: e,
            })?,
            None => String::new(),
        };
        let what = match (&file, req.resume) {
            (Some(p), true) => format!(
                "parsing {} (its {RUN_FILE} names the algorithm whose config this must be)",
                p.display()
            ),
            (Some(p), false) => format!("parsing {}", p.display()),
            (None, _) => "reading the defaults".into(),
        };
        let table = text.parse::<toml::Table>().unwrap_or_default();
        // The family comes from the demos; a file naming another would be silently ignored.
        if let (Some(env), Some(p)) = (registry::other_env(&table, self.ds.family), &file) {
            return Err(Error::Config(format!(
                "{} sets env = {env} but the run is on {} (its demos, {}); remove the key or \
                 give {env} demos",
                p.display(),
                self.ds.family,
                req.demos.display()
            )));
        }
        let mut settings = req.settings.clone();
        // A new run on MuJoCo demos runs on MuJoCo without being told twice.
        let physics_given = settings.iter().any(|s| matches!(s, Setting::Physics(_)));
        if !physics_given && !table.contains_key("physics") {
            settings.push(Setting::Physics(self.ds.physics));
        }
        let mut cfg: C = crate::io::from_toml_over_defaults(&text)
            .map_err(|e| Error::Config(format!("{what}: {e}")))?;
        cfg.apply(self.algo, &settings)?;
        cfg.configure(self.algo, self.ds.family);
        Ok(cfg)
    }

    /// Meta-DAgger's relabelling expert; none for the others, which refuse one.
    fn relabelling_expert(&self, on: &mut dyn FnMut(RunEvent)) -> Result<Option<ExpertSet>> {
        let algo = self.algo;
        if algo.needs_expert() {
            let (set, note) = ExpertSet::relabelling(self.expert.as_deref(), self.ds.family)?;
            on(RunEvent::Note(format!("{algo}: {note}")));
            return Ok(Some(set));
        }
        match &self.expert {
            Some(p) => Err(Error::input(
                Input::Expert,
                format!(
                    "the expert {} would relabel Meta-DAgger's rollouts; {algo} learns from the \
                     demos alone (drop the expert, or train meta-dagger)",
                    p.display()
                ),
            )),
            None => Ok(None),
        }
    }

    /// Creates the run directory (only once the inputs were accepted, so a refused run leaves
    /// nothing behind) and records the run. The returned lock is held for the whole
    /// training: a second writer is refused.
    fn start_dir(&self, on: &mut dyn FnMut(RunEvent)) -> Result<crate::io::DirLock> {
        let out = &self.req.out;
        let lock = open_dir(out, self.resumes(), !self.restart, on)?;
        // The expert it records: the one given, else the default (point-goal's scripted PD).
        let expert = self
            .algo
            .needs_expert()
            .then(|| self.expert.clone().unwrap_or_else(|| SCRIPTED_PD.into()));
        let algo = self.algo.name();
        let physics = self.ds.physics;
        RunInfo::new(algo, expert.as_deref(), self.demos_sha.clone(), physics).write(out)?;
        Ok(lock)
    }

    /// Whether the run continues from its checkpoint.
    fn resumes(&self) -> bool {
        self.req.resume && !self.restart
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
        let run = if self.resumes() {
            let run = L::resume(&req.out, inputs, &cfg)?;
            check_resume(req, &cfg, run.config())?;
            run
        } else {
            L::start(cfg, inputs)?
        };
        let lock = self.start_dir(on)?;
        drive(run, &req.out, what, self.resumes(), lock, on).map(drop)
    }
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
        unit: unit.plural,
        word: unit.word,
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

/// Holds `out`'s lock for the run ([`run_dir::lock_for_run`]), saying what a new run cleared
/// there (when `tell`).
fn open_dir(
    out: &Path,
    resumes: bool,
    tell: bool,
    on: &mut dyn FnMut(RunEvent),
) -> Result<crate::io::DirLock> {
    let (lock, removed) = run_dir::lock_for_run(out, resumes)?;
    if !removed.is_empty() && tell {
        on(RunEvent::Note(format!(
            "{} held a run interrupted before its first checkpoint (nothing to resume); \
             starting over: removed {}",
            out.display(),
            removed.join(", ")
        )));
    }
    Ok(lock)
}

/// On a resume: the configuration asked for must agree with the one the run continues (its
/// checkpoint's, with the budget asked for), and so must its `config.toml` (a reader trusts
/// that file to describe the run).
fn check_resume<C: MetaSettings>(req: &TrainRequest, given: &C, running: &C) -> Result<()> {
    let table = |c: &C| -> Result<toml::Table> {
        toml::Table::try_from(c).map_err(|e| Error::Serialise {
            what: "the configuration",
            reason: e.to_string(),
        })
    };
    let (g, r) = (table(given)?, table(running)?);
    for (key, theirs) in &r {
        let ours = g.get(key);
        if ours != Some(theirs) {
            return Err(Error::ResumeChanges {
                run: req.out.clone(),
                key: key.clone(),
                given: changed_by(req, running, key, &r).into(),
                was: theirs.to_string(),
                now: ours.map_or("missing".into(), ToString::to_string),
            });
        }
    }
    Ok(())
}

/// The positions of the caller's settings (beyond the budget) that alone change `key` of
/// `running`, whose table is `r`: what a resume's refusal blames (none: the run's `config.toml`
/// changed it).
fn changed_by<C: MetaSettings>(
    req: &TrainRequest,
    running: &C,
    key: &str,
    r: &toml::Table,
) -> Vec<usize> {
    let changes = |s: &Setting| {
        let mut c = running.clone();
        c.set(s.clone()) && toml::Table::try_from(&c).is_ok_and(|t| t.get(key) != r.get(key))
    };
    let given = req.settings.iter().enumerate();
    given
        .filter(|(_, s)| !s.is_budget() && changes(s))
        .map(|(at, _)| at)
        .collect()
}
