//! `smile train`: meta-train SMILe (state-action or state-only), Meta-BC or Meta-DAgger.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use sim::{DemoDataset, Family};
use trainer::MetaData;
use trainer::meta_bc::{self, MetaBc, MetaBcConfig};
use trainer::smile::{self, Smile, SmileConfig};

/// Which meta-learner to train.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Algo {
    /// SMILe on (s, a, s') contexts and an [s, a, z] discriminator.
    Smile,
    /// SMILe on (s, s') contexts and an [s, s', z] discriminator.
    SmileStateOnly,
    /// Meta-BC: encoder + policy regressing expert actions.
    MetaBc,
    /// Meta-DAgger: Meta-BC plus online relabelling by an expert (`--expert`).
    MetaDagger,
}

/// Arguments of `smile train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Algorithm.
    #[arg(long, value_enum, default_value_t = Algo::Smile)]
    algo: Algo,
    /// Task family: point-goal, cheetah-vel or walker-dyn.
    #[arg(long, default_value = "point-goal")]
    env: String,
    /// Meta-train demos (`smile demos --split train`); a meta-test file is refused.
    #[arg(long)]
    demos: PathBuf,
    /// Run directory (metrics.jsonl, checkpoint, meta_policy.safetensors, config.toml).
    #[arg(short, long)]
    out: PathBuf,
    /// TOML file with a SmileConfig or MetaBcConfig (flags given here override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Continue the run in `--out` from its checkpoint (with its saved config.toml; flags
    /// given here still override it).
    #[arg(long, conflicts_with = "config")]
    resume: bool,
    /// Total update pairs (SMILe) or gradient steps (Meta-BC / Meta-DAgger).
    #[arg(long)]
    updates: Option<u64>,
    /// Seed.
    #[arg(long)]
    seed: Option<u64>,
    /// SAC / disc / policy hidden widths, e.g. 128,128.
    #[arg(long, value_delimiter = ',')]
    hidden: Option<Vec<usize>>,
    /// Gradient-penalty weight (SMILe).
    #[arg(long)]
    gp_weight: Option<f32>,
    /// Reward scale (SMILe).
    #[arg(long)]
    reward_scale: Option<f32>,
    /// Expert for Meta-DAgger relabelling: a `smile expert` run directory or policy file.
    #[arg(long)]
    expert: Option<PathBuf>,
    /// Evaluate on the held-out train tasks every N updates.
    #[arg(long)]
    eval_every: Option<u64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The base configuration: the run's saved `config.toml` when resuming, else `--config`, else
/// the defaults.
fn read_toml<T: serde::de::DeserializeOwned + Default>(a: &TrainArgs) -> Result<T> {
    let saved = a.out.join("config.toml");
    let p = if a.resume {
        Some(saved)
    } else {
        a.config.clone()
    };
    match &p {
        Some(p) => toml::from_str(
            &std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
        )
        .with_context(|| format!("parsing {}", p.display())),
        None => Ok(T::default()),
    }
}

/// Run `smile train`.
pub fn run(a: TrainArgs) -> Result<()> {
    let family: Family = a.env.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let ds = DemoDataset::read(&a.demos)
        .with_context(|| format!("reading demos {}", a.demos.display()))?;
    if !a.resume {
        trainer::checkpoint::ensure_fresh_run_dir(&a.out)?;
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    match a.algo {
        Algo::Smile | Algo::SmileStateOnly => train_smile(a, family, &ds),
        Algo::MetaBc | Algo::MetaDagger => train_bc(a, family, &ds),
    }
}

fn train_smile(a: TrainArgs, family: Family, ds: &DemoDataset) -> Result<()> {
    let mut cfg: SmileConfig = read_toml(&a)?;
    cfg.env = family.name().into();
    cfg.context.state_only = a.algo == Algo::SmileStateOnly;
    if let Some(v) = a.updates {
        cfg.total_updates = v;
    }
    if let Some(v) = a.seed {
        cfg.seed = v;
    }
    if let Some(v) = &a.hidden {
        cfg.sac.hidden = v.clone();
        cfg.disc_hidden = v.clone();
    }
    if let Some(v) = a.gp_weight {
        cfg.gp_weight = v;
    }
    if let Some(v) = a.reward_scale {
        cfg.sac.reward_scale = v;
    }
    if let Some(v) = a.eval_every {
        cfg.eval_every = v;
    }
    let data = MetaData::from_dataset(ds, family, cfg.holdout_every)?;
    let mut run = if a.resume {
        Smile::resume(&a.out, data, a.updates)?
    } else {
        cfg.validate()?;
        Smile::new(cfg, data)?
    };
    let cfg = run.config().clone();
    std::fs::write(a.out.join("config.toml"), toml::to_string(&cfg)?)?;
    eprintln!(
        "{}: {} training tasks, {} held-out train tasks; {} update pairs",
        cfg.algo_name(),
        run.data().train.len(),
        run.data().val.len(),
        cfg.total_updates
    );
    let pb = trainer::progress_bar(cfg.total_updates, a.quiet, "updates");
    pb.set_position(run.updates());
    let res = smile::train(&mut run, &a.out, &mut |e| match e {
        smile::Event::Updates(u) => pb.set_position(u),
        smile::Event::Eval {
            updates: u,
            metric: m,
            best,
        } => {
            pb.set_message(format!("val {m:.3} (best {best:.3})"));
            if a.quiet {
                eprintln!("update {u}: held-out train-task metric {m:.4} (best {best:.4})");
            }
        }
        smile::Event::Checkpoint(_) => {}
    });
    pb.finish();
    res.with_context(|| format!("SMILe training in {}", a.out.display()))?;
    eprintln!("wrote {}", a.out.join(trainer::META_POLICY_FILE).display());
    Ok(())
}

fn train_bc(a: TrainArgs, family: Family, ds: &DemoDataset) -> Result<()> {
    let mut cfg: MetaBcConfig = read_toml(&a)?;
    cfg.env = family.name().into();
    cfg.dagger = a.algo == Algo::MetaDagger;
    if let Some(v) = a.updates {
        cfg.total_steps = v;
    }
    if let Some(v) = a.seed {
        cfg.seed = v;
    }
    if let Some(v) = &a.hidden {
        cfg.policy_hidden = v.clone();
    }
    if let Some(v) = a.eval_every {
        cfg.eval_every = v;
    }
    let expert = match (&a.expert, cfg.dagger) {
        (Some(p), true) => Some(
            trainer::expert::Expert::load(p)
                .with_context(|| format!("loading expert {}", p.display()))?,
        ),
        (None, true) if family == Family::PointGoal => {
            eprintln!(
                "meta-dagger: no --expert given, relabelling with the scripted point-goal PD expert"
            );
            Some(trainer::expert::Expert::ScriptedPd(
                sim::PointGoalPdExpert::default(),
            ))
        }
        (None, true) => bail!("meta-dagger on {family} needs --expert (a `smile expert` run)"),
        (_, false) => None,
    };
    let data = MetaData::from_dataset(ds, family, cfg.holdout_every)?;
    let mut run = if a.resume {
        MetaBc::resume(&a.out, data, expert, a.updates)?
    } else {
        MetaBc::new(cfg, data, expert)?
    };
    let cfg = run.config().clone();
    std::fs::write(a.out.join("config.toml"), toml::to_string(&cfg)?)?;
    let pb = trainer::progress_bar(cfg.total_steps, a.quiet, "steps");
    pb.set_position(run.steps());
    let select_by = cfg.select_by;
    let res = meta_bc::train(&mut run, &a.out, &mut |e| match e {
        meta_bc::Event::Steps(s) => pb.set_position(s),
        meta_bc::Event::Eval(s, r) => {
            pb.set_message(format!(
                "val mse {:.4} metric {:.3}",
                r.val_mse, r.val_metric
            ));
            if a.quiet {
                eprintln!(
                    "step {s}: val mse {:.5}, held-out metric {:.4}",
                    r.val_mse, r.val_metric
                );
            }
        }
        meta_bc::Event::Stopped(s) => eprintln!(
            "early stop at step {s} (held-out {} stopped improving)",
            match select_by {
                meta_bc::Selection::Mse => "action MSE",
                meta_bc::Selection::Rollouts => "rollout metric",
            }
        ),
    });
    pb.finish();
    res.with_context(|| format!("{} training in {}", cfg.algo_name(), a.out.display()))?;
    eprintln!("wrote {}", a.out.join(trainer::META_POLICY_FILE).display());
    Ok(())
}
