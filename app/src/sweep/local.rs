//! The local runner: `jobs` cells at a time, each in its own `smile sweep run-cell` process
//! (single-threaded), so that the runner can be killed without losing a cell.

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::plan::Sweep;
use super::run::{BUSY_EXIT, Status, status, write_manifest};
use trainer::Result;

/// What the local runner reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// Cells already done before this run, skipped.
    Skipped(usize),
    /// A cell started (its name).
    Started(String),
    /// A cell finished: its name and whether it succeeded.
    Finished(String, bool),
    /// A cell is being run by another process (a killed runner's child, a Slurm task).
    Busy(String),
}

/// How a local sweep ended.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Summary {
    /// Cells done now (including those done before).
    pub done: usize,
    /// Cells that failed (names).
    pub failed: Vec<String>,
    /// Cells left to another process (names).
    pub busy: Vec<String>,
}

/// Runs every cell not yet done, `jobs` at a time, with the `smile` binary `exe`.
pub fn run_local(
    sweep: &Sweep,
    plan_path: &Path,
    jobs: usize,
    exe: &Path,
    on: &(dyn Fn(Event) + Sync),
) -> Result<Summary> {
    write_manifest(sweep)?;
    let todo: Vec<usize> = sweep
        .cells
        .iter()
        .filter(|c| status(sweep, c) != Status::Done)
        .map(|c| c.index)
        .collect();
    on(Event::Skipped(sweep.cells.len() - todo.len()));
    let next = AtomicUsize::new(0);
    let summary = Mutex::new(Summary::default());
    let manifest_lock = Mutex::new(());
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(todo.len().max(1)) {
            s.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(&i) = todo.get(k) else { break };
                    let name = sweep.cells[i].name.clone();
                    on(Event::Started(name.clone()));
                    let code = Command::new(exe)
                        .args(["sweep", "run-cell"])
                        .arg(plan_path)
                        .args(["--index", &i.to_string()])
                        .env("RAYON_NUM_THREADS", "1")
                        .stdin(std::process::Stdio::null())
                        .stdout(std::process::Stdio::null())
                        .stderr(std::process::Stdio::null())
                        .status()
                        .map(|st| st.code());
                    let mut sum = summary.lock().unwrap_or_else(|e| e.into_inner());
                    match code {
                        Ok(Some(0)) => {
                            on(Event::Finished(name, true));
                        }
                        Ok(Some(BUSY_EXIT)) => {
                            on(Event::Busy(name.clone()));
                            sum.busy.push(name);
                        }
                        _ => {
                            on(Event::Finished(name.clone(), false));
                            sum.failed.push(name);
                        }
                    }
                    drop(sum);
                    let _guard = manifest_lock.lock().unwrap_or_else(|e| e.into_inner());
                    let _ = write_manifest(sweep);
                }
            });
        }
    });
    let manifest = write_manifest(sweep)?;
    let mut sum = summary.into_inner().unwrap_or_else(|e| e.into_inner());
    sum.done = manifest
        .cells
        .iter()
        .filter(|c| c.status == Status::Done)
        .count();
    // A cell another process held when this one tried it may have finished since: it is done,
    // not running elsewhere.
    sum.busy.retain(|name| {
        manifest
            .cells
            .iter()
            .any(|c| c.cell.name == *name && c.status != Status::Done)
    });
    Ok(sum)
}
