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

use serde::{Deserialize, Serialize};
use sim::{DemoDataset, Family, Physics};

use crate::algo::expert::ExpertSet;
use crate::algo::{Algo, Learner, MetaInputs, MetaSettings, Overrides, Progress, fit};
use crate::data::{MetaData, read_demos, read_demos_of};
use crate::error::{Error, Input, Result};
use crate::io::checkpoint;
use crate::setting::Setting;

mod expert;
mod registry;
pub use expert::{ExpertRequest, train_expert};

/// File in a run directory recording how the run was started, so that a resume continues it
/// with the same algorithm, expert and demos.
pub const RUN_FILE: &str = "run.json";

/// The expert name recorded for point-goal's scripted PD controller.
pub use crate::algo::expert::SCRIPTED_PD;

/// What a run directory records in [`RUN_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The algorithm's name ([`Algo::name`]).
    pub algo: String,
    /// Meta-DAgger's relabelling expert: a `smile expert` run, or [`SCRIPTED_PD`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expert: Option<String>,
    /// The expert's path as the OS gave it, when it is not UTF-8 (`expert` then holds a lossy
    /// copy for people to read): a resume must find the very same file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expert_os: Option<std::ffi::OsString>,
    /// SHA-256 of the demo file the run started on: a resume refuses other demos (their
    /// normalisation and tasks would silently replace the run's). Absent in older runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub demos_sha256: Option<String>,
    /// The plant the run simulates (the config's `physics`, which the demos must match).
    /// Absent in runs made before the MuJoCo backend: Rapier's.
    #[serde(default)]
    pub physics: Physics,
}

impl RunInfo {
    /// The record of the run in `dir` (its [`RUN_FILE`]).
    pub fn read(dir: &Path) -> Result<RunInfo> {
        let info = dir.join(RUN_FILE);
        let text = std::fs::read_to_string(&info).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => Error::Usage(format!(
                "{} holds no run to resume (no {RUN_FILE})",
                dir.display()
            )),
            _ => Error::Io {
                path: info.clone(),
                source: e,
            },
        })?;
        serde_json::from_str(&text).map_err(|e| Error::Checkpoint {
            path: info.clone(),
            reason: format!("not a run record: {e}"),
        })
    }

    /// The recorded algorithm.
    pub fn algo(&self, dir: &Path) -> Result<Algo> {
        self.algo
            .parse()
            .map_err(|e: Error| Error::Usage(format!("{}: {e}", dir.join(RUN_FILE).display())))
    }

    /// The recorded relabelling expert's path, exactly as it was given.
    pub fn expert_path(&self) -> Option<PathBuf> {
        self.expert_os
            .clone()
            .map(PathBuf::from)
            .or(self.expert.clone().map(PathBuf::from))
    }
}

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
    /// Settings over the file. Its plant (`physics`), when `None`: the file's, else the demos'.
    pub settings: Overrides,
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
    let algo = RunInfo::read(&req.out)?.algo(&req.out)?;
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
    let (family, ds) = match req.family {
        Some(family) => (family, read_demos_of(&req.demos, Input::Demos, family)?),
        None => {
            let ds = read_demos(&req.demos, Input::Demos)?;
            (ds.family, ds)
        }
    };
    let demos_sha = checkpoint::sha256_file(&req.demos)?;
    let algo = algo_of(req)?;
    let mut expert = req.expert.clone();
    // A run killed before its first checkpoint left nothing to continue: `--resume` starts it
    // over with its recorded configuration (a sweep's rerun does the same without the flag).
    let restart = req.resume && !req.out.join(checkpoint::CHECKPOINT_FILE).exists();
    if restart {
        refuse_finished_without_checkpoint(&req.out)?;
        let cfg = req.out.join("config.toml");
        if !cfg.exists() {
            return Err(Error::input(
                Input::Resume,
                format!(
                    "{} holds no checkpoint and no config.toml: its run was interrupted before \
                     it recorded its configuration, so there is nothing to resume; start it \
                     again instead (its partial files are replaced)",
                    req.out.display()
                ),
            ));
        }
        on(RunEvent::Note(format!(
            "{} has no checkpoint yet (its run was interrupted before the first one): starting \
             it over from update 0 with its recorded configuration ({})",
            req.out.display(),
            cfg.display()
        )));
    }
    if req.resume {
        let rec = RunInfo::read(&req.out)?;
        match &rec.demos_sha256 {
            Some(sha) if *sha != demos_sha => {
                return Err(Error::input(
                    Input::Demos,
                    format!(
                        "the demos {} are not the file {} was trained on (SHA-256 {} here, {} \
                         recorded in {RUN_FILE}); resume with the run's own demos, or start a \
                         new run on these",
                        req.demos.display(),
                        req.out.display(),
                        &demos_sha[..12],
                        &sha[..sha.len().min(12)]
                    ),
                ));
            }
            Some(_) => {}
            None => on(RunEvent::Note(format!(
                "warning: {} records no demo checksum (a run older than that check); make sure \
                 the demos are the file it started on",
                req.out.join(RUN_FILE).display()
            ))),
        }
        if expert.is_none() {
            expert = rec.expert_path();
        }
    } else {
        checkpoint::ensure_fresh_run_dir(&req.out)?;
    }
    let run = Run {
        req,
        restart,
        algo,
        family,
        ds: &ds,
        demos_sha,
        expert,
    };
    (registry::Meta::of(algo).train)(&run, on)
}

/// A `--resume` of a run whose checkpoint is gone after it finished: there is nothing to
/// continue from (the replay, the optimisers), and starting it over would replace a finished
/// policy; refused, naming the missing file.
fn refuse_finished_without_checkpoint(out: &Path) -> Result<()> {
    let policy = out.join(crate::model::META_POLICY_FILE);
    let finished = policy.exists()
        && crate::model::MetaPolicy::training_mark(&policy)
            .ok()
            .flatten()
            .is_some_and(|m| m.finished);
    if !finished {
        return Ok(());
    }
    Err(Error::input(
        Input::Resume,
        format!(
            "{} holds a finished run, but its checkpoint {} is gone: a larger budget continues \
             from the checkpoint (its replay and optimisers), so this run cannot be extended; \
             restore the checkpoint, or train a new run in another directory (the finished \
             policy {} is kept)",
            out.display(),
            out.join(checkpoint::CHECKPOINT_FILE).display(),
            policy.display()
        ),
    ))
}

/// A request with its inputs read.
struct Run<'a> {
    req: &'a TrainRequest,
    /// A `--resume` of a run that has no checkpoint: started over with its configuration.
    restart: bool,
    algo: Algo,
    family: Family,
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
            Some(req.out.join("config.toml"))
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
        if let (Some(env), Some(p)) = (registry::other_env(&table, self.family), &file) {
            return Err(Error::Config(format!(
                "{} sets env = {env} but the run is on {} (its demos, {}); remove the key or \
                 give {env} demos",
                p.display(),
                self.family,
                req.demos.display()
            )));
        }
        let mut settings = req.settings.clone();
        // A new run on MuJoCo demos runs on MuJoCo without being told twice.
        if settings.physics.is_none() && !table.contains_key("physics") {
            settings.physics = Some(self.ds.physics);
        }
        let mut cfg: C = crate::io::from_toml_over_defaults(&text)
            .map_err(|e| Error::Config(format!("{what}: {e}")))?;
        cfg.apply(self.algo, &settings)?;
        cfg.configure(self.algo, self.family);
        Ok(cfg)
    }

    /// Meta-DAgger's relabelling expert; none for the others, which refuse one.
    fn relabelling_expert(&self, on: &mut dyn FnMut(RunEvent)) -> Result<Option<ExpertSet>> {
        let algo = self.algo;
        if algo.needs_expert() {
            let (set, note) = ExpertSet::relabelling(self.expert.as_deref(), self.family)?;
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

    /// The name the run records for its expert.
    fn expert_record(&self) -> Option<PathBuf> {
        if !self.algo.needs_expert() {
            return None;
        }
        Some(
            self.expert
                .clone()
                .unwrap_or_else(|| PathBuf::from(SCRIPTED_PD)),
        )
    }

    /// Creates the run directory (only once the inputs were accepted, so a refused run leaves
    /// nothing behind) and records the run. The returned lock is held for the whole
    /// training: a second writer is refused.
    fn start_dir(
        &self,
        physics: Physics,
        on: &mut dyn FnMut(RunEvent),
    ) -> Result<crate::io::DirLock> {
        let out = &self.req.out;
        let lock = open_dir(out, self.resumes(), !self.restart, on)?;
        let expert = self.expert_record();
        let info = RunInfo {
            algo: self.algo.name().into(),
            expert: expert.as_ref().map(|p| p.to_string_lossy().into_owned()),
            expert_os: expert
                .as_ref()
                .filter(|p| p.to_str().is_none())
                .map(|p| p.as_os_str().to_owned()),
            demos_sha256: Some(self.demos_sha.clone()),
            physics,
        };
        let json = serde_json::to_string_pretty(&info).map_err(|e| Error::Serialise {
            what: "run.json",
            reason: e.to_string(),
        })?;
        checkpoint::write_atomic(&out.join(RUN_FILE), json.as_bytes())?;
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
            MetaData::from_dataset(self.ds, self.family, cfg.holdout_every()).map_err(|e| {
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
            check_resume(req, self.algo, &cfg, run.config())?;
            run
        } else {
            L::start(cfg, inputs)?
        };
        let lock = self.start_dir(self.ds.physics, on)?;
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
    write_config(dir, run.config())?;
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

/// Holds `out`'s lock for the run; a new run (not `resumes`) first clears what a run killed
/// before its first checkpoint left there, so this run's log does not continue the dead one's
/// (saying so when `tell`).
fn open_dir(
    out: &Path,
    resumes: bool,
    tell: bool,
    on: &mut dyn FnMut(RunEvent),
) -> Result<crate::io::DirLock> {
    let lock = crate::io::DirLock::acquire(out)?;
    if !resumes {
        // Checked again under the lock: the directory may have changed since the request was
        // read (another process finishing its first checkpoint there).
        let removed = checkpoint::clear_interrupted_run(out)?;
        if !removed.is_empty() && tell {
            on(RunEvent::Note(format!(
                "{} held a run interrupted before its first checkpoint (nothing to resume); \
                 starting over: removed {}",
                out.display(),
                removed.join(", ")
            )));
        }
    }
    Ok(lock)
}

/// Records the configuration a run trains with in `out/config.toml`, atomically.
fn write_config<T: Serialize>(out: &Path, cfg: &T) -> Result<()> {
    let text = toml::to_string(cfg).map_err(|e| Error::Serialise {
        what: "config.toml",
        reason: e.to_string(),
    })?;
    checkpoint::write_atomic(&out.join("config.toml"), text.as_bytes())
}

/// On a resume: the configuration asked for must agree with the one the run continues (its
/// checkpoint's, with the budget asked for), and so must its `config.toml` (a reader trusts
/// that file to describe the run).
fn check_resume<C: MetaSettings>(
    req: &TrainRequest,
    algo: Algo,
    given: &C,
    running: &C,
) -> Result<()> {
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
                given: changed_by(req, algo, running, key, &r).into(),
                was: theirs.to_string(),
                now: ours.map_or("missing".into(), ToString::to_string),
            });
        }
    }
    Ok(())
}

/// The caller's settings (beyond the budget) that alone change `key` of `running`, whose table
/// is `r`: what a resume's refusal blames (none: the run's `config.toml` changed it).
fn changed_by<C: MetaSettings>(
    req: &TrainRequest,
    algo: Algo,
    running: &C,
    key: &str,
    r: &toml::Table,
) -> Vec<Setting> {
    let changes = |s: &Setting| {
        let mut c = running.clone();
        c.apply(algo, &req.settings.only(*s)).is_ok()
            && toml::Table::try_from(&c).is_ok_and(|t| t.get(key) != r.get(key))
    };
    req.settings
        .given_beyond_budget()
        .into_iter()
        .filter(changes)
        .collect()
}
