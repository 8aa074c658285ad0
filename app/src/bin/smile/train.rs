//! `smile train`: meta-train SMILe (state-action or state-only), Meta-BC or Meta-DAgger. The
//! flags become a [`TrainRequest`]; `trainer::run::train` does the rest.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use clap::builder::TypedValueParser;
use sim::Family;
use trainer::run::{RunEvent, TrainRequest};
use trainer::{Algo, Progress};

/// `--algo`'s parser: the library's names, listed in `--help`.
fn algo_parser() -> impl clap::builder::TypedValueParser<Value = Algo> {
    clap::builder::PossibleValuesParser::new(Algo::ALL.map(Algo::name))
        .try_map(|name| name.parse::<Algo>())
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
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    updates: Option<u64>,
    /// SMILe: a compute budget in CPU-seconds (user + system, every thread) for the whole run,
    /// resumes included; training stops at the first iteration end past it and finishes as at
    /// `--updates` (the config's `cpu_budget_s`; 0: none). For comparisons at equal compute on
    /// a machine that also runs other work; raise it on `--resume` to continue.
    #[arg(long, value_parser = |t: &str| crate::finite_at_least(t, 0.0))]
    cpu_budget: Option<f32>,
    /// Seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Learner threads, the cores the updates use (the config's `learner_threads`, default 1):
    /// large matrix products split across them, and SMILe's discriminator and SAC steps
    /// overlapped (SAC's reward then from the discriminator before the pair). Results are the
    /// same for any count above 1; give each thread a free core.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256))]
    learner_threads: Option<u16>,
    /// SAC / disc / policy hidden widths, e.g. 128,128.
    #[arg(long, value_delimiter = ',')]
    hidden: Option<Vec<usize>>,
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
    let mut req = TrainRequest {
        demos: a.demos.clone(),
        out: a.out.clone(),
        family: a.env,
        algo: a.algo,
        config_file: a.config.clone(),
        set: toml::Table::new(),
        physics: a.physics,
        expert: a.expert.clone(),
        resume: a.resume,
    };
    // Which keys the flags set depends on the algorithm: a resume's is the recorded one.
    let algo = trainer::run::algo_of(&req)?;
    req.set = flag_table(&a, algo)?;
    let mut pb = None;
    let res = trainer::run::train(&req, &mut |e| {
        match &e {
            RunEvent::Started {
                total, done, unit, ..
            } => {
                let bar = smile_app::progress::bar(*total, a.quiet, unit);
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
                if let (Some(bar), Some(line)) = (&pb, e.log_line()) {
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
        if let Some(line) = e.log_line() {
            eprintln!("{line}");
        }
    });
    // An error before training started names its input already; one during training gets
    // the run's place.
    let started = pb.is_some();
    if let Some(bar) = pb {
        bar.finish();
    }
    if started {
        res.with_context(|| format!("{algo} training in {}", a.out.display()))?;
    } else {
        res?;
    }
    eprintln!("wrote {}", a.out.join(trainer::META_POLICY_FILE).display());
    Ok(())
}

/// The flags that set configuration keys, as a table in the configuration's own shape.
fn flag_table(a: &TrainArgs, algo: Algo) -> Result<toml::Table> {
    let mut t = toml::Table::new();
    let mut set = |key: &str, v: toml::Value| {
        trainer::set_config_key(&mut t, key, v).map_err(|e| anyhow::anyhow!("{key}: {e}"))
    };
    let int = |v: u64| toml::Value::Integer(v as i64);
    let float = |v: f32| toml::Value::Float(v.into());
    let widths = |v: &[usize]| toml::Value::Array(v.iter().map(|&w| int(w as u64)).collect());
    if let Some(v) = a.updates {
        set(algo.budget_key(), int(v))?;
    }
    if let Some(v) = a.seed {
        set("seed", int(v))?;
    }
    if let Some(v) = a.learner_threads {
        set("learner_threads", int(v.into()))?;
    }
    if let Some(v) = a.eval_every {
        set("eval_every", int(v))?;
    }
    match algo {
        Algo::Smile | Algo::SmileStateOnly => {
            if let Some(v) = &a.hidden {
                set("sac.hidden", widths(v))?;
                set("disc_hidden", widths(v))?;
            }
            for (key, v) in [
                ("gp_weight", a.gp_weight),
                ("sac.reward_scale", a.reward_scale),
                ("bc_weight", a.bc_weight),
                ("cpu_budget_s", a.cpu_budget),
            ] {
                if let Some(v) = v {
                    set(key, float(v))?;
                }
            }
        }
        Algo::MetaBc | Algo::MetaDagger => {
            for (flag, given) in [
                ("--gp-weight", a.gp_weight.is_some()),
                ("--reward-scale", a.reward_scale.is_some()),
                ("--bc-weight", a.bc_weight.is_some()),
                ("--cpu-budget", a.cpu_budget.is_some()),
            ] {
                if given {
                    bail!("{flag} is a SMILe setting; {algo} has no such setting");
                }
            }
            if let Some(v) = &a.hidden {
                set("policy_hidden", widths(v))?;
            }
        }
    }
    Ok(t)
}
