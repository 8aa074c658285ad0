//! Running cells: one cell = `smile train` then `smile eval`, each a child process of the
//! `smile` binary, single-threaded, output appended to the cell's `log.txt`.
//!
//! A cell is resumable and exclusive: a finished cell (its `eval/eval.json` exists) is skipped,
//! a cell whose training left a checkpoint continues with `smile train --resume`, and a cell
//! being run by another process (its `lock` file is locked) is left to it. The lock belongs to
//! the process running the cell (`smile sweep run-cell`), so killing a local runner, even with
//! kill -9, loses nothing: its cells finish in their own processes and a new runner skips them.
//!
//! A cell directory records what it was made from (`cell.json`: the training key; `cell.toml`:
//! the config; `eval/plan.json`: the evaluation settings). After a plan is edited, a cell
//! trained for other settings is *stale*: its directory is moved aside (`<name>.stale-<key>`)
//! and it trains again, except a SMILe cell whose plan only raised its budget
//! (`total_updates`, `cpu_budget_s`): that one *extends*, continuing from its checkpoint with
//! `smile train --resume` (its earlier evaluation kept as `eval.before-<key>`), so a longer
//! budget costs only the extra updates. A cell whose evaluation settings changed is evaluated
//! again. A
//! finished evaluation is one whose `eval.json` parses, written last (atomically) by
//! `smile eval`.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};

use super::plan::{Cell, Sweep};
use trainer::{Error, Result};

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
    /// The directory holds a training for other settings (the plan was edited): it is moved
    /// aside and the cell runs again.
    Stale,
    /// A SMILe training whose plan only raised its budget (`total_updates`, `cpu_budget_s`):
    /// it continues from its checkpoint and is evaluated again.
    Extend,
}

/// The record of what a cell directory was trained for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct CellRecord {
    key: String,
}

/// True when the cell directory was made for other training settings than `cell`'s.
fn is_stale(dir: &Path, cell: &Cell) -> bool {
    if let Ok(text) = std::fs::read_to_string(dir.join("cell.json")) {
        return serde_json::from_str::<CellRecord>(&text).map_or(true, |r| r.key != cell.key);
    }
    // Cells made before cell.json: their cell.toml is the config they trained with.
    std::fs::read_to_string(dir.join("cell.toml")).is_ok_and(|t| t != cell.config)
}

/// True when the cell directory holds a SMILe training for the same settings as `cell` but a
/// smaller budget: the recorded key is the key of `cell` with the recorded config, and the two
/// configs differ only in `total_updates` and `cpu_budget_s`, neither lower now (a budget of 0,
/// none, counts as unlimited) and at least one higher.
fn extends(dir: &Path, cell: &Cell) -> bool {
    use trainer::smile::SmileConfig;
    if !cell.algo.starts_with("smile") {
        return false;
    }
    let (Ok(record), Ok(old_text)) = (
        std::fs::read_to_string(dir.join("cell.json")),
        std::fs::read_to_string(dir.join("cell.toml")),
    ) else {
        return false;
    };
    let Ok(record) = serde_json::from_str::<CellRecord>(&record) else {
        return false;
    };
    let old_cell = Cell {
        config: old_text.clone(),
        ..cell.clone()
    };
    if record.key == cell.key || old_cell.training_key() != record.key {
        return false;
    }
    let (Ok(old), Ok(new)) = (
        toml::from_str::<SmileConfig>(&old_text),
        toml::from_str::<SmileConfig>(&cell.config),
    ) else {
        return false;
    };
    let budget = |c: &SmileConfig| {
        if c.cpu_budget_s > 0.0 {
            c.cpu_budget_s
        } else {
            f64::INFINITY
        }
    };
    let same_but_budget = SmileConfig {
        total_updates: new.total_updates,
        cpu_budget_s: new.cpu_budget_s,
        ..old.clone()
    } == new;
    let not_lower = new.total_updates >= old.total_updates && budget(&new) >= budget(&old);
    let higher = new.total_updates > old.total_updates || budget(&new) > budget(&old);
    same_but_budget && not_lower && higher
}

/// The evaluation settings of a sweep, as recorded beside a cell's eval.json.
fn eval_record(sweep: &Sweep) -> String {
    serde_json::to_string_pretty(&sweep.plan.eval).unwrap_or_default()
}

/// True when the cell's evaluation is finished and was made with the plan's settings.
fn eval_done(sweep: &Sweep, dir: &Path) -> bool {
    let eval = dir.join("eval");
    let parses = std::fs::read_to_string(eval.join("eval.json")).is_ok_and(|t| {
        serde_json::from_str::<serde_json::Value>(&t).is_ok_and(|v| v["methods"].is_array())
    });
    let same = match std::fs::read_to_string(eval.join("plan.json")) {
        Ok(t) => t == eval_record(sweep),
        Err(_) => true, // evaluations made before plan.json
    };
    parses && same
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
    #[serde(with = "trainer::os_path")]
    pub plan: PathBuf,
    /// The family.
    pub env: sim::Family,
    /// The cells by index.
    pub cells: Vec<ManifestCell>,
}

/// The status of `cell` from its directory.
pub fn status(sweep: &Sweep, cell: &Cell) -> Status {
    let dir = sweep.cell_dir(cell);
    if is_stale(&dir, cell) {
        if extends(&dir, cell) {
            Status::Extend
        } else {
            Status::Stale
        }
    } else if eval_done(sweep, &dir) {
        Status::Done
    } else if dir.join("failed").exists() {
        Status::Failed
    } else if dir
        .join("train/last")
        .join(trainer::META_POLICY_FILE)
        .exists()
    {
        Status::Trained
    } else if dir
        .join("train")
        .join(trainer::checkpoint::CHECKPOINT_FILE)
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
        env: sweep.family,
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
    trainer::checkpoint::write_atomic(&sweep.out.join(MANIFEST_FILE), json.as_bytes())?;
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
    let extend = match status(sweep, cell) {
        Status::Done => return Ok(CellOutcome::AlreadyDone),
        Status::Stale => {
            // Keep the old training (it is someone's result), out of the way.
            let aside = dir.with_file_name(format!(
                "{}.stale-{}",
                cell.name,
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_secs())
            ));
            drop(lock);
            std::fs::rename(&dir, &aside).map_err(io_err(&dir))?;
            eprintln!(
                "cell {}: trained for other settings (the plan changed); moved to {}, training again",
                cell.name,
                aside.display()
            );
            return run_cell(sweep, index, exe);
        }
        Status::Extend => {
            // The evaluation at the smaller budget is someone's result too: kept beside.
            let eval = dir.join("eval");
            if eval.join("eval.json").exists() {
                let old_key = std::fs::read_to_string(dir.join("cell.json"))
                    .ok()
                    .and_then(|t| serde_json::from_str::<CellRecord>(&t).ok())
                    .map_or_else(|| "earlier".to_string(), |r| r.key);
                let aside = dir.join(format!("eval.before-{old_key}"));
                if !aside.exists() {
                    std::fs::rename(&eval, &aside).map_err(io_err(&eval))?;
                }
            }
            true
        }
        _ => false,
    };
    let _ = std::fs::remove_file(dir.join("failed"));
    let result = train_and_eval(sweep, cell, &dir, exe, extend);
    if let Err(e) = &result {
        let _ = trainer::checkpoint::write_atomic(&dir.join("failed"), e.to_string().as_bytes());
    }
    result.map(|()| CellOutcome::Ran)
}

/// Trains the cell (or continues it: `extend`, see [`Status::Extend`]), then evaluates it.
fn train_and_eval(sweep: &Sweep, cell: &Cell, dir: &Path, exe: &Path, extend: bool) -> Result<()> {
    let cfg_path = dir.join("cell.toml");
    let record = serde_json::to_string(&CellRecord {
        key: cell.key.clone(),
    })
    .unwrap_or_default();
    let write_record = || -> Result<()> {
        trainer::checkpoint::write_atomic(&cfg_path, cell.config.as_bytes())?;
        trainer::checkpoint::write_atomic(&dir.join("cell.json"), record.as_bytes())
    };
    let log_path = dir.join("log.txt");
    let train_dir = dir.join("train");
    let env = sweep.family.name();
    // An extension keeps the old record until the longer training is done, so an interrupted
    // one is found as one again and resumes from its latest checkpoint; any other training
    // records its settings first.
    if !extend {
        write_record()?;
    }
    // Arguments as OS strings: a plan under a folder whose name is not UTF-8 passes its paths
    // through unchanged (a lossy conversion would name files that do not exist).
    let demos: OsString = cell.demos.clone().into_os_string();
    let s = |p: &Path| -> OsString { p.as_os_str().to_owned() };
    let trained = train_dir
        .join("last")
        .join(trainer::META_POLICY_FILE)
        .exists();
    if extend || !trained {
        let mut args: Vec<OsString> = vec!["train".into()];
        if extend {
            let new: trainer::smile::SmileConfig = toml::from_str(&cell.config)
                .map_err(|e| Error::Config(format!("cell {}: {e}", cell.name)))?;
            args.extend([
                "--resume".into(),
                "--updates".into(),
                new.total_updates.to_string().into(),
                "--cpu-budget".into(),
                new.cpu_budget_s.to_string().into(),
            ]);
        } else if train_dir
            .join(trainer::checkpoint::CHECKPOINT_FILE)
            .exists()
        {
            args.push("--resume".into());
        } else {
            args.extend([
                "--algo".into(),
                cell.algo.clone().into(),
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
    if extend {
        write_record()?;
    }
    let e = &sweep.plan.eval;
    let mut args: Vec<OsString> = vec![
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
        args.extend(["--horizon".into(), h.to_string().into()]);
    }
    if let Some(r) = e.rollouts {
        args.extend(["--rollouts".into(), r.to_string().into()]);
    }
    if !e.context_sizes.is_empty() {
        let k: Vec<String> = e.context_sizes.iter().map(usize::to_string).collect();
        args.extend(["--context-sizes".into(), k.join(",").into()]);
    }
    if let Some(base) = &e.base {
        let mut experts = OsString::new();
        for (i, p) in e.experts.iter().enumerate() {
            if i > 0 {
                experts.push(",");
            }
            experts.push(p);
        }
        args.extend(["--base".into(), s(base), "--expert".into(), experts]);
    }
    // An evaluation for other settings is made again; plan.json says which settings made it.
    let eval_dir = dir.join("eval");
    let _ = std::fs::remove_file(eval_dir.join("eval.json"));
    child(exe, &args, &log_path)?;
    trainer::checkpoint::write_atomic(&eval_dir.join("plan.json"), eval_record(sweep).as_bytes())
}

/// Runs `exe args` single-threaded with stdout and stderr appended to `log`.
fn child(exe: &Path, args: &[OsString], log: &Path) -> Result<()> {
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
        let shown: Vec<_> = args.iter().map(|a| a.to_string_lossy()).collect();
        let _ = writeln!(f, "$ smile {}", shown.join(" "));
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
            command: format!(
                "smile {}",
                args.first().map_or("".into(), |a| a.to_string_lossy())
            ),
            status: status.to_string(),
            log: log.to_path_buf(),
        })
    }
}
