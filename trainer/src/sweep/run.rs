//! Running cells: one cell = `smile train` then `smile eval`, each a child process of the
//! `smile` binary, single-threaded, output appended to the cell's `log.txt`.
//!
//! A cell is resumable and exclusive: a finished cell (its `eval/eval.json` exists) is skipped,
//! a cell whose training left a checkpoint continues with `smile train --resume`, and a cell
//! being run by another process (its `lock` file is locked) is left to it. The lock belongs to
//! the process running the cell (`smile sweep run-cell`), so killing a local runner, even with
//! kill -9, loses nothing: its cells finish in their own processes and a new runner skips them.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};

use super::plan::{Cell, Sweep};
use crate::{Error, Result};

/// File name of the manifest in a sweep directory.
pub const MANIFEST_FILE: &str = "manifest.json";

/// Exit status of `smile sweep run-cell` when another process holds the cell (EX_TEMPFAIL).
pub const BUSY_EXIT: i32 = 75;

/// Where a cell stands, read from its directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Nothing done yet.
    Pending,
    /// Training started (a checkpoint exists) but did not finish.
    Training,
    /// Trained, not evaluated.
    Trained,
    /// Trained and evaluated.
    Done,
    /// The last attempt failed (see `failed` and `log.txt` in the cell directory).
    Failed,
}

/// One manifest row.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ManifestCell {
    /// The cell (index, name, parameters, config).
    #[serde(flatten)]
    pub cell: Cell,
    /// Its status when the manifest was written.
    pub status: Status,
}

/// `manifest.json`: the plan's cells and their status.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// The plan file.
    pub plan: PathBuf,
    /// The family.
    pub env: String,
    /// The cells by index.
    pub cells: Vec<ManifestCell>,
}

/// The status of `cell` from its directory.
pub fn status(sweep: &Sweep, cell: &Cell) -> Status {
    let dir = sweep.cell_dir(cell);
    if dir.join("eval").join("eval.json").exists() {
        Status::Done
    } else if dir.join("failed").exists() {
        Status::Failed
    } else if dir
        .join("train/last")
        .join(crate::META_POLICY_FILE)
        .exists()
    {
        Status::Trained
    } else if dir
        .join("train")
        .join(crate::io::checkpoint::CHECKPOINT_FILE)
        .exists()
    {
        Status::Training
    } else {
        Status::Pending
    }
}

/// Writes `out/manifest.json` (atomically) with every cell's current status.
pub fn write_manifest(sweep: &Sweep) -> Result<Manifest> {
    let manifest = Manifest {
        plan: sweep.path.clone(),
        env: sweep.family.name().into(),
        cells: sweep
            .cells
            .iter()
            .map(|c| ManifestCell {
                cell: c.clone(),
                status: status(sweep, c),
            })
            .collect(),
    };
    std::fs::create_dir_all(&sweep.out).map_err(|e| Error::Io {
        path: sweep.out.clone(),
        source: e,
    })?;
    let json = serde_json::to_string_pretty(&manifest).map_err(|e| Error::Serialise {
        what: "manifest",
        reason: e.to_string(),
    })?;
    crate::io::checkpoint::write_atomic(&sweep.out.join(MANIFEST_FILE), json.as_bytes())?;
    Ok(manifest)
}

/// What [`run_cell`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellOutcome {
    /// The cell was already done.
    AlreadyDone,
    /// Trained (or resumed) and evaluated now.
    Ran,
    /// Another process holds the cell.
    Busy,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |e| Error::Io {
        path: path.to_path_buf(),
        source: e,
    }
}

/// Runs cell `index` of `sweep` with the `smile` binary `exe`: train (or resume) and evaluate,
/// holding the cell's lock. A failure leaves a `failed` file with the reason.
pub fn run_cell(sweep: &Sweep, index: usize, exe: &Path) -> Result<CellOutcome> {
    let cell = sweep.cells.get(index).ok_or_else(|| {
        Error::Config(format!(
            "cell index {index} out of range: the plan has cells 0..={}",
            sweep.cells.len().saturating_sub(1)
        ))
    })?;
    let dir = sweep.cell_dir(cell);
    std::fs::create_dir_all(&dir).map_err(io_err(&dir))?;
    let lock_path = dir.join("lock");
    let lock = std::fs::File::create(&lock_path).map_err(io_err(&lock_path))?;
    match lock.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => return Ok(CellOutcome::Busy),
        Err(std::fs::TryLockError::Error(e)) => return Err(io_err(&lock_path)(e)),
    }
    if status(sweep, cell) == Status::Done {
        return Ok(CellOutcome::AlreadyDone);
    }
    let _ = std::fs::remove_file(dir.join("failed"));
    let result = train_and_eval(sweep, cell, &dir, exe);
    if let Err(e) = &result {
        let _ = crate::io::checkpoint::write_atomic(&dir.join("failed"), e.to_string().as_bytes());
    }
    result.map(|()| CellOutcome::Ran)
}

fn train_and_eval(sweep: &Sweep, cell: &Cell, dir: &Path, exe: &Path) -> Result<()> {
    let cfg_path = dir.join("cell.toml");
    crate::io::checkpoint::write_atomic(&cfg_path, cell.config.as_bytes())?;
    let log_path = dir.join("log.txt");
    let train_dir = dir.join("train");
    let env = sweep.family.name();
    let demos = cell.demos.to_string_lossy().into_owned();
    let s = |p: &Path| p.to_string_lossy().into_owned();
    if !train_dir
        .join("last")
        .join(crate::META_POLICY_FILE)
        .exists()
    {
        let mut args: Vec<String> = vec!["train".into()];
        if train_dir
            .join(crate::io::checkpoint::CHECKPOINT_FILE)
            .exists()
        {
            args.push("--resume".into());
        } else {
            args.extend([
                "--algo".into(),
                cell.algo.clone(),
                "--config".into(),
                s(&cfg_path),
            ]);
            if let Some(e) = &cell.expert {
                args.extend(["--expert".into(), s(e)]);
            }
        }
        args.extend([
            "--env".into(),
            env.into(),
            "--demos".into(),
            demos,
            "-o".into(),
            s(&train_dir),
            "--quiet".into(),
        ]);
        child(exe, &args, &log_path)?;
    }
    let e = &sweep.plan.eval;
    let mut args: Vec<String> = vec![
        "eval".into(),
        "--policy".into(),
        s(&train_dir),
        "--env".into(),
        env.into(),
        "--split".into(),
        "test".into(),
        "--contexts".into(),
        s(&e.contexts),
        "-o".into(),
        s(&dir.join("eval")),
    ];
    if let Some(h) = e.horizon {
        args.extend(["--horizon".into(), h.to_string()]);
    }
    if let Some(r) = e.rollouts {
        args.extend(["--rollouts".into(), r.to_string()]);
    }
    if !e.context_sizes.is_empty() {
        let k: Vec<String> = e.context_sizes.iter().map(usize::to_string).collect();
        args.extend(["--context-sizes".into(), k.join(",")]);
    }
    if let Some(base) = &e.base {
        let experts: Vec<String> = e.experts.iter().map(|p| s(p)).collect();
        args.extend([
            "--base".into(),
            s(base),
            "--expert".into(),
            experts.join(","),
        ]);
    }
    child(exe, &args, &log_path)
}

/// Runs `exe args` single-threaded with stdout and stderr appended to `log`.
fn child(exe: &Path, args: &[String], log: &Path) -> Result<()> {
    let open = || {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)
            .map_err(io_err(log))
    };
    let out = open()?;
    let err = out.try_clone().map_err(io_err(log))?;
    {
        use std::io::Write;
        let mut f = open()?;
        let _ = writeln!(f, "$ smile {}", args.join(" "));
    }
    let status = Command::new(exe)
        .args(args)
        .env("RAYON_NUM_THREADS", "1")
        .stdin(std::process::Stdio::null())
        .stdout(out)
        .stderr(err)
        .status()
        .map_err(io_err(exe))?;
    if status.success() {
        Ok(())
    } else {
        Err(Error::Child {
            command: format!("smile {}", args.first().map_or("", String::as_str)),
            status: status.to_string(),
            log: log.to_path_buf(),
        })
    }
}
