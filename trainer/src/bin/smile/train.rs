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

impl Algo {
    /// The name `--algo` takes.
    fn name(self) -> &'static str {
        match self {
            Algo::Smile => "smile",
            Algo::SmileStateOnly => "smile-state-only",
            Algo::MetaBc => "meta-bc",
            Algo::MetaDagger => "meta-dagger",
        }
    }
}

/// File in a run directory recording how the run was started, so that `--resume` continues
/// it with the same algorithm and expert.
const RUN_FILE: &str = "run.json";

/// The expert name recorded for the scripted point-goal PD controller.
const SCRIPTED_PD: &str = "scripted-pd";

/// What `smile train` records in [`RUN_FILE`].
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct RunInfo {
    /// `--algo` of the run.
    algo: String,
    /// Meta-DAgger's relabelling expert: a `smile expert` run, or `scripted-pd`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    expert: Option<String>,
    /// The expert's path as the OS gave it, when it is not UTF-8 (`expert` then holds a lossy
    /// copy for people to read): `--resume` must find the very same file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    expert_os: Option<std::ffi::OsString>,
    /// SHA-256 of the `--demos` file the run started on: `--resume` refuses other demos (their
    /// normalisation and tasks would silently replace the run's). Absent in older runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    demos_sha256: Option<String>,
}

/// Arguments of `smile train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Algorithm [default: smile]; `--resume` reads it from the run directory.
    #[arg(long, value_enum)]
    algo: Option<Algo>,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass [default: the demo file's].
    #[arg(long)]
    env: Option<String>,
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
    /// with: only `--updates` may change (a larger budget); other settings given here must
    /// match the run's or are refused, as are other demos than the run's.
    #[arg(long, conflicts_with = "config")]
    resume: bool,
    /// Total update pairs (SMILe) or gradient steps (Meta-BC / Meta-DAgger), at least 1.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    updates: Option<u64>,
    /// SMILe: a compute budget in CPU-seconds (user + system, every thread) for this
    /// invocation; training stops at the first iteration end past it and finishes as at
    /// `--updates` (the config's `cpu_budget_s`; 0: none). For comparisons at equal compute on
    /// a machine that also runs other work.
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

/// The base configuration: the run's saved `config.toml` when resuming, else `--config`, else
/// the defaults.
fn read_toml<T: serde::Serialize + serde::de::DeserializeOwned + Default>(
    a: &TrainArgs,
) -> Result<T> {
    let saved = a.out.join("config.toml");
    let p = if a.resume {
        Some(saved)
    } else {
        a.config.clone()
    };
    let what = if a.resume {
        format!(" (its {RUN_FILE} names the algorithm whose config this must be)")
    } else {
        String::new()
    };
    match &p {
        Some(p) => trainer::from_toml_over_defaults(
            &std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
        )
        .with_context(|| format!("parsing {}{what}", p.display())),
        None => Ok(T::default()),
    }
}

/// The algorithm (and Meta-DAgger's expert) of the run in `dir`: from its `run.json`, or for
/// runs older than that file, from its `config.toml`.
fn recorded_run(dir: &std::path::Path) -> Result<RunInfo> {
    let info = dir.join(RUN_FILE);
    if let Ok(text) = std::fs::read_to_string(&info) {
        return serde_json::from_str(&text).with_context(|| format!("parsing {}", info.display()));
    }
    let cfg = dir.join("config.toml");
    let text = std::fs::read_to_string(&cfg).with_context(|| {
        format!(
            "{} holds no run to resume (no {RUN_FILE} or config.toml)",
            dir.display()
        )
    })?;
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("parsing {}", cfg.display()))?;
    let algo = match table.get("dagger").and_then(toml::Value::as_bool) {
        Some(true) => Algo::MetaDagger,
        Some(false) => Algo::MetaBc,
        None => {
            let state_only = table
                .get("context")
                .and_then(|c| c.get("state_only"))
                .and_then(toml::Value::as_bool);
            if state_only == Some(true) {
                Algo::SmileStateOnly
            } else {
                Algo::Smile
            }
        }
    };
    Ok(RunInfo {
        algo: algo.name().into(),
        expert: None,
        expert_os: None,
        demos_sha256: None,
    })
}

/// Run `smile train`.
pub fn run(mut a: TrainArgs) -> Result<()> {
    let (family, ds) = match &a.env {
        Some(env) => {
            let family: Family = env.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
            (family, crate::read_demos(&a.demos, "--demos", family)?)
        }
        None => {
            let ds = crate::read_any_demos(&a.demos, "--demos")?;
            (ds.family, ds)
        }
    };
    let demos_sha = trainer::checkpoint::sha256_file(&a.demos)?;
    let algo = if a.resume {
        let rec = recorded_run(&a.out)?;
        match &rec.demos_sha256 {
            Some(sha) if *sha != demos_sha => bail!(
                "--demos {} is not the file {} was trained on (SHA-256 {} here, {} recorded in \
                 {RUN_FILE}); resume with the run's own demos, or start a new run on these",
                a.demos.display(),
                a.out.display(),
                &demos_sha[..12],
                &sha[..sha.len().min(12)]
            ),
            Some(_) => {}
            None => eprintln!(
                "warning: {} records no demo checksum (a run older than that check); make sure \
                 --demos is the file it started on",
                a.out.join(RUN_FILE).display()
            ),
        }
        let algo = Algo::from_str(&rec.algo, false)
            .map_err(|e| anyhow::anyhow!("{}: unknown algo {:?}: {e}", RUN_FILE, rec.algo))?;
        if let Some(given) = a.algo.filter(|g| *g != algo) {
            bail!(
                "{} is a {} run; --algo {} does not match (drop --algo to resume it)",
                a.out.display(),
                algo.name(),
                given.name()
            );
        }
        if a.expert.is_none() {
            a.expert = rec
                .expert_os
                .map(PathBuf::from)
                .or(rec.expert.map(PathBuf::from));
        }
        algo
    } else {
        trainer::checkpoint::ensure_fresh_run_dir(&a.out)?;
        a.algo.unwrap_or(Algo::Smile)
    };
    match algo {
        Algo::Smile | Algo::SmileStateOnly => train_smile(a, algo, family, &ds, demos_sha),
        Algo::MetaBc | Algo::MetaDagger => train_bc(a, algo, family, &ds, demos_sha),
    }
}

/// On `--resume`: the flags given must agree with the configuration the run continues (its
/// checkpoint's), and so must its `config.toml` (a reader trusts that file to describe the
/// run); `total` names the budget field, the one setting `--updates` may change.
fn check_resume<T: serde::Serialize>(
    a: &TrainArgs,
    given: &T,
    running: &T,
    changeable: &[&str],
) -> Result<()> {
    let table = |c: &T| -> Result<toml::Table> { Ok(toml::Table::try_from(c)?) };
    let (mut g, mut r) = (table(given)?, table(running)?);
    for key in changeable {
        g.remove(*key);
        r.remove(*key);
    }
    for (key, theirs) in &r {
        let ours = g.get(key);
        if ours != Some(theirs) {
            let flag = match key.as_str() {
                "seed" => "--seed",
                "learner_threads" => "--learner-threads",
                "disc_hidden" | "sac" | "policy_hidden" => "--hidden / --reward-scale",
                "gp_weight" => "--gp-weight",
                "bc_weight" => "--bc-weight",
                "eval_every" => "--eval-every",
                _ => "config.toml",
            };
            bail!(
                "--resume continues {} with the configuration it started with, but {flag} \
                 changes `{key}` ({} -> {}); drop the flag (or restore {}), or start a new run \
                 to change it. Only --updates (and SMILe's --cpu-budget) may change on --resume",
                a.out.display(),
                theirs,
                ours.map_or("missing".into(), ToString::to_string),
                a.out.join("config.toml").display()
            );
        }
    }
    Ok(())
}

/// Creates the run directory (only once the inputs were accepted, so a refused run leaves
/// nothing behind) and records the run's algorithm and expert.
/// The returned lock is held for the whole training: a second writer is refused.
fn start_run_dir(
    a: &TrainArgs,
    algo: Algo,
    expert: Option<&std::path::Path>,
    demos_sha256: String,
) -> Result<trainer::DirLock> {
    let lock = trainer::DirLock::acquire(&a.out)?;
    let info = RunInfo {
        algo: algo.name().into(),
        expert: expert.map(|p| p.to_string_lossy().into_owned()),
        expert_os: expert
            .filter(|p| p.to_str().is_none())
            .map(|p| p.as_os_str().to_owned()),
        demos_sha256: Some(demos_sha256),
    };
    trainer::checkpoint::write_atomic(
        &a.out.join(RUN_FILE),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    Ok(lock)
}

fn train_smile(
    a: TrainArgs,
    algo: Algo,
    family: Family,
    ds: &DemoDataset,
    demos_sha: String,
) -> Result<()> {
    let mut cfg: SmileConfig = read_toml(&a)?;
    cfg.env = family;
    cfg.context.state_only = algo == Algo::SmileStateOnly;
    if let Some(v) = a.updates {
        cfg.total_updates = v;
    }
    if let Some(v) = a.seed {
        cfg.seed = v;
    }
    if let Some(v) = a.learner_threads {
        cfg.learner_threads = v.into();
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
    if let Some(v) = a.bc_weight {
        cfg.bc_weight = v;
    }
    if let Some(v) = a.eval_every {
        cfg.eval_every = v;
    }
    if let Some(v) = a.cpu_budget {
        cfg.cpu_budget_s = v.into();
    }
    let data = MetaData::from_dataset(ds, family, cfg.holdout_every)
        .with_context(|| format!("--demos {}", a.demos.display()))?;
    let mut run = if a.resume {
        let mut run = Smile::resume(&a.out, data, a.updates.or(Some(cfg.total_updates)))?;
        check_resume(&a, &cfg, run.config(), &["total_updates", "cpu_budget_s"])?;
        run.set_cpu_budget(cfg.cpu_budget_s)?;
        run
    } else {
        cfg.validate()?;
        Smile::new(cfg, data)?
    };
    let cfg = run.config().clone();
    let _lock = start_run_dir(&a, algo, None, demos_sha)?;
    trainer::checkpoint::write_atomic(
        &a.out.join("config.toml"),
        toml::to_string(&cfg)?.as_bytes(),
    )?;
    if a.resume {
        eprintln!("resuming from update {}", run.updates());
    }
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

fn train_bc(
    a: TrainArgs,
    algo: Algo,
    family: Family,
    ds: &DemoDataset,
    demos_sha: String,
) -> Result<()> {
    for (flag, given) in [
        ("--gp-weight", a.gp_weight.is_some()),
        ("--reward-scale", a.reward_scale.is_some()),
        ("--bc-weight", a.bc_weight.is_some()),
        ("--cpu-budget", a.cpu_budget.is_some()),
    ] {
        if given {
            bail!(
                "{flag} is a SMILe setting; {} has no such setting",
                algo.name()
            );
        }
    }
    let mut cfg: MetaBcConfig = read_toml(&a)?;
    cfg.env = family;
    cfg.dagger = algo == Algo::MetaDagger;
    if let Some(v) = a.updates {
        cfg.total_steps = v;
    }
    if let Some(v) = a.seed {
        cfg.seed = v;
    }
    if let Some(v) = a.learner_threads {
        cfg.learner_threads = v.into();
    }
    if let Some(v) = &a.hidden {
        cfg.policy_hidden = v.clone();
    }
    if let Some(v) = a.eval_every {
        cfg.eval_every = v;
    }
    let scripted = a.expert.as_deref() == Some(std::path::Path::new(SCRIPTED_PD));
    let expert = match (&a.expert, cfg.dagger) {
        (Some(p), true) if !scripted => {
            eprintln!("meta-dagger: relabelling with the expert {}", p.display());
            Some(
                trainer::expert::ExpertSet::load(&[p])
                    .with_context(|| format!("loading expert {}", p.display()))?,
            )
        }
        (_, true) if family == Family::PointGoal => {
            eprintln!("meta-dagger: relabelling with the scripted point-goal PD expert");
            Some(trainer::expert::Expert::ScriptedPd(sim::PointGoalPdExpert::default()).into())
        }
        (_, true) => bail!("meta-dagger on {family} needs --expert (a `smile expert` run)"),
        (_, false) => None,
    };
    let data = MetaData::from_dataset(ds, family, cfg.holdout_every)
        .with_context(|| format!("--demos {}", a.demos.display()))?;
    let mut run = if a.resume {
        let run = MetaBc::resume(&a.out, data, expert, a.updates.or(Some(cfg.total_steps)))?;
        check_resume(&a, &cfg, run.config(), &["total_steps"])?;
        run
    } else {
        MetaBc::new(cfg, data, expert)?
    };
    let cfg = run.config().clone();
    let expert_path = match (&a.expert, cfg.dagger) {
        (Some(p), true) => Some(p.as_path()),
        (None, true) => Some(std::path::Path::new(SCRIPTED_PD)),
        (_, false) => None,
    };
    let _lock = start_run_dir(&a, algo, expert_path, demos_sha)?;
    trainer::checkpoint::write_atomic(
        &a.out.join("config.toml"),
        toml::to_string(&cfg)?.as_bytes(),
    )?;
    if a.resume {
        eprintln!("resuming from step {}", run.steps());
    }
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
