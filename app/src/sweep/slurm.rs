//! Slurm: an `sbatch` array script with one array index per cell (`--cpus-per-task` = the
//! cells' learner threads, one log per cell) whose tasks run `smile sweep run-cell PLAN --index
//! $SLURM_ARRAY_TASK_ID`, and a report job that runs after every cell succeeded
//! (`--dependency=afterok`).
//!
//! The same `run-cell` serves a Kubernetes Indexed Job: it reads `JOB_COMPLETION_INDEX` when
//! no `--index` is given (docs/GUIDE.md, "Sweeps").

use std::path::{Path, PathBuf};
use std::process::Command;

use super::plan::Sweep;
use trainer::{Error, Result};

/// The scripts written for a sweep.
#[derive(Debug, Clone)]
pub struct SlurmScripts {
    /// The array job over cells.
    pub cells: PathBuf,
    /// The report job.
    pub report: PathBuf,
}

fn abs(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).map_err(|e| Error::Io {
        path: p.to_path_buf(),
        source: e,
    })
}

fn quote(p: &Path) -> String {
    format!("'{}'", p.to_string_lossy().replace('\'', "'\\''"))
}

/// Writes `out/slurm/cells.sbatch` and `out/slurm/report.sbatch` for `sweep`, whose plan is
/// at `plan_path`, to be run by the `smile` binary `exe`. `extra` lines (e.g.
/// `#SBATCH --partition=cpu`) go into both headers.
pub fn write_scripts(
    sweep: &Sweep,
    plan_path: &Path,
    exe: &Path,
    extra: &[String],
) -> Result<SlurmScripts> {
    let dir = abs(&sweep.out.join("slurm"))?;
    std::fs::create_dir_all(&dir).map_err(|e| Error::Io {
        path: dir.clone(),
        source: e,
    })?;
    let cwd = std::env::current_dir().map_err(|e| Error::Io {
        path: PathBuf::from("."),
        source: e,
    })?;
    let (exe, plan) = (abs(exe)?, abs(plan_path)?);
    let out = abs(&sweep.out)?;
    // A batch script is text: a path that is not UTF-8 cannot be written into it faithfully
    // (a lossy copy would name another file), so it is refused by name.
    for p in [&cwd, &dir, &exe, &plan, &out] {
        if p.to_str().is_none() {
            return Err(Error::Config(format!(
                "Slurm batch scripts are text, and this path is not UTF-8: {}; run the sweep \
                 from a UTF-8 path (or locally, `smile sweep PLAN` without --slurm, which passes paths as they are)",
                p.display()
            )));
        }
    }
    // `#SBATCH` lines are not parsed by a shell: no quoting there, so no whitespace either.
    for p in [&cwd, &dir] {
        if p.to_string_lossy().chars().any(char::is_whitespace) {
            return Err(Error::Config(format!(
                "Slurm needs a sweep directory and working directory without whitespace: {}",
                p.display()
            )));
        }
    }
    let n = sweep.cells.len();
    let extra: String = extra.iter().map(|l| format!("{l}\n")).collect();
    let name = sweep
        .out
        .file_name()
        .map_or("sweep".into(), |s| s.to_string_lossy().into_owned());
    let cells = format!(
        "#!/bin/bash
# {n} cells of {plan}: one array task per cell, {cpus} CPU(s) each.
#SBATCH --job-name=smile-{name}
#SBATCH --array=0-{last}
#SBATCH --cpus-per-task={cpus}
#SBATCH --chdir={cwd_raw}
#SBATCH --output={log}/cell-%a.out
#SBATCH --error={log}/cell-%a.out
{extra}export RAYON_NUM_THREADS=1
exec {exe} sweep run-cell {plan} --index \"$SLURM_ARRAY_TASK_ID\"
",
        plan = quote(&plan),
        last = n.saturating_sub(1),
        cpus = sweep.cpus_per_cell(),
        cwd_raw = cwd.to_string_lossy(),
        log = dir.to_string_lossy(),
        exe = quote(&exe),
    );
    let report = format!(
        "#!/bin/bash
# The report of {plan}, after every cell succeeded (submitted with --dependency=afterok).
#SBATCH --job-name=smile-{name}-report
#SBATCH --cpus-per-task=1
#SBATCH --chdir={cwd_raw}
#SBATCH --output={log}/report.out
#SBATCH --error={log}/report.out
{extra}export RAYON_NUM_THREADS=1
exec {exe} report {out} -o {report_dir}
",
        plan = quote(&plan),
        cwd_raw = cwd.to_string_lossy(),
        log = dir.to_string_lossy(),
        exe = quote(&exe),
        out = quote(&out),
        report_dir = quote(&out.join("report")),
    );
    let scripts = SlurmScripts {
        cells: dir.join("cells.sbatch"),
        report: dir.join("report.sbatch"),
    };
    trainer::checkpoint::write_atomic(&scripts.cells, cells.as_bytes())?;
    trainer::checkpoint::write_atomic(&scripts.report, report.as_bytes())?;
    Ok(scripts)
}

/// Submits the array job, then the report job depending on it; returns both job ids.
pub fn submit(scripts: &SlurmScripts) -> Result<(String, String)> {
    let sbatch = |args: &[&str], script: &Path| -> Result<String> {
        let out = Command::new("sbatch")
            .arg("--parsable")
            .args(args)
            .arg(script)
            .output()
            .map_err(|e| Error::Io {
                path: PathBuf::from("sbatch"),
                source: e,
            })?;
        if !out.status.success() {
            return Err(Error::Child {
                command: format!("sbatch {}", script.display()),
                status: format!(
                    "{}: {}",
                    out.status,
                    String::from_utf8_lossy(&out.stderr).trim()
                ),
                log: script.to_path_buf(),
            });
        }
        let id = String::from_utf8_lossy(&out.stdout);
        Ok(id.trim().split(';').next().unwrap_or("").to_string())
    };
    let cells = sbatch(&[], &scripts.cells)?;
    let report = sbatch(&[&format!("--dependency=afterok:{cells}")], &scripts.report)?;
    Ok((cells, report))
}
