//! `smile report`: aggregate `smile eval` results of sweeps or runs into a paper-shaped table.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use smile_app::report::Report;

/// Arguments of `smile report`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Sweep directories (with manifest.json), evaluation directories or eval.json files.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output directory (report.md, report.json, tasks.svg, context-sizes.svg).
    #[arg(short, long, default_value = "runs/report")]
    out: PathBuf,
}

/// Run `smile report`.
pub fn run(a: ReportArgs) -> Result<()> {
    let report = Report::from_inputs(&a.inputs)?;
    let written = report.write(&a.out)?;
    println!("{}", report.markdown());
    for w in written {
        eprintln!("wrote {}", w.display());
    }
    if !report.left_out.is_empty() {
        eprintln!(
            "warning: {} sweep cell(s) left out of the report (not evaluated yet, or unreadable):",
            report.left_out.len()
        );
        for l in &report.left_out {
            eprintln!("  {l}");
        }
    }
    Ok(())
}
