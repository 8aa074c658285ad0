//! `smile`: train SAC experts, record demonstrations and benchmark the learner.
//!
//! Thread layout: the learner runs candle single-threaded (`--threads`, default 1); see
//! `trainer::threads` for why.

use anyhow::Result;
use clap::{Parser, Subcommand};

mod cli_bench;

#[derive(Parser, Debug)]
#[command(
    name = "smile",
    version,
    about = "SMILe trainer: SAC experts, demos, benchmarks"
)]
struct Cli {
    /// Threads for candle's matmul (1 is fastest on 2 vCPUs shared with rollouts).
    #[arg(long, global = true, default_value_t = 1)]
    threads: usize,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Time SAC updates (batch 256, obs 20 + z 16, act 6) at several hidden widths.
    #[command(
        after_help = "Examples:\n  smile bench\n  smile bench --hidden 64 256 --iters 500 --json bench.json"
    )]
    Bench(cli_bench::BenchArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    trainer::threads::set_compute_threads(cli.threads);
    match cli.cmd {
        Cmd::Bench(a) => cli_bench::run(a),
    }
}
