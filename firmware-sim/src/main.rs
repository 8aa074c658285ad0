//! `firmware-sim`: run a policy blob on the simulated device against a sim plant.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use firmware_sim::link::{LinkConfig, SimLink};
use firmware_sim::{Controller, Device, DeviceConfig, LoopConfig, host, ram_needed, run, trace};
use infer_core::Model;
use sim::{DemoDataset, EnvConfig, Family, Task, make_env};

#[derive(Parser, Debug)]
#[command(
    name = "firmware-sim",
    version,
    about = "Run a SMILe policy blob on a simulated microcontroller"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Flash a blob over the simulated link, teach it a demo, and run the control loop.
    #[command(after_help = "Examples:\n  \
        firmware-sim run --blob runs/quickstart/policy.blob --env point-goal --task 3 --context runs/quickstart/demos-test.safetensors\n  \
        firmware-sim run --blob policy.blob --env cheetah-vel --task param=1.25 --context extra.safetensors --rate 10 --noise 0.01 --adc-bits 12 --latency\n\n\
        --task N picks test task N; --task param=VALUE names a task by its parameter (goal angle in rad,\n\
        target velocity in m/s, dynamics seed), which must have a demo in the --context file.")]
    Run(RunArgs),
}

#[derive(Args, Debug)]
struct RunArgs {
    /// The policy blob (from `smile export`).
    #[arg(long)]
    blob: PathBuf,
    /// Task family of the plant.
    #[arg(long)]
    env: Family,
    /// Test-split index, or `param=VALUE` for an explicit task parameter.
    #[arg(long)]
    task: String,
    /// Demo dataset holding the context demo(s) for that task.
    #[arg(long)]
    context: PathBuf,
    /// Context trajectories to teach (taken in file order).
    #[arg(long, default_value_t = 1)]
    trajectories: usize,
    /// Control rate in Hz (default: the plant's own, 1 / control dt).
    #[arg(long)]
    rate: Option<f32>,
    /// Ticks to run (default: one plant episode).
    #[arg(long)]
    ticks: Option<usize>,
    /// Plant episode length in plant steps (default: the family's).
    #[arg(long)]
    horizon: Option<usize>,
    /// Std of Gaussian sensor noise.
    #[arg(long, default_value_t = 0.0)]
    noise: f32,
    /// ADC resolution in bits (ideal sensors when absent).
    #[arg(long)]
    adc_bits: Option<u8>,
    /// ADC full scale (+-).
    #[arg(long, default_value_t = 10.0)]
    adc_range: f32,
    /// Apply each action one tick late.
    #[arg(long)]
    latency: bool,
    /// Compute budget per tick, microseconds; late actions are dropped and the last one held.
    #[arg(long, default_value_t = 1000.0)]
    budget_us: f64,
    /// Seed of the plant reset and sensor noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Flash budget for the blob, KiB.
    #[arg(long, default_value_t = 64)]
    flash_kib: usize,
    /// RAM budget for the application, KiB.
    #[arg(long, default_value_t = 16)]
    ram_kib: usize,
    /// Probability that a link frame is corrupted.
    #[arg(long, default_value_t = 0.0)]
    link_corrupt: f64,
    /// Probability that a link frame is lost.
    #[arg(long, default_value_t = 0.0)]
    link_drop: f64,
    /// Output directory for trace.csv, plot.svg and summary.txt.
    #[arg(long, short, default_value = "runs/firmware")]
    out: PathBuf,
}

fn parse_task(family: Family, spec: &str) -> Result<Task> {
    if let Some(value) = spec.strip_prefix("param=") {
        let value: f64 = value
            .parse()
            .with_context(|| format!("--task {spec}: not a number"))?;
        return Ok(family.task_from_value(value)?);
    }
    let tasks = family.test_tasks();
    let index: usize = spec
        .parse()
        .with_context(|| format!("--task {spec}: expected a test index or param=VALUE"))?;
    tasks.get(index).copied().with_context(|| {
        format!(
            "--task {index}: {family} has {} test tasks (0..{}); use param=VALUE for others",
            tasks.len(),
            tasks.len()
        )
    })
}

fn run_cmd(args: RunArgs) -> Result<()> {
    let task = parse_task(args.env, &args.task)?;
    let blob =
        std::fs::read(&args.blob).with_context(|| format!("reading {}", args.blob.display()))?;
    let demos = DemoDataset::read(&args.context)
        .with_context(|| format!("reading {}", args.context.display()))?;
    demos.ensure_family(args.env)?;
    let Some(task_demos) = demos.tasks.iter().find(|t| t.task == task) else {
        let available: Vec<String> = demos.tasks.iter().map(|t| t.task.label()).collect();
        bail!(
            "{} has no demo for {}; it has: {}",
            args.context.display(),
            task.label(),
            available.join(", ")
        );
    };
    let context: Vec<_> = task_demos
        .trajectories
        .iter()
        .take(args.trajectories.max(1))
        .collect();

    let config = DeviceConfig {
        flash_bytes: args.flash_kib * 1024,
        ram_bytes: args.ram_kib * 1024,
    };
    let mut device = Device::new(config);
    let link_config = LinkConfig {
        corrupt_probability: args.link_corrupt,
        drop_probability: args.link_drop,
        seed: args.seed,
        ..LinkConfig::default()
    };
    let mut link = SimLink::new(link_config);
    host::upload_blob(&mut link, &mut device, &blob).context("flashing the blob")?;
    let model = Model::from_bytes(device.blob()?).map_err(firmware_sim::DeviceError::from)?;
    let h = *model.header();
    if h.obs_dim as usize != args.env.obs_dim() || h.act_dim as usize != args.env.act_dim() {
        bail!(
            "blob is for obs {} / act {}, but {} has obs {} / act {}",
            h.obs_dim,
            h.act_dim,
            args.env,
            args.env.obs_dim(),
            args.env.act_dim()
        );
    }
    let mut controller = Controller::new(&model, config)?;
    host::teach(
        &mut link,
        &mut controller,
        &context,
        demos.obs_dim,
        demos.act_dim,
    )
    .context("teaching the context demo")?;
    let z = controller.z().map(<[f32]>::to_vec).unwrap_or_default();

    let mut plant = make_env(
        args.env,
        EnvConfig {
            horizon: args.horizon,
            ..EnvConfig::default()
        },
    )?;
    let loop_config = LoopConfig {
        rate_hz: args.rate,
        ticks: args.ticks,
        noise_std: args.noise,
        adc_bits: args.adc_bits,
        adc_range: args.adc_range,
        latency: args.latency,
        budget_us: args.budget_us,
        seed: args.seed,
        nan_ticks: Vec::new(),
    };
    let report = run(&mut controller, plant.as_mut(), &task, &loop_config)?;

    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    trace::write_csv(&args.out.join("trace.csv"), &report, &z)?;
    trace::write_plot(&args.out.join("plot.svg"), &report)
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    let summary = format!(
        "{}\nlink            {} frames, {} corrupted, {} dropped, {} retries\nz               {:?}\n",
        trace::summary(
            &report,
            blob.len(),
            config.flash_bytes,
            ram_needed(),
            config.ram_bytes
        ),
        link.stats.frames,
        link.stats.corrupted,
        link.stats.dropped,
        link.stats.retries,
        z,
    );
    firmware_sim::write_atomic(&args.out.join("summary.txt"), summary.as_bytes())?;
    print!("{summary}");
    println!(
        "wrote {}/{{trace.csv, plot.svg, summary.txt}}",
        args.out.display()
    );
    Ok(())
}

fn main() -> Result<()> {
    match Cli::parse().cmd {
        Cmd::Run(args) => run_cmd(args),
    }
}
