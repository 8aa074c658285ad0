//! The whole pipeline in one call (`smile quickstart`), on the fast family by default.
//!
//! expert -> demos (train, test) -> SMILe and Meta-BC -> evaluation on the held-out test tasks
//! -> w8a8 blob with its parity check -> a firmware-sim device run of the blob, taught one
//! test demo. Everything lands in one run directory with a `report.md`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::ValueEnum;
use serde::{Deserialize, Serialize};
use sim::{DemoDataset, EnvConfig, Family, Split};

use crate::progress::bar;
use indicatif::MultiProgress;
use trainer::MetaPolicy;
use trainer::eval::{self, EvalReport, MethodResult, Protocol};
use trainer::expert::{self, Expert};
use trainer::expert::{DemoSpec, record};
use trainer::export::{self, BlobActor};
use trainer::meta_bc::MetaBcConfig;
use trainer::run::{ExpertRequest, RunEvent, TrainRequest};
use trainer::smile::SmileConfig;
use trainer::{Algo, Progress};
use trainer::{Error, Result};

mod device;
mod recipe;
mod report;

use recipe::{ExpertSource, Preset, Recipe, recipe};
pub use report::Summary;
use report::report_markdown;

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn device_err<E: std::fmt::Display>(e: E) -> Error {
    Error::Device(e.to_string())
}

fn write(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    firmware_sim::write_atomic(path, bytes.as_ref()).map_err(io(path))
}

fn json<T: Serialize>(value: &T) -> Result<String> {
    serde_json::to_string_pretty(value).map_err(|e| Error::Serialise {
        what: "JSON report",
        reason: e.to_string(),
    })
}

/// How much compute the quickstart spends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Budget {
    /// Seconds (2-15 s on 2 cores): tiny nets and a few hundred updates. Proves the plumbing,
    /// not the learning.
    Tiny,
    /// The default: about 2 minutes on 2 cores for point-goal (docs/BENCHMARKS.md).
    Short,
    /// Longer training (point-goal: 2x the updates); required for the slow families.
    Long,
}

/// What `smile quickstart` runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QuickstartConfig {
    /// Task family (point-goal is the fast one; the others need an SAC expert and hours).
    #[serde(with = "family_name")]
    pub env: Family,
    /// Run directory. Default `runs/quickstart`.
    pub out: PathBuf,
    /// Seed of the whole pipeline. Default 0.
    pub seed: u64,
    /// Compute budget. Default short.
    pub budget: Budget,
    /// Demos per meta-train task. Default 4 (the paper's smallest budget).
    pub demos_per_task: usize,
    /// Subsampling factor of the demos. Default 20 (the paper's low-data regime).
    pub subsample: usize,
    /// No progress bars.
    pub quiet: bool,
    /// Directory of shipped experts and demos (`assets/experts` of the repository, used when
    /// `None` and present): cheetah-vel then starts from `assets/experts/cheetah-vel` instead
    /// of training an expert. Default None.
    #[serde(default)]
    pub assets: Option<PathBuf>,
    /// What the device senses: the full observation, or positions only with its on-device
    /// velocity estimator (firmware-sim's `--sensing positions`). Default full.
    #[serde(default)]
    pub sensing: DeviceSensing,
}

/// The quickstart device stage's sensing (firmware-sim's [`firmware_sim::Sensing`] with the
/// family's default filter tuning).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeviceSensing {
    /// Every observation entry, as measured.
    #[default]
    Full,
    /// Positions and angles only; the device estimates the velocities (Kalman filter).
    Positions,
}

mod family_name {
    use serde::{Deserialize, Deserializer, Serializer};
    use sim::Family;

    pub fn serialize<S: Serializer>(f: &Family, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(f.name())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Family, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

impl Default for QuickstartConfig {
    fn default() -> Self {
        Self {
            env: Family::default(),
            out: PathBuf::from("runs/quickstart"),
            seed: 0,
            budget: Budget::Short,
            demos_per_task: 4,
            subsample: 20,
            quiet: false,
            assets: None,
            sensing: DeviceSensing::Full,
        }
    }
}

fn stage(n: usize, what: &str) {
    eprintln!("\n[{n}/6] {what}");
}

/// A quickstart's arguments with what they resolve to, decided once: the family's recipe and
/// the shipped assets it starts from, hence its episode length and its training presets.
pub(crate) struct Quickstart<'a> {
    args: &'a QuickstartConfig,
    /// The family's choices ([`recipe`]).
    recipe: Recipe,
    /// The shipped expert and demos of the family (`assets/experts/<family>/`), used by every
    /// budget but `tiny` on the families without a scripted expert.
    shipped: Option<PathBuf>,
}

impl std::ops::Deref for Quickstart<'_> {
    type Target = QuickstartConfig;

    fn deref(&self) -> &QuickstartConfig {
        self.args
    }
}

impl<'a> Quickstart<'a> {
    /// Looks for the shipped assets once.
    pub(crate) fn resolve(args: &'a QuickstartConfig) -> Result<Self> {
        let recipe = recipe(args.env).ok_or_else(|| {
            Error::Usage(format!(
                "the quickstart runs the paper's families, not {}: train a family of your own \
                 through the library (GUIDE.md, \"Your own task family\")",
                args.env
            ))
        })?;
        let shipped = (recipe.expert != ExpertSource::Scripted && args.budget != Budget::Tiny)
            .then(|| {
                let root = args.assets.clone().unwrap_or_else(|| {
                    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts")
                });
                root.join(args.env.name())
            })
            .filter(|dir| {
                let (train, test) = recipe.shipped_demos;
                [trainer::checkpoint::POLICY_FILE, train, test]
                    .iter()
                    .all(|f| dir.join(f).exists())
            });
        Ok(Self {
            args,
            recipe,
            shipped,
        })
    }

    /// The recipe's shorter episode and presets when the quickstart trains its own expert.
    fn own_expert(&self) -> Option<(usize, [Preset; 2])> {
        self.recipe.own_expert.filter(|_| self.shipped.is_none())
    }

    /// Episode length: the family's own (cheetah-vel: the paper's 1000 steps) with shipped
    /// assets; without them the recipe's shorter one, if it has one.
    fn horizon(&self) -> Option<usize> {
        self.own_expert().map(|(horizon, _)| horizon)
    }

    /// The (SMILe, Meta-BC) configuration files the quickstart trains with.
    fn presets(&self) -> [Preset; 2] {
        self.own_expert()
            .map_or(self.recipe.presets, |(_, presets)| presets)
    }

    fn env_config(&self) -> EnvConfig {
        EnvConfig {
            horizon: self.horizon(),
            ..EnvConfig::default()
        }
    }
}

/// Refuses, before any work, a budget that cannot do what it promises on this family.
fn check_budget(args: &Quickstart<'_>) -> Result<()> {
    let scripted = args.recipe.expert == ExpertSource::Scripted;
    if !scripted && args.budget == Budget::Short && args.shipped.is_none() {
        return Err(Error::Usage(format!(
            "{0} has no scripted expert and no shipped one (assets/experts/{0}): the quickstart \
             would train an SAC expert (about 1-2 hours on 2 cores) and then SMILe (about 1 \
             hour more). Pass `--budget long` to run all of it, or `--budget tiny` to check the \
             pipeline in about 15 seconds (nothing useful is learned). point-goal is the fast \
             family.",
            args.env
        )));
    }
    if let ExpertSource::ScriptedOver { make } = args.recipe.expert
        && args.budget == Budget::Long
        && args.shipped.is_none()
    {
        return Err(Error::Usage(format!(
            "{0}'s expert is scripted over another family's expert: {make}, or restore \
             assets/experts/{0} (the quickstart's shipped files)",
            args.env
        )));
    }
    Ok(())
}

fn train_expert(args: &Quickstart<'_>, dir: &Path) -> Result<(Expert, String)> {
    if args.recipe.expert == ExpertSource::Scripted {
        expert::export_scripted_pd(dir)?;
        let note =
            "scripted PD controller (point-goal's documented expert; nothing trained)".to_string();
        return Ok((Expert::load(dir)?, note));
    }
    if let Some(assets) = &args.shipped {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        for f in [trainer::checkpoint::POLICY_FILE, "config.toml", "eval.json"] {
            if assets.join(f).exists() {
                std::fs::copy(assets.join(f), dir.join(f)).map_err(io(dir))?;
            }
        }
        let expert = Expert::load(dir)?;
        let note = format!(
            "the shipped {} expert ({}; nothing trained)",
            expert.name(),
            assets.display()
        );
        return Ok((expert, note));
    }
    let mut cfg = expert::ExpertConfig {
        env: args.env,
        horizon: args.horizon(),
        seed: args.seed,
        ..expert::ExpertConfig::default()
    };
    if args.budget == Budget::Tiny {
        (cfg.total_steps, cfg.learning_starts, cfg.eval_episodes) = (400, 200, 1);
        cfg.sac.hidden = vec![32, 32];
    } else {
        // docs/RESULTS.md: this configuration reached mean |v - v*| 0.081 on cheetah-vel.
        (cfg.total_steps, cfg.learning_starts) = (300_000, 5_000);
        cfg.sac.hidden = vec![256, 256];
        cfg.sac.batch_size = 128;
    }
    let pb = bar(cfg.total_steps, args.quiet, "env steps");
    let req = ExpertRequest {
        out: dir.to_path_buf(),
        config: Some(cfg.clone()),
        total_steps: None,
    };
    // The one run driver: the directory's lock, config.toml, checkpoints, as `smile expert`.
    trainer::run::train_expert(&req, &mut |e| match e {
        RunEvent::Progress(Progress::Steps(n), _) => pb.set_position(n),
        RunEvent::Progress(
            Progress::Episode {
                episodic_return, ..
            },
            _,
        ) => pb.set_message(format!("return {episodic_return:.1}")),
        _ => {}
    })?;
    pb.finish();
    let note = format!(
        "SAC expert on the oracle observation, {} env steps",
        cfg.total_steps
    );
    Ok((Expert::load(dir)?, note))
}

fn demos(
    expert: &Expert,
    args: &Quickstart<'_>,
    split: Split,
    per_task: usize,
    path: &Path,
) -> Result<DemoDataset> {
    let seed = args.seed * 1_000_000 + if split == Split::Train { 0 } else { 500_000 };
    let spec = DemoSpec {
        tasks: args.env.tasks(split),
        split,
        per_task,
        subsample: args.subsample,
        seed,
        distinct_starts: false,
        env: args.env_config(),
    };
    let ds = match &args.shipped {
        Some(assets) => {
            let (train, test) = args.recipe.shipped_demos;
            let src = assets.join(if split == Split::Train { train } else { test });
            std::fs::copy(&src, path).map_err(io(path))?;
            eprintln!("  shipped demos {}", src.display());
            DemoDataset::read(path)?
        }
        None => {
            let ds = record(expert, &spec)?;
            ds.write(path)?;
            ds
        }
    };
    eprintln!(
        "  {} tasks x {} demos -> {}",
        ds.tasks.len(),
        ds.trajectory_count() / ds.tasks.len().max(1),
        path.display()
    );
    Ok(ds)
}

/// A learner's preset file over its defaults.
fn preset<C: serde::Serialize + serde::de::DeserializeOwned + Default>(
    (name, text): (&str, &str),
) -> Result<C> {
    trainer::from_toml_over_defaults(text)
        .map_err(|e| Error::Config(format!("the quickstart's preset {name}: {}", e.message())))
}

/// The SMILe configuration the quickstart trains with, per family and budget: its preset
/// under the quickstart's own settings (family, seed, two learner threads; the `tiny`
/// budget's small nets and counts).
fn smile_config(args: &Quickstart<'_>) -> Result<SmileConfig> {
    let mut cfg: SmileConfig = preset(args.presets()[0])?;
    (cfg.env, cfg.seed) = (args.env, args.seed);
    // Two learner threads: the discriminator step beside the SAC step (docs/BENCHMARKS.md
    // "Threads"); Meta-BC shares the cores for its first minute or so.
    cfg.learner_threads = 2;
    match args.budget {
        Budget::Tiny => {
            (cfg.total_updates, cfg.updates_per_iter) = (200, 50);
            (cfg.sac.hidden, cfg.disc_hidden) = (vec![32, 32], vec![32, 32]);
            (cfg.eval_every, cfg.checkpoint_every) = (100, 100);
        }
        Budget::Short => {}
        Budget::Long => cfg.total_updates *= args.recipe.long_updates,
    }
    Ok(cfg)
}

/// The Meta-BC configuration the quickstart trains with, per family and budget.
fn meta_bc_config(args: &Quickstart<'_>) -> Result<MetaBcConfig> {
    let mut cfg: MetaBcConfig = preset(args.presets()[1])?;
    (cfg.env, cfg.seed) = (args.env, args.seed);
    if args.budget == Budget::Tiny {
        (cfg.total_steps, cfg.policy_hidden, cfg.eval_every) = (200, vec![32, 32], 100);
    }
    Ok(cfg)
}

/// Trains one learner of the quickstart in `dir` through the one run driver (as `smile train
/// --config FILE`: the run's lock, `run.json`, `config.toml`, checkpoints), its configuration
/// first written to `dir.toml` beside it and a progress bar under `label`, and loads the policy
/// it kept.
fn train_learner<C: serde::Serialize>(
    (algo, cfg): (Algo, C),
    args: &Quickstart<'_>,
    dir: &Path,
    bars: &MultiProgress,
) -> Result<MetaPolicy> {
    let config_file = dir.with_extension("toml");
    let text = toml::to_string(&cfg).map_err(|e| Error::Serialise {
        what: "a quickstart learner's configuration",
        reason: e.to_string(),
    })?;
    write(&config_file, text)?;
    let req = TrainRequest {
        demos: args.out.join(TRAIN_DEMOS),
        out: dir.to_path_buf(),
        family: Some(args.env),
        algo: Some(algo),
        config_file: Some(config_file),
        ..TrainRequest::default()
    };
    let label = match algo {
        Algo::Smile => "SMILe",
        _ => "Meta-BC",
    };
    let mut pb = None;
    trainer::run::train(&req, &mut |e| match e {
        RunEvent::Started { total, unit, .. } => {
            pb = Some(bars.add(bar(total, args.quiet, &format!("{label} {}", unit.plural))));
        }
        RunEvent::Progress(p, _) => {
            let Some(pb) = &pb else { return };
            match p {
                Progress::Steps(s) => pb.set_position(s),
                Progress::Eval { score: s, .. } => pb.set_message(match s.val_mse {
                    Some(mse) => format!("val mse {mse:.4}, held-out train tasks {:.3}", s.metric),
                    None => format!("held-out train tasks {:.3} (best {:.3})", s.metric, s.best),
                }),
                Progress::Stopped(s) => pb.set_message(format!("early stop at step {s}")),
                Progress::Checkpoint(_) | Progress::Episode { .. } => {}
            }
        }
        RunEvent::Note(_) => {}
    })?;
    if let Some(pb) = pb {
        pb.finish();
    }
    MetaPolicy::load(dir)
}

fn protocol(args: &Quickstart<'_>) -> Protocol {
    let mut p = Protocol::for_family(args.env);
    p.horizon = args.horizon();
    if args.budget == Budget::Tiny {
        p.draws = 1;
        p.rollouts = 1;
    }
    p
}

fn evaluate(
    args: &Quickstart<'_>,
    actor: &mut dyn eval::ConditionedActor,
    name: &str,
    test: &DemoDataset,
) -> Result<MethodResult> {
    let n = args.env.test_tasks().len() as u64;
    let pb = bar(n, args.quiet, "test tasks");
    pb.set_message(name.to_string());
    let r = eval::evaluate(
        actor,
        name,
        args.env,
        Split::Test,
        test,
        &protocol(args),
        &mut |i, _| pb.set_position(i as u64),
    )?;
    pb.finish_and_clear();
    eprintln!(
        "  {name}: {} {:.4} +- {:.4} over test tasks",
        eval::metric_name(args.env.metric_kind()),
        r.mean,
        r.std_over_tasks
    );
    Ok(r)
}

/// The point-goal short budget's wall clock on 2 cores, by what this CPU has: measured at 96 s
/// on a 2-vCPU Intel Xeon with AVX-512 and 392 s on a 2-vCPU AMD EPYC with AVX2 only
/// (2026-12-04, docs/BENCHMARKS.md): the learner's matrix kernels set the pace.
fn short_budget_estimate() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        return "about 2 minutes (this CPU has AVX-512)";
    } else if std::arch::is_x86_feature_detected!("avx2") {
        return "about 6-7 minutes (this CPU has AVX2 but not AVX-512)";
    }
    "2-7 minutes on x86-64 with AVX2 or AVX-512; more without them"
}

/// The meta-train demos' file in the quickstart's directory.
const TRAIN_DEMOS: &str = "demos-train.safetensors";

/// The run directories and configurations of the quickstart's training stages: cleared with
/// the results, so that each quickstart starts its runs afresh.
const STAGE_FILES: [&str; 5] = ["expert", "smile", "meta-bc", "smile.toml", "meta-bc.toml"];

/// What the quickstart's last stages write: a directory holding any of them looks finished.
const RESULT_FILES: [&str; 8] = [
    "summary.json",
    "report.md",
    "eval.json",
    "eval.md",
    "eval.svg",
    "policy.blob",
    "policy.blob.json",
    "device",
];

/// Removes an earlier quickstart's results from `out` (the caller holds its lock), so that a
/// run interrupted before its own are written never sits beside them looking complete.
fn clear_results(out: &Path) -> Result<()> {
    for name in RESULT_FILES.iter().chain(&STAGE_FILES) {
        let path = out.join(name);
        sim::remove_any(&path).map_err(io(&path))?;
    }
    Ok(())
}

/// Runs the whole pipeline; returns what it measured (also in `out/summary.json`).
pub fn run(args: &QuickstartConfig) -> Result<Summary> {
    let start = Instant::now();
    let args = &Quickstart::resolve(args)?;
    let out = &args.out;
    let _lock = prepare(args)?;

    stage(1, "expert");
    let (expert, expert_note) = train_expert(args, &out.join("expert"))?;
    eprintln!("  {expert_note} -> {}", out.join("expert").display());

    stage(2, "demos (meta-train and meta-test splits)");
    let train = demos(
        &expert,
        args,
        Split::Train,
        args.demos_per_task,
        &out.join(TRAIN_DEMOS),
    )?;
    // Three single-trajectory contexts per test task, as the evaluation protocol draws.
    let test = demos(
        &expert,
        args,
        Split::Test,
        3,
        &out.join("demos-test.safetensors"),
    )?;

    stage(
        3,
        "SMILe (state-action) and Meta-BC (early-stopped on held-out train tasks) on the \
         meta-train demos, at the same time",
    );
    let (mut smile_policy, mut bc_policy) = train_both(args)?;

    stage(4, "evaluation on the held-out meta-test tasks");
    let smile_result = evaluate(args, &mut smile_policy, "SMILe", &test)?;
    let bc_result = evaluate(args, &mut bc_policy, "Meta-BC", &test)?;

    stage(
        5,
        "export a w8a8 blob and check it against the float policy",
    );
    let exported = export_blob(args, &smile_policy, &smile_result, &train, &test)?;
    let report = EvalReport::new(
        args.env,
        Split::Test,
        protocol(args),
        vec![smile_result.clone(), bc_result, exported.result.clone()],
    );
    // eval.md, eval.svg and eval.json, as `smile eval` writes them.
    eval::write_report(&report, out)?;

    stage(
        6,
        "firmware-sim: the blob on a simulated device, taught one test demo",
    );
    let device = device::device_run(args, &exported.blob, &test, &out.join("device"))?;

    let (_, median, p99, _) = device.compute_percentiles();
    let summary = Summary {
        env: args.env,
        budget: format!("{:?}", args.budget).to_lowercase(),
        seed: args.seed,
        expert: expert_note,
        eval: report
            .methods
            .iter()
            .map(|m| (m.name.clone(), m.mean, m.std_over_tasks))
            .collect(),
        blob_bytes: exported.blob.len(),
        blob_quant: "w8a8".into(),
        parity: exported.parity,
        blob_metric: exported.result.mean,
        float_metric: smile_result.mean,
        device_task: device.task.label(),
        device_metric: device.metric,
        device_ticks: device.records.len(),
        device_faults: device.faults,
        device_overruns: device.overruns,
        device_median_us: median as f64 / 1e3,
        device_p99_us: p99 as f64 / 1e3,
        seconds: start.elapsed().as_secs_f64(),
    };
    write(&out.join("summary.json"), json(&summary)?)?;
    let md = report_markdown(&summary, &report);
    write(&out.join("report.md"), &md)?;
    if !args.quiet {
        println!("\n{md}");
    }
    eprintln!(
        "done in {:.0} s; everything is in {}",
        summary.seconds,
        out.display()
    );
    Ok(summary)
}

/// Checks the budget, takes the output directory (one quickstart per directory at a time: a
/// second is refused with this one's pid, held by the returned lock), clears an earlier run's
/// results, records the settings and announces the run.
fn prepare(args: &Quickstart<'_>) -> Result<trainer::DirLock> {
    check_budget(args)?;
    let out = &args.out;
    let lock = trainer::DirLock::acquire(out)?;
    clear_results(out)?;
    write(
        &out.join("quickstart.toml"),
        toml::to_string(args.args).map_err(|e| Error::Serialise {
            what: "quickstart.toml",
            reason: e.to_string(),
        })?,
    )?;
    announce(args)?;
    Ok(lock)
}

/// The run's first lines: what it does, where, and how long it should take.
fn announce(args: &Quickstart<'_>) -> Result<()> {
    eprintln!(
        "smile quickstart: {} ({:?} budget, seed {}) -> {}",
        args.env,
        args.budget,
        args.seed,
        args.out.display()
    );
    let scripted = args.recipe.expert == ExpertSource::Scripted;
    if args.budget == Budget::Short && scripted {
        eprintln!("expected time on 2 cores: {}", short_budget_estimate());
    } else if let Some(assets) = &args.shipped {
        eprintln!(
            "from the shipped expert and demos in {}; expected time on 2 cores: 10-20 minutes \
             (SMILe, {}k update pairs on {}-step episodes, is the long stage)",
            assets.display(),
            smile_config(args)?.total_updates / 1000,
            args.horizon().unwrap_or_else(
                || sim::make_env(args.env, EnvConfig::default()).map_or(0, |e| e.horizon())
            )
        );
    } else if args.budget == Budget::Long && !scripted {
        eprintln!(
            "expected time on 2 cores: 2-4 hours (SAC expert, then SMILe); checkpoints are in the run directory"
        );
    }
    Ok(())
}

/// SMILe and Meta-BC on the meta-train demos, at the same time: two learners, candle
/// single-threaded in each (trainer::threads); SMILe's update pairs on two threads
/// (`learner_threads = 2`): deterministic either way.
fn train_both(args: &Quickstart<'_>) -> Result<(MetaPolicy, MetaPolicy)> {
    let (smile_dir, bc_dir) = (args.out.join("smile"), args.out.join("meta-bc"));
    let bars = if args.quiet {
        MultiProgress::with_draw_target(indicatif::ProgressDrawTarget::hidden())
    } else {
        MultiProgress::new()
    };
    let (smile_res, bc_res) = std::thread::scope(|s| {
        let smile = s.spawn(|| {
            let cfg = (Algo::Smile, smile_config(args)?);
            train_learner(cfg, args, &smile_dir, &bars)
        });
        let bc = s.spawn(|| {
            let cfg = (Algo::MetaBc, meta_bc_config(args)?);
            train_learner(cfg, args, &bc_dir, &bars)
        });
        (smile.join(), bc.join())
    });
    let joined = |r: std::thread::Result<Result<MetaPolicy>>| {
        r.unwrap_or_else(|p| std::panic::resume_unwind(p))
    };
    Ok((joined(smile_res)?, joined(bc_res)?))
}

/// What stage 5 made: the blob, its parity with the float policy, its evaluation.
struct Exported {
    blob: Vec<u8>,
    parity: export::Parity,
    result: eval::MethodResult,
}

/// Exports the SMILe policy as the deployed w8a8 blob, checks it against the float policy and
/// evaluates it; writes `policy.blob` and the report `smile export` writes beside a blob, so
/// that `firmware-sim compare --blob policy.blob` works on it as it is.
fn export_blob(
    args: &Quickstart<'_>,
    policy: &MetaPolicy,
    float: &eval::MethodResult,
    train: &DemoDataset,
    test: &DemoDataset,
) -> Result<Exported> {
    let out = &args.out;
    let blob = export::export_blob(policy, infer_core::Quant::W8A8, Some(train))?;
    write(&out.join("policy.blob"), &blob)?;
    let (parity, result, (edges, context)) = {
        let model = export::load_blob(&blob)?;
        let mut actor = BlobActor::new(&model)?;
        let parity = export::parity(policy, &mut actor, test)?;
        eprintln!(
            "  {} bytes; actions vs float: max {:.4}, mean {:.5} over {} actions",
            blob.len(),
            parity.action_max_abs_diff,
            parity.action_mean_abs_diff,
            parity.actions
        );
        let result = evaluate(args, &mut actor, "SMILe w8a8 blob", test)?;
        (parity, result, export::finer_precisions(&model))
    };
    let export_report = export::ExportReport {
        bytes: blob.len(),
        blob_sha256: trainer::checkpoint::sha256_hex(&blob),
        quant: "w8a8".into(),
        edges,
        context,
        qat_steps: None,
        algo: policy.algo.clone(),
        env: args.env,
        physics: policy.physics,
        parity: parity.clone(),
        metric: eval::metric_name(args.env.metric_kind()).into(),
        split: Split::Test.to_string(),
        metric_blob: result.mean,
        metric_candle: float.mean,
        metric_relative_difference: (result.mean - float.mean) / float.mean.abs().max(1e-9),
        per_task_blob: result.tasks.clone(),
        per_task_candle: float.tasks.clone(),
    };
    export_report.write(&export::ExportReport::path_beside(&out.join("policy.blob")))?;
    Ok(Exported {
        blob,
        parity,
        result,
    })
}

#[cfg(test)]
mod tests;
