//! `firmware-sim`: run a policy blob on the simulated device against a sim plant.

mod hil;

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use firmware_sim::link::LinkConfig;
use firmware_sim::{DeviceConfig, LoopConfig, SessionConfig, ram_needed, run_session, trace};
use serde::Serialize;
use sim::{DemoDataset, EnvConfig, ExportReport, Family, Task, TaskDemos};

/// Run a SMILe policy blob on a simulated microcontroller
#[derive(Parser, Debug)]
#[command(version)]
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
    /// Run the tasks of a `smile export` report on the device and compare the metric with the
    /// float policy's on the host.
    #[command(after_help = "Example:\n  \
        smile export --policy runs/pg-smile --quant w8a8 --demos demos/pg-train.safetensors --contexts demos/pg-test.safetensors -o runs/pg-smile/policy.blob\n  \
        firmware-sim compare --blob runs/pg-smile/policy.blob --env point-goal --contexts demos/pg-test.safetensors")]
    Compare(CompareArgs),
    /// Be the device: serve the bootloader and the controller on a serial port (or a new
    /// pseudo-terminal) until killed, as a board does. The wire protocol is docs/PROTOCOL.md.
    #[command(after_help = "Examples:\n  \
        firmware-sim device --pty /tmp/smile-tty                 # a virtual board; the host opens /tmp/smile-tty\n  \
        firmware-sim device --port /dev/ttyUSB0 --baud 115200    # behind a USB-serial adapter")]
    Device(hil::DeviceArgs),
    /// Drive a device on a serial port: upload the blob, teach the demo, then run the plant on
    /// this host in real time, one tick message and one action per tick.
    #[command(after_help = "Example (two terminals):\n  \
        firmware-sim device --pty /tmp/smile-tty\n  \
        firmware-sim host --port /tmp/smile-tty --blob assets/policies/cheetah-vel-rapier-smile-bc/policy.blob --env cheetah-vel --task 3 --context assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors")]
    Host(hil::HostArgs),
}

/// The longest plant episode a run takes, in plant steps: a day of a 1 kHz plant. A run's trace
/// holds every tick, so a larger horizon could not finish (or allocate) anyway.
const MAX_HORIZON: usize = 86_400_000;

/// A count of at least 1 and at most [`MAX_HORIZON`] (`--horizon`).
fn positive_count(text: &str) -> std::result::Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("0: expected a count of at least 1".into()),
        Ok(n) if n > MAX_HORIZON => Err(format!("{n}: at most {MAX_HORIZON} plant steps")),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("`{text}` is not a count: {e}")),
    }
}

/// A finite number > 0 (`--adc-range`).
fn positive_finite(text: &str) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(v) => Err(format!("{v}: expected a finite number > 0")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// A line rate (`--baud`): 0 (unpaced) or 1200 to 12,000,000 baud. Below 1200 a 64 KiB
/// blob's upload alone takes over 9 minutes, and one tick's frames outlast any control rate;
/// above 12 Mbaud no USB-serial adapter goes.
pub(crate) fn baud_rate(text: &str) -> std::result::Result<u32, String> {
    const RANGE: std::ops::RangeInclusive<u32> = 1200..=12_000_000;
    match text.parse::<u32>() {
        Ok(v) if v == 0 || RANGE.contains(&v) => Ok(v),
        Ok(v) => Err(format!(
            "{v}: expected 0 (unpaced) or {} to {} baud",
            RANGE.start(),
            RANGE.end()
        )),
        Err(e) => Err(format!("`{text}` is not a whole number: {e}")),
    }
}

/// How much faster than real time a host runs its plant (`--speedup`): 0.01 to 1000 (a tick
/// every 1 / (rate x speedup) s; below 0.01 an 80 Hz loop waits over a second a tick).
pub(crate) fn speedup_factor(text: &str) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if (0.01..=1000.0).contains(&v) => Ok(v),
        Ok(v) => Err(format!("{v}: expected 0.01 to 1000")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// A share from 0 to 1 (`--max-held-safe`).
pub(crate) fn fraction(text: &str) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        Ok(v) => Err(format!("{v}: expected 0 to 1")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// A finite number >= 0 (`--budget-us`).
fn non_negative_finite(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Ok(v) => Err(format!("{v}: expected a finite number >= 0")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// A probability in [0, 1] (`--link-drop`, `--link-corrupt`).
fn probability(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        Ok(v) => Err(format!("{v}: expected a probability from 0 to 1")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

#[derive(Args, Debug)]
struct PlantArgs {
    /// The policy blob (from `smile export`).
    #[arg(long)]
    blob: PathBuf,
    /// Task family of the plant: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass.
    #[arg(long)]
    env: Family,
    /// Physics of the plant, rapier or mujoco (a `--features mujoco` build) [default: the
    /// blob's export report's (`<blob>.json`), else rapier]. Context demos of another plant
    /// are refused.
    #[arg(long)]
    physics: Option<sim::Physics>,
    /// Test-split index, or `param=VALUE` for an explicit task parameter.
    #[arg(long)]
    task: String,
    /// Demo dataset holding the context demo(s) for that task.
    #[arg(long)]
    context: PathBuf,
    /// Context trajectories to teach (taken in file order), at least 1.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    trajectories: u64,
    /// Control rate in Hz, finite and > 0 (default: the plant's own, 1 / control dt).
    #[arg(long, value_parser = positive_finite)]
    rate: Option<f32>,
    /// Ticks to run, 1 to one plant episode (default: one plant episode).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    ticks: Option<u64>,
    /// Plant episode length in plant steps, at least 1 (default: the family's).
    #[arg(long, value_parser = positive_count)]
    horizon: Option<usize>,
    /// Std of Gaussian sensor noise.
    #[arg(long, default_value_t = 0.0)]
    noise: f32,
    /// ADC resolution in bits, 1 to 24 (ideal sensors when absent).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=24))]
    adc_bits: Option<u8>,
    /// ADC full scale (+-), finite and > 0.
    #[arg(long, default_value_t = 10.0, value_parser = positive_finite)]
    adc_range: f32,
    /// Apply each action one tick late.
    #[arg(long)]
    latency: bool,
    /// Seed of the plant reset and sensor noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Probability that a link frame is corrupted, 0 to 1.
    #[arg(long, default_value_t = 0.0, value_parser = probability)]
    link_corrupt: f64,
    /// Probability that a link frame is lost, 0 to 1.
    #[arg(long, default_value_t = 0.0, value_parser = probability)]
    link_drop: f64,
    /// Output directory for trace.csv, plot.svg and summary.txt.
    #[arg(long, short, default_value = "runs/firmware")]
    out: PathBuf,
}

#[derive(Args, Debug)]
struct RunArgs {
    #[command(flatten)]
    plant: PlantArgs,
    /// Compute budget per tick, microseconds, finite and >= 0; late actions are dropped and
    /// the last one held.
    #[arg(long, default_value_t = 1000.0, value_parser = non_negative_finite)]
    budget_us: f64,
    /// What the sensors deliver: `full` (every observation entry) or `positions` (positions
    /// and angles only; the device estimates the velocities with a Kalman filter per axis).
    #[arg(long, default_value = "full")]
    sensing: firmware_sim::Sensing,
    /// `--sensing positions`: the filter's acceleration std (default: the family's).
    #[arg(long)]
    accel_std: Option<f32>,
    /// `--sensing positions`: the reading noise std the filter assumes (default: from
    /// --noise and --adc-bits).
    #[arg(long)]
    meas_std: Option<f32>,
    /// Flash budget for the blob, KiB, 1 to 16384 (16 MiB, more than a microcontroller has).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u64).range(1..=16384))]
    flash_kib: u64,
    /// RAM budget for the application, KiB, 1 to 16384.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u64).range(1..=16384))]
    ram_kib: u64,
}

/// How `--task` named the task: a test index or a parameter value.
#[derive(Debug, Clone, Copy)]
enum TaskSpec {
    Index(Task),
    Param(f64),
}

fn parse_task(family: Family, spec: &str) -> Result<TaskSpec> {
    if let Some(value) = spec.strip_prefix("param=") {
        let value: f64 = value.parse().map_err(|_| {
            anyhow::anyhow!(
                "--task {spec}: {value:?} is not a number; give the {} of a task in --context",
                family.value_name()
            )
        })?;
        if !value.is_finite() {
            bail!("--task {spec}: not finite");
        }
        return Ok(TaskSpec::Param(value));
    }
    let tasks = family.test_tasks();
    let last = tasks.len() - 1;
    let bad = || {
        anyhow::anyhow!(
            "--task {spec}: {family} has {} test tasks; give an index in 0..={last}, or \
             param=VALUE for a task by its {}",
            tasks.len(),
            family.value_name()
        )
    };
    let index: usize = spec.parse().map_err(|_| bad())?;
    tasks
        .get(index)
        .copied()
        .map(TaskSpec::Index)
        .ok_or_else(bad)
}

fn session_config(args: &RunArgs, physics: sim::Physics) -> SessionConfig {
    let p = &args.plant;
    let mut config = plant_config(p, physics);
    config.device = DeviceConfig {
        flash_bytes: args.flash_kib as usize * 1024,
        ram_bytes: args.ram_kib as usize * 1024,
    };
    config.control.budget_us = args.budget_us;
    config.control.sensing = match args.sensing {
        firmware_sim::Sensing::Full => firmware_sim::Sensing::Full,
        firmware_sim::Sensing::Positions { .. } => firmware_sim::Sensing::Positions {
            accel_std: args.accel_std,
            meas_std: args.meas_std,
        },
    };
    config
}

/// The session settings the plant's flags give (full sensing, the default device).
fn plant_config(p: &PlantArgs, physics: sim::Physics) -> SessionConfig {
    SessionConfig {
        device: DeviceConfig::default(),
        link: LinkConfig {
            corrupt_probability: p.link_corrupt,
            drop_probability: p.link_drop,
            seed: p.seed,
            ..LinkConfig::default()
        },
        control: LoopConfig {
            rate_hz: p.rate,
            ticks: p.ticks.map(|t| t as usize),
            noise_std: p.noise,
            adc_bits: p.adc_bits,
            adc_range: p.adc_range,
            latency: p.latency,
            seed: p.seed,
            ..LoopConfig::default()
        },
        plant: EnvConfig {
            horizon: p.horizon,
            physics,
            ..EnvConfig::default()
        },
    }
}

/// The demos in `demos` (read from `path`, given with `flag`) of the task `value` names, within
/// the family's tolerance (sim's [`Family::find_task`]); errors name the file and the flag and
/// list the file's tasks.
fn demos_of<'d>(
    demos: &'d DemoDataset,
    path: &std::path::Path,
    flag: &str,
    value: f64,
) -> Result<&'d TaskDemos> {
    let index = demos
        .family
        .find_task(value, demos.tasks.iter().map(|t| &t.task))
        .map_err(|e| anyhow::anyhow!("{flag} {}: {e}", path.display()))?;
    let found = &demos.tasks[index];
    if found.trajectories.iter().all(|t| t.is_empty()) {
        bail!(
            "{flag} {}: the demos of {} are empty; record them again with `smile demos`",
            path.display(),
            found.task.label()
        );
    }
    Ok(found)
}

/// The export report that describes `blob` (`report`, else `<blob>.json` beside it), checked
/// against what the blob is flashed to: the one place `run` and `compare` check a blob's
/// provenance. The report must name this very blob (its SHA-256: an interrupted re-export can
/// leave a new blob beside the previous export's report), the family `--env` gives (a blob of
/// another family with the same dimensions would run, meaninglessly) and the plant `--physics`
/// gives, if any. Returns the report (or, without one and not `required`, the warning to print
/// once the other inputs are accepted: nothing can be checked) and the plant to run on.
fn checked_provenance(
    blob_path: &std::path::Path,
    blob: &[u8],
    report: Option<&std::path::Path>,
    required: bool,
    env: Family,
    physics: Option<sim::Physics>,
) -> Result<(std::result::Result<ExportReport, String>, sim::Physics)> {
    let path = report.map_or_else(|| ExportReport::path_beside(blob_path), Into::into);
    if !path.exists() && !required {
        let plant = physics.unwrap_or_default();
        let warning = format!(
            "warning: no export report beside {} ({} is missing): its family and plant cannot \
             be checked; flashing it as {env} on the {plant} plant",
            blob_path.display(),
            path.display(),
        );
        return Ok((Err(warning), plant));
    }
    let rep = ExportReport::read(&path)?;
    match Some(rep.blob_sha256.as_str()).filter(|s| !s.is_empty()) {
        Some(sha) => {
            let here = sim::sha256_hex(blob);
            if sha != here {
                bail!(
                    "{} describes another blob (SHA-256 {}), not {} ({}): run `smile export` \
                     again to write the blob and its report together",
                    path.display(),
                    &sha[..sha.len().min(12)],
                    blob_path.display(),
                    &here[..12]
                );
            }
        }
        None => eprintln!(
            "warning: {} names no blob checksum (written before that field); cannot check it \
             describes {}",
            path.display(),
            blob_path.display()
        ),
    }
    if rep.env != env {
        bail!(
            "{} is a {} policy ({} says so), but --env is {env}; pass --env {} or a {env} blob",
            blob_path.display(),
            rep.env,
            path.display(),
            rep.env
        );
    }
    if let Some(asked) = physics.filter(|p| *p != rep.physics) {
        bail!(
            "--physics {asked}, but {} says the blob was trained on the {} plant",
            path.display(),
            rep.physics
        );
    }
    let plant = rep.physics;
    Ok((Ok(rep), plant))
}

/// Reads a demo file given with `flag`, checking it holds demos of `family` recorded on
/// `physics`.
fn read_demos(
    path: &std::path::Path,
    flag: &str,
    family: Family,
    physics: sim::Physics,
) -> Result<DemoDataset> {
    let demos = DemoDataset::read(path).map_err(|e| match e {
        // Its message names the path already.
        sim::DatasetError::Io { source, .. } => {
            anyhow::anyhow!("{flag} {}: {source}", path.display())
        }
        e => anyhow::anyhow!("{flag} {}: {e}", path.display()),
    })?;
    if demos.family != family {
        bail!(
            "{flag} {} holds {} demos but --env is {family}; give demos of {family} or pass \
             --env {}",
            path.display(),
            demos.family,
            demos.family
        );
    }
    demos
        .ensure_family(family)
        .and_then(|()| demos.ensure_physics(physics))
        .map_err(|e| anyhow::anyhow!("{flag} {}: {e}", path.display()))?;
    Ok(demos)
}

/// What `run` and `host` read and check before the device sees anything.
struct Prepared {
    blob: Vec<u8>,
    physics: sim::Physics,
    /// The warning to print once the run is accepted (no export report to check against).
    provenance: Option<String>,
    demos: DemoDataset,
    task: Task,
    /// Index of the task's demos in `demos`.
    entry: usize,
}

impl Prepared {
    /// The context trajectories to teach.
    fn context(&self, p: &PlantArgs) -> Vec<&sim::Trajectory> {
        self.demos.tasks[self.entry]
            .trajectories
            .iter()
            .take(p.trajectories as usize)
            .collect()
    }
}

fn prepare(p: &PlantArgs) -> Result<Prepared> {
    let spec = parse_task(p.env, &p.task)?;
    let blob = read_blob(&p.blob)?;
    let (provenance, physics) = checked_provenance(&p.blob, &blob, None, false, p.env, p.physics)?;
    let demos = read_demos(&p.context, "--context", p.env, physics)?;
    let value = match spec {
        TaskSpec::Index(task) => task.value(),
        TaskSpec::Param(value) => value,
    };
    let found = demos_of(&demos, &p.context, "--context", value)?;
    let task = found.task;
    let named = match spec {
        TaskSpec::Index(_) => format!("--task {}", p.task),
        TaskSpec::Param(v) => format!("--task param={v}"),
    };
    println!(
        "task            {} ({named}; value {}), demo from {}",
        task.label(),
        task.value(),
        p.context.display()
    );
    let available = found.trajectories.len();
    if p.trajectories as usize > available {
        bail!(
            "--trajectories {}: --context {} holds {available} demo(s) of {}; pass \
             --trajectories 1..={available} or a file with more",
            p.trajectories,
            p.context.display(),
            task.label()
        );
    }
    let entry = demos
        .tasks
        .iter()
        .position(|t| t.task == task)
        .expect("demos_of found it there");
    Ok(Prepared {
        blob,
        physics,
        provenance: provenance.err(),
        demos,
        task,
        entry,
    })
}

fn run_cmd(args: RunArgs) -> Result<()> {
    if args.sensing == firmware_sim::Sensing::Full
        && (args.accel_std.is_some() || args.meas_std.is_some())
    {
        bail!("--accel-std and --meas-std tune the estimator: they need --sensing positions");
    }
    let p = &args.plant;
    let prep = prepare(p)?;
    let (blob, physics, task) = (&prep.blob, prep.physics, prep.task);
    let context = prep.context(p);
    let config = session_config(&args, physics);
    let session = run_session(blob, &task, &context, &config)?;
    // Only now: a blob the device refuses gets that one error, not a warning before it.
    if let Some(warning) = &prep.provenance {
        eprintln!("{warning}");
    }
    let report = &session.report;
    let out = &p.out;
    write_trace(out, report, &session.z)?;
    let summary = format!(
        "{}\nlink            {} frames, {} corrupted, {} dropped, {} retries\nz               {:?}\n",
        trace::summary(
            report,
            blob.len(),
            config.device.flash_bytes,
            ram_needed(),
            config.device.ram_bytes
        ),
        session.link.frames,
        session.link.corrupted,
        session.link.dropped,
        session.link.retries,
        session.z,
    );
    firmware_sim::write_atomic(&out.join("summary.txt"), summary.as_bytes())?;
    print!("{summary}");
    println!(
        "wrote {}/{{trace.csv, plot.svg, summary.txt}}",
        out.display()
    );
    Ok(())
}

/// `trace.csv` and `plot.svg` of a run in `out`.
fn write_trace(out: &std::path::Path, report: &firmware_sim::RunReport, z: &[f32]) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    trace::write_csv(&out.join("trace.csv"), report, z)?;
    trace::write_plot(&out.join("plot.svg"), report).map_err(|e| anyhow::anyhow!("plot: {e}"))
}

/// Reads `--blob` and checks it is a whole, valid policy blob before the link sees it (a
/// truncated file would otherwise be "device refused message N: BadBlob"), and the one shipped
/// where its folder lists checksums.
fn read_blob(path: &std::path::Path) -> Result<Vec<u8>> {
    let blob = std::fs::read(path).with_context(|| format!("reading --blob {}", path.display()))?;
    // A shipped blob (its folder lists its SHA-256) must be the one shipped.
    sim::check_shipped_bytes(path, &blob).with_context(|| format!("--blob {}", path.display()))?;
    if let Err(e) = infer_core::Model::from_bytes(&blob) {
        bail!(
            "--blob {} is not a valid policy blob ({e}); export it again with `smile export`",
            path.display()
        );
    }
    Ok(blob)
}

#[derive(Args, Debug)]
struct CompareArgs {
    /// The policy blob (from `smile export`).
    #[arg(long)]
    blob: PathBuf,
    /// The export's report with the float policy's per-task metric (`smile export` writes
    /// `<blob>.json`; default: that file).
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass.
    #[arg(long)]
    env: Family,
    /// Demos of the reference's tasks (the `--contexts` file given to `smile export`).
    #[arg(long)]
    contexts: PathBuf,
    /// Device episodes per task (context trajectory i % n, reset seed i), at least 1.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..))]
    episodes: u64,
    /// Output directory for compare.json and compare.md.
    #[arg(long, short, default_value = "runs/firmware-compare")]
    out: PathBuf,
}

#[derive(Debug, Serialize)]
struct CompareRow {
    task: String,
    value: f64,
    host_float: f32,
    device_blob: f32,
    difference: f32,
}

#[derive(Debug, Serialize)]
struct CompareReport {
    env: Family,
    metric: String,
    episodes_per_task: usize,
    host_mean: f32,
    device_mean: f32,
    mean_abs_difference: f32,
    relative_difference_of_means: f32,
    tasks: Vec<CompareRow>,
}

fn compare_cmd(args: CompareArgs) -> Result<()> {
    let blob = read_blob(&args.blob)?;
    // The device runs the plant the policy was trained and verified on.
    let (reference, physics) = checked_provenance(
        &args.blob,
        &blob,
        args.reference.as_deref(),
        true,
        args.env,
        None,
    )?;
    let reference = reference.map_err(anyhow::Error::msg)?;
    let demos = read_demos(&args.contexts, "--contexts", args.env, physics)?;
    let config = SessionConfig {
        plant: EnvConfig {
            physics,
            ..EnvConfig::default()
        },
        ..SessionConfig::default()
    };
    let mut rows = Vec::new();
    for entry in &reference.per_task_candle {
        let (value, host) = (entry.value, f64::from(entry.metric));
        let found = demos_of(&demos, &args.contexts, "--contexts", value)?;
        let (task, trajectories) = (found.task, &found.trajectories);
        let episodes = args.episodes as usize;
        let mut metrics = Vec::with_capacity(episodes);
        for i in 0..episodes {
            let context = [&trajectories[i % trajectories.len()]];
            let control = LoopConfig {
                seed: sim::seeds::EVALUATION_SEED + i as u64,
                ..LoopConfig::default()
            };
            let session = run_session(
                &blob,
                &task,
                &context,
                &SessionConfig {
                    control,
                    ..config.clone()
                },
            )?;
            metrics.push(session.report.metric);
        }
        let device = metrics.iter().sum::<f32>() / metrics.len() as f32;
        rows.push(CompareRow {
            task: task.label(),
            value,
            host_float: host as f32,
            device_blob: device,
            difference: device - host as f32,
        });
    }
    let n = rows.len().max(1) as f32;
    let host_mean = rows.iter().map(|r| r.host_float).sum::<f32>() / n;
    let device_mean = rows.iter().map(|r| r.device_blob).sum::<f32>() / n;
    let report = CompareReport {
        env: args.env,
        metric: reference.metric.clone(),
        episodes_per_task: args.episodes as usize,
        host_mean,
        device_mean,
        mean_abs_difference: rows.iter().map(|r| r.difference.abs()).sum::<f32>() / n,
        relative_difference_of_means: (device_mean - host_mean) / host_mean.abs().max(1e-9),
        tasks: rows,
    };
    let mut md =
        String::from("| task | host float | device blob | difference |\n|---|---|---|---|\n");
    for r in &report.tasks {
        md.push_str(&format!(
            "| {} | {:.4} | {:.4} | {:+.4} |\n",
            r.task, r.host_float, r.device_blob, r.difference
        ));
    }
    md.push_str(&format!(
        "| **mean** | **{:.4}** | **{:.4}** | mean abs {:.4}, relative {:+.1}% |\n",
        report.host_mean,
        report.device_mean,
        report.mean_abs_difference,
        100.0 * report.relative_difference_of_means
    ));
    std::fs::create_dir_all(&args.out)?;
    firmware_sim::write_atomic(
        &args.out.join("compare.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    firmware_sim::write_atomic(&args.out.join("compare.md"), md.as_bytes())?;
    print!("{md}");
    println!("wrote {}/{{compare.json, compare.md}}", args.out.display());
    Ok(())
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().cmd {
        Cmd::Run(args) => run_cmd(args),
        Cmd::Compare(args) => compare_cmd(args),
        Cmd::Device(args) => hil::device_cmd(args),
        Cmd::Host(args) => hil::host_cmd(args),
    };
    sim::exit_code(result)
}
