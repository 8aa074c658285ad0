//! `smile quickstart`: flags for [`smile_app::quickstart`].

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use sim::Family;
use smile_app::quickstart::{Budget, DeviceSensing, QuickstartConfig};

/// Arguments of `smile quickstart`.
#[derive(Args, Debug)]
pub struct QuickstartArgs {
    /// Task family (point-goal is the fast one; the others need a trained SAC expert first).
    #[arg(long, default_value = "point-goal")]
    env: Family,
    /// Run directory.
    #[arg(short, long, default_value = "runs/quickstart")]
    out: PathBuf,
    /// Seed of the whole pipeline.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Compute budget: tiny (2-15 s, plumbing only), short (point-goal: about 2 min), long.
    #[arg(long, value_enum, default_value_t = Budget::Short)]
    budget: Budget,
    /// Demos per meta-train task.
    #[arg(long, default_value_t = 4, value_parser = crate::positive)]
    demos_per_task: usize,
    /// Subsampling factor of the demos (keep every k-th step).
    #[arg(long, default_value_t = 20, value_parser = crate::positive)]
    subsample: usize,
    /// No progress bars.
    #[arg(long)]
    quiet: bool,
    /// Write into a non-empty `--out` (its files are replaced); without it the quickstart
    /// refuses one, so an earlier run's results are never overwritten or mixed with these.
    #[arg(long)]
    force: bool,
    /// Directory of shipped experts and demos [default: the repository's assets/experts].
    #[arg(long)]
    assets: Option<std::path::PathBuf>,
    /// What the simulated device senses: the full observation, or positions only with an
    /// on-device velocity estimator.
    #[arg(long, value_enum, default_value_t = DeviceSensing::Full)]
    sensing: DeviceSensing,
}

/// Run `smile quickstart`.
pub fn run(a: QuickstartArgs) -> Result<()> {
    let non_empty = std::fs::read_dir(&a.out).is_ok_and(|mut d| d.next().is_some());
    if non_empty && !a.force {
        anyhow::bail!(
            "{} already holds files (an earlier quickstart?); pass --force to replace them, or \
             choose another --out (nothing was touched)",
            a.out.display()
        );
    }
    let config = QuickstartConfig {
        env: a.env,
        out: a.out,
        seed: a.seed,
        budget: a.budget,
        demos_per_task: a.demos_per_task,
        subsample: a.subsample,
        quiet: a.quiet,
        assets: a.assets,
        sensing: a.sensing,
    };
    smile_app::quickstart::run(&config)?;
    Ok(())
}
