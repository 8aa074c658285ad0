//! `smile train`: meta-train SMILe (state-action or state-only), Meta-BC or Meta-DAgger. The
//! flags become a [`TrainRequest`]; `trainer::run::train` does the rest.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use clap::builder::TypedValueParser;
use sim::Family;
use trainer::run::{RunEvent, TrainRequest};
use trainer::{Algo, Progress, Setting};

/// `--algo`'s parser: the library's names, listed in `--help`.
fn algo_parser() -> impl clap::builder::TypedValueParser<Value = Algo> {
    clap::builder::PossibleValuesParser::new(Algo::ALL.map(Algo::name))
        .try_map(|name| name.parse::<Algo>())
}

/// The flags `smile train` and `smile expert` share: how the learner runs.
#[derive(Args, Debug)]
pub(crate) struct LearnerFlags {
    /// Seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Learner threads, the cores the updates use (the config's `learner_threads`, default 1):
    /// large matrix products split across them (SMILe also overlaps its discriminator and SAC
    /// steps). The count does not change the results (SMILe's: any count above 1 gives the
    /// same); give each thread a free core.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub learner_threads: Option<u16>,
    /// Hidden widths of the networks the learner trains, e.g. 128,128 (an expert: actor and
    /// critics; SMILe: SAC and discriminator; Meta-BC: the policy).
    #[arg(long, value_delimiter = ',', value_parser = crate::width)]
    pub hidden: Option<Vec<usize>>,
}

/// Arguments of `smile train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Algorithm [default: smile]; `--resume` reads it from the run directory.
    #[arg(long, value_parser = algo_parser())]
    algo: Option<Algo>,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass [default: the demo file's].
    #[arg(long)]
    env: Option<Family>,
    /// Physics backend, rapier or mujoco (a `--features mujoco` build) [default: the
    /// config's `physics`, else the demo file's plant]. Demos of another plant are refused.
    #[arg(long)]
    physics: Option<sim::Physics>,
    /// Meta-train demos (`smile demos --split train`); a meta-test file is refused.
    #[arg(long)]
    demos: PathBuf,
    /// Run directory (metrics.jsonl, checkpoint, meta_policy.safetensors, config.toml).
    #[arg(short, long)]
    out: PathBuf,
    /// TOML file with a SmileConfig or MetaBcConfig (flags given here override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Continue the run in `--out` from its checkpoint, with the configuration it started
    /// with: only `--updates` (and SMILe's `--cpu-budget`) may change; other settings given
    /// here must match the run's or are refused, as are other demos than the run's.
    #[arg(long, conflicts_with = "config")]
    resume: bool,
    /// Total update pairs (SMILe) or gradient steps (Meta-BC / Meta-DAgger), at least 1.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=trainer::MAX_STEPS))]
    updates: Option<u64>,
    /// SMILe: a compute budget in CPU-seconds (user + system, every thread) for the whole run,
    /// resumes included; training stops at the first iteration end past it and finishes as at
    /// `--updates` (the config's `cpu_budget_s`; 0: none). For comparisons at equal compute on
    /// a machine that also runs other work; raise it on `--resume` to continue.
    #[arg(long, value_parser = |t: &str| crate::finite_at_least(t, 0.0))]
    cpu_budget: Option<f32>,
    #[command(flatten)]
    learner: LearnerFlags,
    /// Gradient-penalty weight (SMILe), finite and >= 0.
    #[arg(long, value_parser = |t: &str| crate::finite_at_least(t, 0.0))]
    gp_weight: Option<f32>,
    /// Reward scale (SMILe), finite and > 0.
    #[arg(long, value_parser = |t: &str| crate::finite_at_least(t, f32::MIN_POSITIVE))]
    reward_scale: Option<f32>,
    /// SMILe + BC: weight of the auxiliary cloning term on SAC's actor loss (state-action
    /// SMILe), finite and >= 0; 0 is plain SMILe. `bc_decay_updates` in a config decays it.
    #[arg(long, value_parser = |t: &str| crate::finite_at_least(t, 0.0))]
    bc_weight: Option<f32>,
    /// Train through the device's senses: a TOML file whose `[sensing]` section (noise_std,
    /// adc_bits, adc_range, fraction; positions = true for position-only sensing through the
    /// device's estimator, SMILe only) the policy reads its training states through, the
    /// device's sensor model (presets: docs/configs/sensing-noise01-adc12.toml,
    /// sensing-positions.toml; the config's own `[sensing]` otherwise).
    #[arg(long)]
    sensing: Option<PathBuf>,
    /// Expert for Meta-DAgger relabelling: a `smile expert` run directory or policy file, or a
    /// folder of per-task experts (point-goal: the scripted PD expert if omitted; `--resume`
    /// reuses the run's expert).
    #[arg(long)]
    expert: Option<PathBuf>,
    /// Evaluate on the held-out train tasks every N updates (0: never).
    #[arg(long)]
    eval_every: Option<u64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Run `smile train`.
pub fn run(a: TrainArgs) -> Result<()> {
    let req = TrainRequest {
        demos: a.demos.clone(),
        out: a.out.clone(),
        family: a.env,
        algo: a.algo,
        config_file: a.config.clone(),
        settings: settings(&a)?,
        expert: a.expert.clone(),
        resume: a.resume,
    };
    let algo = trainer::run::algo_of(&req)?;
    let mut pb = None;
    let res = trainer::run::train(&req, &mut |e| {
        match &e {
            RunEvent::Started {
                total, done, unit, ..
            } => {
                let bar = smile_app::progress::bar(*total, a.quiet, unit.plural);
                bar.set_position(*done);
                pb = Some(bar);
            }
            RunEvent::Progress(Progress::Steps(s), _) => {
                if let Some(bar) = &pb {
                    bar.set_position(*s);
                }
            }
            RunEvent::Progress(Progress::Eval { .. }, _) => {
                // The bar shows the latest evaluation; a quiet run prints each one.
                if let (Some(bar), Some(line)) = (&pb, smile_app::progress::log_line(&e)) {
                    if a.quiet {
                        eprintln!("{line}");
                    }
                    let text = line.split_once(": ").map_or(line.as_str(), |(_, t)| t);
                    bar.set_message(text.to_string());
                }
                return;
            }
            _ => {}
        }
        if let Some(line) = smile_app::progress::log_line(&e) {
            eprintln!("{line}");
        }
    });
    // An error before training started names its input already; one during training gets
    // the run's place.
    let started = pb.is_some();
    if let Some(bar) = pb {
        bar.finish();
    }
    let res = res.map_err(|e| with_flags(e, &req.settings));
    if started {
        res.with_context(|| format!("{algo} training in {}", a.out.display()))?;
    } else {
        res?;
    }
    eprintln!("wrote {}", a.out.join(trainer::META_POLICY_FILE).display());
    Ok(())
}

/// The flags that set configuration values, typed; the algorithm refuses one it lacks.
fn settings(a: &TrainArgs) -> Result<Vec<Setting>> {
    let sensing = a.sensing.as_deref().map(sensing_preset).transpose()?;
    let l = &a.learner;
    let given = [
        a.updates.map(Setting::Updates),
        a.cpu_budget.map(|s| Setting::CpuBudget(s.into())),
        l.seed.map(Setting::Seed),
        l.learner_threads.map(|n| Setting::LearnerThreads(n.into())),
        a.eval_every.map(Setting::EvalEvery),
        l.hidden.clone().map(Setting::Hidden),
        a.gp_weight.map(Setting::GpWeight),
        a.reward_scale.map(Setting::RewardScale),
        a.bc_weight.map(Setting::BcWeight),
        a.physics.map(Setting::Physics),
        sensing.map(Setting::Sensing),
    ];
    Ok(given.into_iter().flatten().collect())
}

/// The `[sensing]` section of the `--sensing` file, checked, or an error naming the file.
pub(crate) fn sensing_preset(path: &std::path::Path) -> Result<trainer::Sensing> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Preset {
        sensing: trainer::Sensing,
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--sensing: cannot read {}", path.display()))?;
    let preset: Preset = toml::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "--sensing: {} is not a [sensing] section (noise_std, adc_bits, adc_range, \
             fraction): {}",
            path.display(),
            e.message().trim()
        )
    })?;
    preset
        .sensing
        .check()
        .with_context(|| format!("--sensing: {}", path.display()))?;
    Ok(preset.sensing)
}

/// The library's error, with the flag of the setting it names (`given`: the settings the
/// flags gave, in the library's positions).
fn with_flags(e: trainer::Error, given: &[Setting]) -> anyhow::Error {
    match e {
        trainer::Error::NoSuchSetting { name, at, algo } => {
            let flag = given.get(at).map_or(name, flag_of);
            anyhow::anyhow!("{flag} is a SMILe setting; {algo} has no such setting")
        }
        trainer::Error::ResumeChanges {
            run,
            key,
            given: blamed,
            was,
            now,
        } => {
            debug_assert!(blamed.iter().all(|&at| at < given.len()), "{blamed:?}");
            let flags: Vec<&str> = blamed
                .iter()
                .filter_map(|&at| given.get(at))
                .map(flag_of)
                .collect();
            let flag = match flags.is_empty() {
                true => "config.toml".to_string(),
                false => flags.join(" / "),
            };
            anyhow::anyhow!(
                "--resume continues {} with the configuration it started with, but {flag} \
                 changes `{key}` ({was} -> {now}); drop the flag (or restore {}), or start a \
                 new run to change it. Only --updates (and SMILe's --cpu-budget) may change on \
                 --resume",
                run.display(),
                run.join("config.toml").display()
            )
        }
        e => e.into(),
    }
}

/// The flag that gives a setting.
fn flag_of(setting: &Setting) -> &'static str {
    match setting {
        Setting::Updates(_) => "--updates",
        Setting::CpuBudget(_) => "--cpu-budget",
        Setting::Seed(_) => "--seed",
        Setting::LearnerThreads(_) => "--learner-threads",
        Setting::EvalEvery(_) => "--eval-every",
        Setting::Hidden(_) => "--hidden",
        Setting::GpWeight(_) => "--gp-weight",
        Setting::RewardScale(_) => "--reward-scale",
        Setting::BcWeight(_) => "--bc-weight",
        Setting::Physics(_) => "--physics",
        Setting::Sensing(_) => "--sensing",
    }
}
