//! A run directory's records and the checks that start or resume one: [`RUN_FILE`] (how the
//! run was started), [`CONFIG_FILE`] (what it trains with), its lock, and the restart of a run
//! killed before its first checkpoint. Whether a directory may take a new run, and the clearing
//! of what a killed run left, are the checkpoint's (`checkpoint::ensure_fresh_run_dir`,
//! `checkpoint::clear_interrupted_run`). The run driver (`run.rs`) decides; this module reads
//! and writes.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim::Physics;

use super::checkpoint::{self, CHECKPOINT_FILE, POLICY_FILE, write_atomic};
use super::lock::DirLock;
use crate::error::{Error, Input, Result};
use crate::model::{META_POLICY_FILE, MetaPolicy};

/// File in a run directory recording how the run was started, so that a resume continues it
/// with the same algorithm, expert and demos.
pub const RUN_FILE: &str = "run.json";

/// File in a run directory holding the configuration the run trains with.
pub const CONFIG_FILE: &str = "config.toml";

/// What a run directory records in [`RUN_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The algorithm's name (`Algo::name`).
    pub algo: String,
    /// Meta-DAgger's relabelling expert: a `smile expert` run, or `SCRIPTED_PD`.
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
    /// A record of a run of `algo` on the demos whose SHA-256 is `demos_sha256`, relabelled
    /// by `expert` (the path exactly as given).
    pub(crate) fn new(
        algo: &str,
        expert: Option<&Path>,
        demos_sha256: String,
        physics: Physics,
    ) -> Self {
        Self {
            algo: algo.into(),
            expert: expert.map(|p| p.to_string_lossy().into_owned()),
            expert_os: expert
                .filter(|p| p.to_str().is_none())
                .map(|p| p.as_os_str().to_owned()),
            demos_sha256: Some(demos_sha256),
            physics,
        }
    }

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

    /// Writes this record as `dir`'s [`RUN_FILE`], atomically.
    pub(crate) fn write(&self, dir: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self).map_err(|e| Error::Serialise {
            what: RUN_FILE,
            reason: e.to_string(),
        })?;
        write_atomic(&dir.join(RUN_FILE), json.as_bytes())
    }

    /// Refuses other demos than the ones the run in `dir` started on (`sha256`: the SHA-256
    /// of `demos`); a record older than that check passes with a warning to show.
    pub(crate) fn check_demos(
        &self,
        dir: &Path,
        demos: &Path,
        sha256: &str,
    ) -> Result<Option<String>> {
        match &self.demos_sha256 {
            Some(sha) if sha != sha256 => Err(Error::input(
                Input::Demos,
                format!(
                    "the demos {} are not the file {} was trained on (SHA-256 {} here, {} \
                     recorded in {RUN_FILE}); resume with the run's own demos, or start a new \
                     run on these",
                    demos.display(),
                    dir.display(),
                    sha256.get(..12).unwrap_or(sha256),
                    sha.get(..12).unwrap_or(sha)
                ),
            )),
            Some(_) => Ok(None),
            None => Ok(Some(format!(
                "warning: {} records no demo checksum (a run older than that check); make sure \
                 the demos are the file it started on",
                dir.join(RUN_FILE).display()
            ))),
        }
    }

    /// The recorded relabelling expert's path, exactly as it was given.
    pub fn expert_path(&self) -> Option<PathBuf> {
        self.expert_os
            .clone()
            .map(PathBuf::from)
            .or(self.expert.clone().map(PathBuf::from))
    }
}

/// Records the configuration a run trains with in `dir`'s [`CONFIG_FILE`], atomically.
pub fn write_config<T: Serialize>(dir: &Path, cfg: &T) -> Result<()> {
    let text = toml::to_string(cfg).map_err(|e| Error::Serialise {
        what: CONFIG_FILE,
        reason: e.to_string(),
    })?;
    write_atomic(&dir.join(CONFIG_FILE), text.as_bytes())
}

/// Takes `dir`'s lock for a run; a new run (not `resumes`) first clears what a run killed
/// before its first checkpoint left there, so its log does not continue the dead one's.
/// Returns the lock, held for the whole training, and the names it removed.
pub fn lock_for_run(dir: &Path, resumes: bool) -> Result<(DirLock, Vec<&'static str>)> {
    let lock = DirLock::acquire(dir)?;
    // Checked again under the lock: the directory may have changed since the request was
    // read (another process finishing its first checkpoint there).
    let removed = if resumes {
        Vec::new()
    } else {
        checkpoint::clear_interrupted_run(dir)?
    };
    Ok((lock, removed))
}

/// The configuration a `--resume` of the run in `dir`, killed before its first checkpoint,
/// starts over with: its recorded [`CONFIG_FILE`]. Refused when the run recorded none, or
/// finished and then lost its checkpoint.
pub fn restart_config(dir: &Path) -> Result<PathBuf> {
    refuse_finished_without_checkpoint(dir)?;
    let cfg = dir.join(CONFIG_FILE);
    if cfg.exists() {
        return Ok(cfg);
    }
    Err(Error::input(
        Input::Resume,
        format!(
            "{} holds no checkpoint and no config.toml: its run was interrupted before it \
             recorded its configuration, so there is nothing to resume; start it again instead \
             (its partial files are replaced)",
            dir.display()
        ),
    ))
}

/// A `--resume` of a run whose checkpoint is gone after it finished (its meta-policy marked
/// finished, or an expert's policy, which only a finished run writes): there is nothing to
/// continue from (the replay, the optimisers), and starting it over would replace a finished
/// policy; refused, naming the missing file.
fn refuse_finished_without_checkpoint(dir: &Path) -> Result<()> {
    let meta = dir.join(META_POLICY_FILE);
    let finished_meta = meta.exists()
        && MetaPolicy::training_mark(&meta)
            .ok()
            .flatten()
            .is_some_and(|m| m.finished);
    let expert = dir.join(POLICY_FILE);
    let policy = match (finished_meta, expert.exists()) {
        (true, _) => meta,
        (false, true) => expert,
        (false, false) => return Ok(()),
    };
    Err(Error::input(
        Input::Resume,
        format!(
            "{} holds a finished run, but its checkpoint {} is gone: a larger budget continues \
             from the checkpoint (its replay and optimisers), so this run cannot be extended; \
             restore the checkpoint, or train a new run in another directory (the finished \
             policy {} is kept)",
            dir.display(),
            dir.join(CHECKPOINT_FILE).display(),
            policy.display()
        ),
    ))
}
