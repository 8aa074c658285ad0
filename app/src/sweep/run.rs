//! Running cells: one cell = a training run then its evaluation, both through the library
//! ([`trainer::run::train`], [`trainer::eval::evaluate_to_dir`]) in the process running the
//! cell (`smile sweep run-cell`, single-threaded), messages appended to the cell's `log.txt`.
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

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim::Split;
use trainer::eval::{EvalEvent, EvalRequest};
use trainer::run::TrainRequest;

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

/// The settings that continue the training in the cell directory to `cell`'s larger budget,
/// when it holds one for the same settings but a smaller budget: the recorded key is the key
/// of `cell` with the recorded config, and the algorithm finds the two configs equal but for
/// a budget, none of it lower now and some higher ([`trainer::Algo::extension`]).
fn extension(dir: &Path, cell: &Cell) -> Option<Vec<trainer::Setting>> {
    let record = std::fs::read_to_string(dir.join("cell.json")).ok()?;
    let old_text = std::fs::read_to_string(dir.join("cell.toml")).ok()?;
    let record = serde_json::from_str::<CellRecord>(&record).ok()?;
    let old_cell = Cell {
        config: old_text.clone(),
        ..cell.clone()
    };
    if record.key == cell.key || old_cell.training_key() != record.key {
        return None;
    }
    let algo: trainer::Algo = cell.algo.parse().ok()?;
    algo.extension(&old_text, &cell.config)
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
        if extension(&dir, cell).is_some() {
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

/// Runs cell `index` of `sweep` in this process: train (or resume) and evaluate, holding the
/// cell's lock. A failure leaves a `failed` file with the reason.
pub fn run_cell(sweep: &Sweep, index: usize) -> Result<CellOutcome> {
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
            return run_cell(sweep, index);
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
    let result = train_and_eval(sweep, cell, &dir, extend);
    if let Err(e) = &result {
        let _ = trainer::checkpoint::write_atomic(&dir.join("failed"), e.to_string().as_bytes());
    }
    result.map(|()| CellOutcome::Ran)
}

/// Trains the cell (or continues it: `extend`, see [`Status::Extend`]), then evaluates it,
/// both in this process through the library ([`trainer::run::train`],
/// [`trainer::eval::evaluate_to_dir`]), every message appended to the cell's `log.txt`.
fn train_and_eval(sweep: &Sweep, cell: &Cell, dir: &Path, extend: bool) -> Result<()> {
    let cfg_path = dir.join("cell.toml");
    let record = serde_json::to_string(&CellRecord {
        key: cell.key.clone(),
    })
    .unwrap_or_default();
    let write_record = || -> Result<()> {
        trainer::checkpoint::write_atomic(&cfg_path, cell.config.as_bytes())?;
        trainer::checkpoint::write_atomic(&dir.join("cell.json"), record.as_bytes())
    };
    let mut log = CellLog::open(&dir.join("log.txt"))?;
    let result = (|| {
        let train_dir = dir.join("train");
        // An extension keeps the old record until the longer training is done, so an
        // interrupted one is found as one again and resumes from its latest checkpoint; any
        // other training records its settings first.
        if !extend {
            write_record()?;
        }
        let trained = train_dir
            .join("last")
            .join(trainer::META_POLICY_FILE)
            .exists();
        if extend || !trained {
            let mut req = TrainRequest {
                demos: cell.demos.clone(),
                out: train_dir.clone(),
                family: Some(sweep.family),
                ..TrainRequest::default()
            };
            if extend {
                req.settings = extension(dir, cell).ok_or_else(|| {
                    Error::Config(format!("cell {}: no longer an extension", cell.name))
                })?;
                req.resume = true;
                log.line("train: extending the cell's run to the plan's larger budget");
            } else if train_dir
                .join(trainer::checkpoint::CHECKPOINT_FILE)
                .exists()
            {
                req.resume = true;
                log.line("train: resuming from the cell's checkpoint");
            } else {
                req.algo = Some(cell.algo.parse()?);
                req.config_file = Some(cfg_path.clone());
                req.expert = cell.expert.clone();
                log.line(&format!("train: {} on {}", cell.algo, cell.demos.display()));
            }
            trainer::run::train(&req, &mut |e| {
                if let Some(line) = crate::progress::log_line(&e) {
                    log.line(&line);
                }
            })?;
        }
        if extend {
            write_record()?;
        }
        let e = &sweep.plan.eval;
        let eval_dir = dir.join("eval");
        let mut req = EvalRequest::new(
            vec![train_dir],
            sweep.family,
            Split::Test,
            e.contexts.clone(),
            eval_dir.clone(),
        );
        req.horizon = e.horizon;
        req.rollouts = e.rollouts;
        req.context_sizes = e.context_sizes.clone();
        if let Some(base) = &e.base {
            req.base = Some(base.clone());
            req.experts = e.experts.clone();
        }
        // An evaluation for other settings is made again; plan.json says which settings made it.
        let _ = std::fs::remove_file(eval_dir.join("eval.json"));
        log.line(&format!("eval: on {}", e.contexts.display()));
        let report = trainer::eval::evaluate_to_dir(&req, &mut |ev| {
            if let EvalEvent::Note(text) = ev {
                log.line(&text);
            }
        })?;
        log.line(&report.markdown());
        trainer::checkpoint::write_atomic(
            &eval_dir.join("plan.json"),
            eval_record(sweep).as_bytes(),
        )
    })();
    if let Err(e) = &result {
        log.line(&format!("error: {e}"));
    }
    result
}

/// A cell's `log.txt`, appended to line by line (a failed write is not worth failing the cell
/// for: the run's own files are what count).
struct CellLog(std::fs::File);

impl CellLog {
    fn open(path: &Path) -> Result<Self> {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map(CellLog)
            .map_err(io_err(path))
    }

    fn line(&mut self, text: &str) {
        use std::io::Write;
        let _ = writeln!(self.0, "{text}");
    }
}
