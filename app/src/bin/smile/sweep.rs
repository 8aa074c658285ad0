//! `smile sweep`: a grid of training + evaluation runs from a plan, on every local core or as a
//! Slurm array; `smile sweep run-cell` runs one cell (what each Slurm or Kubernetes task runs).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use smile_app::sweep::{self, BUSY_EXIT, CellOutcome, Event, Sweep};

/// Arguments of `smile sweep`.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct SweepArgs {
    #[command(subcommand)]
    cmd: Option<SweepCmd>,
    /// The plan (TOML): methods, demo files, seeds, config axes and the evaluation.
    #[arg(required = true)]
    plan: Option<PathBuf>,
    /// Cells run at once, each its own process [default: one per core; one per two cores when
    /// a cell sets `learner_threads = 2`].
    #[arg(long)]
    jobs: Option<usize>,
    /// Write a Slurm array script (and the report job) instead of running locally.
    #[arg(long)]
    slurm: bool,
    /// With --slurm: also submit both jobs with sbatch.
    #[arg(long, requires = "slurm")]
    submit: bool,
    /// With --slurm: an extra `#SBATCH` line for both scripts, e.g. "#SBATCH --partition=cpu".
    #[arg(long, requires = "slurm")]
    sbatch_line: Vec<String>,
    /// Print the cells and their status, run nothing.
    #[arg(long)]
    dry_run: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Subcommand, Debug)]
enum SweepCmd {
    /// Run one cell (train, then evaluate), resuming it if it was interrupted.
    RunCell(RunCellArgs),
}

#[derive(Args, Debug)]
struct RunCellArgs {
    /// The plan.
    plan: PathBuf,
    /// The cell index [default: $SLURM_ARRAY_TASK_ID, else $JOB_COMPLETION_INDEX].
    #[arg(long)]
    index: Option<usize>,
}

fn exe() -> Result<PathBuf> {
    std::env::current_exe().context("locating the smile binary")
}

fn run_cell(a: RunCellArgs) -> Result<()> {
    let index = match a.index {
        Some(i) => i,
        None => {
            let var = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"]
                .into_iter()
                .find_map(|v| std::env::var(v).ok().map(|x| (v, x)));
            match var {
                Some((v, x)) => x
                    .parse()
                    .with_context(|| format!("${v} = {x:?} is not a cell index"))?,
                None => bail!(
                    "give --index, or run under Slurm ($SLURM_ARRAY_TASK_ID) or a Kubernetes \
                     Indexed Job ($JOB_COMPLETION_INDEX)"
                ),
            }
        }
    };
    let sweep = Sweep::load(&a.plan)?;
    let name = sweep
        .cells
        .get(index)
        .map_or_else(String::new, |c| c.name.clone());
    let outcome = sweep::run_cell(&sweep, index)?;
    if outcome != CellOutcome::Busy {
        // Every cell's status, so `smile report` reads a sweep whose cells ran one by one.
        sweep::write_manifest(&sweep)?;
    }
    match outcome {
        CellOutcome::AlreadyDone => eprintln!("cell {index} ({name}) is done already"),
        CellOutcome::Ran => eprintln!("cell {index} ({name}) done"),
        CellOutcome::Busy => {
            eprintln!("cell {index} ({name}) is being run by another process; left to it");
            std::process::exit(BUSY_EXIT);
        }
    }
    Ok(())
}

/// Run `smile sweep`.
pub fn run(a: SweepArgs) -> Result<()> {
    if let Some(SweepCmd::RunCell(rc)) = a.cmd {
        return run_cell(rc);
    }
    let Some(plan) = a.plan.clone() else {
        bail!("give a plan file");
    };
    let sweep = Sweep::load(&plan)?;
    if a.dry_run {
        dry_run(&sweep);
        Ok(())
    } else if a.slurm {
        slurm(&sweep, &plan, &a)
    } else {
        local(&sweep, &plan, &a)
    }
}

/// `--dry-run`: every cell with its status.
fn dry_run(sweep: &Sweep) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    for c in &sweep.cells {
        let status = format!("{:?}", sweep::status(sweep, c)).to_lowercase();
        // A closed pipe (`| head`) ends the listing quietly.
        if writeln!(out, "{:>4}  {status:<10} {}", c.index, c.name).is_err() {
            break;
        }
    }
}

/// `--slurm`: the array and report scripts, submitted with `--submit`.
fn slurm(sweep: &Sweep, plan: &Path, a: &SweepArgs) -> Result<()> {
    sweep::write_manifest(sweep)?;
    let scripts = sweep::write_scripts(sweep, plan, &exe()?, &a.sbatch_line)?;
    eprintln!(
        "{} cells; wrote {} and {}",
        sweep.cells.len(),
        scripts.cells.display(),
        scripts.report.display()
    );
    if a.submit {
        let (cells, report) = sweep::submit(&scripts)?;
        println!("submitted array job {cells} and report job {report} (afterok)");
    } else {
        println!(
            "submit with: jid=$(sbatch --parsable {}) && sbatch --dependency=afterok:$jid {}",
            scripts.cells.display(),
            scripts.report.display()
        );
    }
    Ok(())
}

/// The cells on this machine, `--jobs` at once, then the report.
fn local(sweep: &Sweep, plan: &Path, a: &SweepArgs) -> Result<()> {
    let jobs = a.jobs.unwrap_or_else(|| {
        sweep.default_jobs(std::thread::available_parallelism().map_or(1, |n| n.get()))
    });
    let pb = smile_app::progress::bar(sweep.cells.len() as u64, a.quiet, "cells");
    let running = std::sync::Mutex::new(Vec::<String>::new());
    let summary = sweep::run_local(sweep, plan, jobs, &exe()?, &|e| {
        let mut r = running.lock().unwrap_or_else(|p| p.into_inner());
        match e {
            Event::Skipped(n) => {
                pb.inc(n as u64);
                if n > 0 {
                    pb.println(format!("{n} cells done already, skipped"));
                }
            }
            Event::Started(name) => r.push(name),
            Event::Finished(name, ok) => {
                r.retain(|x| *x != name);
                pb.inc(1);
                if !ok || a.quiet {
                    let how = if ok {
                        "done"
                    } else {
                        "FAILED (see its log.txt)"
                    };
                    pb.println(format!("{name}: {how}"));
                }
            }
            Event::Busy(name) => {
                r.retain(|x| *x != name);
                pb.println(format!("{name}: running in another process, left to it"));
            }
        }
        pb.set_message(r.join(", "));
    })?;
    pb.finish();
    let report_dir = sweep.out.join("report");
    match smile_app::report::Report::from_inputs(std::slice::from_ref(&sweep.out)) {
        Ok(rep) => {
            rep.write(&report_dir)?;
            println!("{}", rep.markdown());
            eprintln!("wrote {}", report_dir.display());
        }
        Err(e) => eprintln!("no report: {e}"),
    }
    let list = |what: &str, names: &[String]| match names {
        [] => String::new(),
        n => format!("; {what}: {}", n.join(", ")),
    };
    eprintln!(
        "{} of {} cells done{}{}",
        summary.done,
        sweep.cells.len(),
        list("failed", &summary.failed),
        list("running elsewhere", &summary.busy)
    );
    if !summary.failed.is_empty() {
        bail!("{} cells failed", summary.failed.len());
    }
    if !summary.busy.is_empty() {
        // The report above lacks them: not a finished sweep, so not exit 0 (EX_TEMPFAIL: run
        // it again when the other process is done).
        eprintln!(
            "error: {} cells are being run by another process ({}); the report leaves them \
             out: run `smile sweep` again when that process is done",
            summary.busy.len(),
            summary.busy.join(", ")
        );
        std::process::exit(BUSY_EXIT);
    }
    Ok(())
}
