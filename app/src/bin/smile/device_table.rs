//! `smile device-table`: shipped meta-policies from float to int8 to the device loop.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use smile_app::device_table::{self, TableConfig};

/// Arguments of `smile device-table`.
#[derive(Args, Debug)]
pub struct DeviceTableArgs {
    /// Shipped policy directories (meta_policy.safetensors and deploy.toml), e.g.
    /// assets/policies/*.
    #[arg(required = true)]
    policies: Vec<PathBuf>,
    /// Context draws per test task (each teaches one demo).
    #[arg(long, default_value_t = 3, value_parser = crate::positive)]
    draws: usize,
    /// Rollouts per draw.
    #[arg(long, default_value_t = 1, value_parser = crate::positive)]
    rollouts: usize,
    /// Measure on the tasks this demo file holds (new tasks recorded with `smile demos
    /// --task-params`, its demos the one-demo contexts) instead of each policy's test split and
    /// `deploy.toml` contexts: more tasks narrow a standard error that more episodes cannot.
    #[arg(long)]
    new_tasks: Option<PathBuf>,
    /// Output directory for device-table.md and device-table.json.
    #[arg(short, long, default_value = "runs/device-table")]
    out: PathBuf,
}

/// Run `smile device-table`.
pub fn run(a: DeviceTableArgs) -> Result<()> {
    let config = TableConfig {
        draws: a.draws,
        rollouts: a.rollouts,
        new_tasks: a.new_tasks,
    };
    let mut rows = Vec::new();
    for dir in &a.policies {
        let row = device_table::measure(dir, &config, &mut |line| eprintln!("{line}"))
            .with_context(|| format!("measuring {}", dir.display()))?;
        rows.push(row);
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let md = device_table::markdown(&rows);
    trainer::checkpoint::write_atomic(&a.out.join("device-table.md"), md.as_bytes())?;
    trainer::checkpoint::write_atomic(
        &a.out.join("device-table.json"),
        serde_json::to_string_pretty(&rows)?.as_bytes(),
    )?;
    print!("{md}");
    eprintln!("wrote {}/device-table.{{md,json}}", a.out.display());
    Ok(())
}
