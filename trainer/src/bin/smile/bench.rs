//! `smile bench`.

use anyhow::Result;
use clap::Args;
use trainer::bench::{SacBenchShape, bench_sac_update};

/// Arguments of `smile bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Hidden widths to time.
    #[arg(long, num_args = 1.., default_values_t = [64usize, 128, 256])]
    hidden: Vec<usize>,
    /// Timed iterations per width.
    #[arg(long, default_value_t = 200)]
    iters: usize,
    /// Untimed warm-up iterations per width.
    #[arg(long, default_value_t = 20)]
    warmup: usize,
    /// Also write the results as one JSON object to this file.
    #[arg(long)]
    json: Option<std::path::PathBuf>,
}

/// Run the benchmark and print a table.
pub fn run(a: BenchArgs) -> Result<()> {
    let threads = trainer::threads::compute_threads();
    println!("sac update, batch 256, obs 20 + z 16, act 6, candle threads {threads}");
    println!(
        "{:>5} {:>12} {:>10} {:>10} {:>10} {:>12}",
        "H", "median_us", "p10_us", "p90_us", "upd/s", "cpu_mean_us"
    );
    let mut rows = Vec::new();
    for &h in &a.hidden {
        let t = bench_sac_update(SacBenchShape::reference(h), a.warmup, a.iters)?;
        println!(
            "{h:>5} {:>12.1} {:>10.1} {:>10.1} {:>10.1} {:>12}",
            t.median_us,
            t.p10_us,
            t.p90_us,
            t.updates_per_s,
            t.cpu_mean_us.map_or("n/a".into(), |c| format!("{c:.1}"))
        );
        rows.push(serde_json::json!({"workload": "sac", "H": h, "threads": threads, "timing": t}));
    }
    if let Some(p) = a.json {
        std::fs::write(&p, serde_json::to_string_pretty(&rows)? + "\n")?;
    }
    Ok(())
}
