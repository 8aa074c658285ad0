//! The quickstart's results: [`Summary`] (`summary.json`) and its `report.md` rendering.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use trainer::eval::EvalReport;
use trainer::export::Parity;

/// What a quickstart run measured; written as `summary.json`, rendered as `report.md`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Task family.
    pub env: sim::Family,
    /// Budget name.
    pub budget: String,
    /// Seed.
    pub seed: u64,
    /// Which expert made the demos.
    pub expert: String,
    /// (method, mean over test tasks, std over test tasks) of the family's metric.
    pub eval: Vec<(String, f32, f32)>,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Blob quantization.
    pub blob_quant: String,
    /// Blob vs float policy on held-out contexts.
    pub parity: Parity,
    /// Test metric of the blob policy.
    pub blob_metric: f32,
    /// Test metric of the float policy it came from.
    pub float_metric: f32,
    /// Task of the device run.
    pub device_task: String,
    /// Metric of the device run.
    pub device_metric: f32,
    /// Control ticks run.
    pub device_ticks: usize,
    /// Ticks with a non-finite reading.
    pub device_faults: usize,
    /// Ticks over the compute budget.
    pub device_overruns: usize,
    /// Median compute per tick, microseconds.
    pub device_median_us: f64,
    /// 99th percentile compute per tick, microseconds.
    pub device_p99_us: f64,
    /// Wall time of the whole run.
    pub seconds: f64,
}

/// `report.md`: the held-out results, the blob checks and the device run.
pub(super) fn report_markdown(s: &Summary, report: &EvalReport) -> String {
    let mut md = String::new();
    let better = if report.lower_is_better {
        "lower is better"
    } else {
        "higher is better"
    };
    let _ = writeln!(md, "# SMILe quickstart: {}\n", s.env);
    let _ = writeln!(
        md,
        "Budget `{}`, seed {}, {:.0} s. Expert: {}.\n",
        s.budget, s.seed, s.seconds, s.expert
    );
    let _ = writeln!(
        md,
        "## Held-out meta-test tasks ({}, {better})\n",
        report.metric
    );
    let _ = writeln!(
        md,
        "| method | mean over test tasks | std over tasks |\n|---|---|---|"
    );
    for (name, mean, std) in &s.eval {
        let _ = writeln!(md, "| {name} | {mean:.4} | {std:.4} |");
    }
    let _ = writeln!(
        md,
        "\nPer task: `eval.md`, `eval.json`; plot: `eval.svg`.\n"
    );
    let _ = writeln!(md, "## Blob ({}, {} bytes)\n", s.blob_quant, s.blob_bytes);
    let _ = writeln!(md, "| check | value |\n|---|---|");
    let _ = writeln!(
        md,
        "| action max abs diff vs float | {:.5} |",
        s.parity.action_max_abs_diff
    );
    let _ = writeln!(
        md,
        "| action mean abs diff vs float | {:.6} |",
        s.parity.action_mean_abs_diff
    );
    let _ = writeln!(
        md,
        "| z max abs diff vs float | {:.5} |",
        s.parity.z_max_abs_diff
    );
    let _ = writeln!(md, "| metric, float policy | {:.4} |", s.float_metric);
    let _ = writeln!(md, "| metric, blob policy | {:.4} |", s.blob_metric);
    let _ = writeln!(md, "\n## Device (firmware-sim)\n");
    let _ = writeln!(
        md,
        "| task | metric | ticks | faults | overruns | compute median | compute p99 |\n|---|---|---|---|---|---|---|"
    );
    let _ = writeln!(
        md,
        "| {} | {:.4} | {} | {} | {} | {:.2} us | {:.2} us |",
        s.device_task,
        s.device_metric,
        s.device_ticks,
        s.device_faults,
        s.device_overruns,
        s.device_median_us,
        s.device_p99_us
    );
    let _ = writeln!(md, "\nTrace: `device/trace.csv`; plot: `device/plot.svg`.");
    md
}
