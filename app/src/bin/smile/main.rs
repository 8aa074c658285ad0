//! `smile`: the SMILe trainer's command line: experts, demos, meta-training (SMILe, Meta-BC,
//! Meta-DAgger), evaluation, blob export, the quickstart and benchmarks. One file per
//! subcommand.
//!
//! Thread layout: the learner runs candle single-threaded (`--threads`, default 1); see
//! `trainer::threads` for why.

// The flags' doc comments are clap's help text (`runs/expert-<env>`), not rustdoc HTML.
#![allow(rustdoc::invalid_html_tags)]

use anyhow::Result;
use clap::{Parser, Subcommand};

mod bench;
mod demos;
mod device_table;
mod distill;
mod eval;
mod expert;
mod export;
mod flags;
mod latents;
mod linclass;
mod quickstart;
mod report;
mod sweep;
mod train;

/// SMILe: meta-train a few-shot imitation policy (SMILe, Meta-BC, Meta-DAgger), evaluate it and
/// export it to a no_std device blob
#[derive(Parser, Debug)]
#[command(name = "smile", version)]
struct Cli {
    /// Threads for candle's matmul, 1 to 64 (1 is fastest on 2 vCPUs shared with rollouts).
    #[arg(long, global = true, default_value_t = 1, value_parser = parse_threads)]
    threads: usize,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Train an oracle SAC expert on a family's meta-train tasks (or export the scripted one).
    #[command(
        after_help = "Examples:\n  smile expert --env point-goal --total-steps 30000 -o runs/pg-expert\n  smile expert --env point-goal --kind scripted-pd -o runs/pg-pd\n  smile expert --env cheetah-vel --horizon 1000 --total-steps 600000 --batch-size 128 --hidden 128,128 -o runs/cv-expert\n  smile expert --env walker-dyn --task-value 10003 --hidden 128,128 --batch-size 128 --total-steps 150000 -o runs/wd-expert-10003\n  smile expert --env walker-dyn --nominal -o runs/walker-base\n  smile expert --env walker-dyn --task-value 10003 --init-from runs/walker-base --total-steps 50000 -o runs/wd-10003\n  smile expert --resume runs/pg-expert --total-steps 60000\n  smile expert --config expert.toml --quiet"
    )]
    Expert(expert::ExpertArgs),
    /// Record deterministic expert demonstrations in sim's dataset format.
    #[command(
        after_help = "Examples:\n  smile demos --env point-goal --split train --per-task 4 --subsample 20 --expert runs/pg-expert -o demos/pg-train.safetensors\n  smile demos --env point-goal --task-params 0.1,1.7 --per-task 1 --expert runs/pg-pd -o demos/pg-extra.safetensors"
    )]
    Demos(demos::DemosArgs),
    /// Time SAC updates (batch 256, obs 20 + z 16, act 6) at several hidden widths.
    #[command(
        after_help = "Examples:\n  smile bench\n  smile bench --hidden 64 256 --iters 500 --json bench.json"
    )]
    Bench(bench::BenchArgs),
    /// Meta-train SMILe (state-action or state-only), Meta-BC or Meta-DAgger on meta-train demos.
    #[command(
        after_help = "Examples:\n  smile train --algo smile --env point-goal --demos demos/pg-train.safetensors -o runs/pg-smile\n  smile train --algo meta-bc --env point-goal --demos demos/pg-train.safetensors -o runs/pg-bc\n  smile train --algo smile -o runs/pg-smile --demos demos/pg-train.safetensors --resume --updates 30000"
    )]
    Train(train::TrainArgs),
    /// Evaluate trained meta-policies on a split's tasks with the paper's protocol.
    #[command(
        after_help = "Examples:\n  smile eval --policy runs/pg-smile runs/pg-bc --env point-goal --split test --contexts demos/pg-test.safetensors -o runs/pg-eval\n  smile eval --policy runs/pg-smile --contexts demos/pg-test.safetensors --render\n  smile eval --policy runs/wd-smile --env walker-dyn --contexts demos/wd-test.safetensors --base runs/walker-base --expert runs/walker-expert -o runs/wd-eval"
    )]
    Eval(eval::EvalArgs),
    /// Export a meta-policy as an infer-core blob and verify it (parity + metric).
    #[command(
        after_help = "Examples:\n  smile export --policy runs/pg-smile --quant w8a8 --demos demos/pg-train.safetensors --contexts demos/pg-test.safetensors -o runs/pg-smile/policy.blob\n  smile export --policy runs/pg-smile --format onnx --contexts demos/pg-test.safetensors -o runs/pg-smile/onnx"
    )]
    Export(export::ExportArgs),
    /// Distil a trained meta-policy to act through the device's senses (noise and ADC, or
    /// position-only sensing and its estimator), taught by itself on true states.
    #[command(
        after_help = "Examples:\n  smile distill --policy assets/policies/cheetah-vel-rapier-smile-bc --demos assets/experts/cheetah-vel/demos-train-4x-sub20.safetensors --sensing docs/configs/sensing-positions.toml --horizon 1000 -o runs/cv-distilled"
    )]
    Distill(distill::DistillArgs),
    /// The whole pipeline on point-goal: expert, demos, SMILe + Meta-BC, eval, blob, device.
    #[command(
        after_help = "Examples:\n  smile quickstart\n  smile quickstart --out runs/qs-seed1 --seed 1\n  smile quickstart --budget tiny --quiet"
    )]
    Quickstart(quickstart::QuickstartArgs),
    /// Run a grid of trainings + evaluations from a plan: every core, or a Slurm array.
    #[command(
        after_help = "Examples:\n  smile sweep docs/plans/point-goal-3seeds.toml\n  smile sweep plan.toml --jobs 2 --dry-run\n  smile sweep plan.toml --slurm --submit\n  smile sweep run-cell plan.toml --index 3"
    )]
    Sweep(sweep::SweepArgs),
    /// Aggregate evaluations of sweeps or runs: mean +- std over seeds, markdown, JSON, plots.
    #[command(
        after_help = "Examples:\n  smile report runs/point-goal-3seeds -o runs/point-goal-3seeds/report\n  smile report runs/h6/eval-s0 runs/h6/eval-s1 runs/h6/eval-s2"
    )]
    Report(report::ReportArgs),
    /// The encoder's z for every task's contexts (CSV) and a linear probe of the task from z.
    #[command(
        after_help = "Examples:\n  smile latents --policy runs/wd-smile --env walker-dyn --contexts assets/experts/walker-dyn/demos-test-4x-sub20.safetensors -o runs/wd-smile/latents.csv\n  smile latents --policy runs/alc-smile --env ant-linclass --contexts assets/experts/ant-linclass/demos-test-16x-sub5.safetensors --context-sizes 1,2,4,8 -o z.csv"
    )]
    Latents(latents::LatentsArgs),
    /// ant-linclass diagnosed: what the context demos show and the best accuracy they allow,
    /// what each policy's z carries about the hyperplane, and when its episodes commit.
    #[command(
        name = "linclass-diagnose",
        after_help = "Examples:\n  smile linclass-diagnose --contexts assets/experts/ant-linclass/demos-test-16x-sub5.safetensors --train-demos assets/experts/ant-linclass/demos-train-16x-sub5.safetensors --policy meta-bc=assets/policies/ant-linclass-rapier-meta-bc -o runs/alc-diagnosis"
    )]
    LinclassDiagnose(linclass::LinclassArgs),
    /// Shipped meta-policies from float to int8 to the device loop: the deployment table.
    #[command(
        after_help = "Examples:\n  smile device-table assets/policies/* -o runs/device-table\n  smile device-table assets/policies/cheetah-vel-rapier-smile-bc --draws 3 --rollouts 2\n  smile device-table assets/policies/point-goal-rapier-smile --new-tasks demos/pg-new-goals.safetensors"
    )]
    DeviceTable(device_table::DeviceTableArgs),
}

/// Most `--threads`: each is a candle worker; far more than cores only thrashes (1000 made a
/// 0.5 s run take over a minute).
const MAX_THREADS: usize = 64;

fn parse_threads(text: &str) -> std::result::Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if (1..=MAX_THREADS).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{text}`: expected a thread count from 1 to {MAX_THREADS}"
        )),
    }
}

/// A count that must be at least 1 (`--rollouts`, `--horizon`, `--draws`, ...).
pub(crate) fn positive(text: &str) -> std::result::Result<usize, String> {
    count_up_to(text, trainer::MAX_COUNT as usize)
}

/// An episode length, 1 to `trainer::MAX_HORIZON` plant steps (`--horizon`).
pub(crate) fn horizon(text: &str) -> std::result::Result<usize, String> {
    count_up_to(text, trainer::MAX_HORIZON)
}

/// A whole number from 1 to `max` (0 would do nothing; beyond `max` no run finishes).
fn count_up_to(text: &str, max: usize) -> std::result::Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        Ok(0) => Err("expected at least 1 (0 would do nothing)".into()),
        Ok(n) => Err(format!("{n}: at most {max}")),
        Err(e) => Err(format!("`{text}` is not a whole number: {e}")),
    }
}

/// A finite number of at least `min` (a learning rate, a weight, a scale), for `flag`.
pub(crate) fn finite_at_least(text: &str, min: f32) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= min => Ok(v),
        Ok(v) => Err(format!("{v}: expected a finite number >= {min}")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// The widest hidden layer a flag may ask for: 16384 units (a 16384 x 16384 layer is already
/// 1 GiB of weights; a wider one could only end in an allocation abort).
const MAX_WIDTH: usize = 16_384;

/// One hidden width, 1 to [`MAX_WIDTH`] (`--hidden 128,128`).
pub(crate) fn width(text: &str) -> std::result::Result<usize, String> {
    match text.parse::<usize>() {
        Ok(w) if (1..=MAX_WIDTH).contains(&w) => Ok(w),
        Ok(w) => Err(format!("{w}: a hidden width is 1 to {MAX_WIDTH}")),
        Err(e) => Err(format!("`{text}` is not a width: {e}")),
    }
}

fn main() -> std::process::ExitCode {
    sim::exit_code(run().map_err(flags::render))
}

fn run() -> Result<()> {
    let cli = Cli::parse();
    trainer::threads::keep_freed_memory();
    trainer::threads::set_compute_threads(cli.threads);
    match cli.cmd {
        Cmd::Bench(a) => bench::run(a),
        Cmd::Expert(a) => expert::run(a),
        Cmd::Demos(a) => demos::run(a),
        Cmd::Train(a) => train::run(a),
        Cmd::Eval(a) => eval::run(a),
        Cmd::Export(a) => export::run(a),
        Cmd::Distill(a) => distill::run(a),
        Cmd::Quickstart(a) => quickstart::run(a),
        Cmd::Sweep(a) => sweep::run(a),
        Cmd::Report(a) => report::run(a),
        Cmd::Latents(a) => latents::run(a),
        Cmd::LinclassDiagnose(a) => linclass::run(a),
        Cmd::DeviceTable(a) => device_table::run(a),
    }
}
