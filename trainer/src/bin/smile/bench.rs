//! `smile bench`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use trainer::bench::{
    DiscBenchShape, SacBenchShape, Timing, bench_disc_step, bench_sac_update, bench_smile_pairs,
};

/// What `smile bench` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Workload {
    /// One SAC update (torch_reference.py `sac`: batch 256, obs 20 + z 16, act 6).
    Sac,
    /// One context-encoder + discriminator update (torch_reference.py `disc`).
    Disc,
    /// Whole SMILe iterations on point-goal demos (smile_proto.py's layout: 4 rollouts, then
    /// 100 pairs; 8 tasks x 64 expert + 64 policy rows, 8 x 32 SAC rows; gradient penalty 1).
    Pair,
}

/// Arguments of `smile bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Workloads to time.
    #[arg(long, value_enum, num_args = 1.., default_values_t = [Workload::Sac])]
    workload: Vec<Workload>,
    /// Hidden widths to time (for `pair`: the discriminator's and SAC's).
    #[arg(long, num_args = 1.., default_values_t = [64usize, 128, 256])]
    hidden: Vec<usize>,
    /// Timed iterations per width (for `pair`: whole SMILe iterations, default 20).
    #[arg(long)]
    iters: Option<usize>,
    /// Untimed warm-up iterations per width (for `pair`: default 2).
    #[arg(long)]
    warmup: Option<usize>,
    /// Demos for `pair` (meta-train point-goal demos).
    #[arg(
        long,
        default_value = "assets/experts/point-goal/demos-train-4x-sub20.safetensors"
    )]
    demos: PathBuf,
    /// For `pair`: SMILe's `learner_threads` (2 overlaps the discriminator and SAC steps of
    /// each pair on two threads).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    learner_threads: u8,
    /// Also write the results as one JSON array to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn row(h: usize, t: &Timing) -> String {
    format!(
        "{h:>5} {:>12.1} {:>10.1} {:>10.1} {:>10.1} {:>12}",
        t.median_us,
        t.p10_us,
        t.p90_us,
        t.updates_per_s,
        t.cpu_mean_us.map_or("n/a".into(), |c| format!("{c:.1}"))
    )
}

/// Run the benchmarks and print a table per workload.
pub fn run(a: BenchArgs) -> Result<()> {
    let threads = trainer::threads::compute_threads();
    let header = format!(
        "{:>5} {:>12} {:>10} {:>10} {:>10} {:>12}",
        "H", "median_us", "p10_us", "p90_us", "upd/s", "cpu_mean_us"
    );
    let mut rows = Vec::new();
    for &w in &a.workload {
        match w {
            Workload::Sac => {
                println!("sac update, batch 256, obs 20 + z 16, act 6, candle threads {threads}");
                println!("{header}");
                for &h in &a.hidden {
                    let t = bench_sac_update(
                        SacBenchShape::reference(h),
                        a.warmup.unwrap_or(20),
                        a.iters.unwrap_or(200),
                    )?;
                    println!("{}", row(h, &t));
                    rows.push(serde_json::json!({"workload": "sac", "H": h, "threads": threads, "timing": t}));
                }
            }
            Workload::Disc => {
                println!(
                    "disc + encoder update, 8 tasks x 4 x 16 context steps, 128 + 128 rows per task, obs 20, act 6, r 32, z 16, gp 10, candle threads {threads}"
                );
                println!("{header}");
                for &h in &a.hidden {
                    let shape = DiscBenchShape::reference(h);
                    let t = bench_disc_step(shape, a.warmup.unwrap_or(20), a.iters.unwrap_or(200))?;
                    println!("{}", row(h, &t));
                    rows.push(serde_json::json!({"workload": "disc", "H": h, "threads": threads, "shape": shape, "timing": t}));
                }
            }
            Workload::Pair => {
                let demos = sim::DemoDataset::read(&a.demos)
                    .with_context(|| format!("reading the demos {}", a.demos.display()))?;
                println!(
                    "SMILe iterations on {} ({}): 4 rollouts + 100 pairs, candle threads {threads}, \
                     learner threads {}",
                    demos.family,
                    a.demos.display(),
                    a.learner_threads
                );
                println!(
                    "{:>5} {:>14} {:>22} {:>10}",
                    "H", "per_pair_us", "updates_only_per_pair", "pairs/s"
                );
                for &h in &a.hidden {
                    let mut cfg = trainer::smile::SmileConfig {
                        env: demos.family,
                        rollouts_per_iter: 4,
                        updates_per_iter: 100,
                        sac_per_task: 32,
                        disc_hidden: vec![h, h],
                        learner_threads: a.learner_threads.into(),
                        ..Default::default()
                    };
                    cfg.sac.hidden = vec![h, h];
                    let t = bench_smile_pairs(
                        cfg,
                        &demos,
                        a.warmup.unwrap_or(2),
                        a.iters.unwrap_or(20),
                    )?;
                    println!(
                        "{h:>5} {:>14.1} {:>22.1} {:>10.1}",
                        t.per_pair_us, t.updates_only_per_pair_us, t.pairs_per_s
                    );
                    rows.push(serde_json::json!({"workload": "pair", "H": h, "threads": threads, "learner_threads": a.learner_threads, "timing": t}));
                }
            }
        }
    }
    if let Some(p) = a.json {
        std::fs::write(&p, serde_json::to_string_pretty(&rows)? + "\n")?;
    }
    Ok(())
}
