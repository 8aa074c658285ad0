//! `smile train`: meta-train SMILe (state-action or state-only), Meta-BC or Meta-DAgger.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use clap::builder::TypedValueParser;
use sim::{DemoDataset, Family};
use trainer::meta_bc::MetaBc;
use trainer::smile::Smile;
use trainer::{Algo, MetaData, MetaLearner, Progress};

/// `--algo`'s parser: the library's names, listed in `--help`.
fn algo_parser() -> impl clap::builder::TypedValueParser<Value = Algo> {
    clap::builder::PossibleValuesParser::new(Algo::ALL.map(Algo::name))
        .try_map(|name| name.parse::<Algo>())
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
    /// The plant the run simulates (the config's `physics`, which the demos must match).
    /// Absent in runs made before the MuJoCo backend: Rapier's.
    #[serde(default)]
    physics: sim::Physics,
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

/// The configuration: the flags given here, over the run's saved `config.toml` when resuming
/// (else over `--config`), over the algorithm's defaults.
fn read_config<L: MetaLearner>(
    a: &TrainArgs,
    algo: Algo,
    demos_physics: sim::Physics,
) -> Result<L::Config> {
    let file = if a.resume {
        Some(a.out.join("config.toml"))
    } else {
        a.config.clone()
    };
    let text = match &file {
        Some(p) => {
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?
        }
        None => String::new(),
    };
    let what = match (&file, a.resume) {
        (Some(p), true) => format!(
            "parsing {} (its {RUN_FILE} names the algorithm whose config this must be)",
            p.display()
        ),
        (Some(p), false) => format!("parsing {}", p.display()),
        (None, _) => "reading the flags".into(),
    };
    let mut flags = flag_table(a, algo, L::TOTAL_KEY)?;
    // The plant: --physics, else the file's `physics`, else the demos' (a new run on MuJoCo
    // demos runs on MuJoCo without being told twice).
    let in_file = text
        .parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("physics"));
    if let Some(p) = a.physics.or((!in_file).then_some(demos_physics)) {
        flags.insert("physics".into(), p.name().into());
    }
    trainer::from_toml_with_flags(&text, flags).context(what)
}

/// The flags that set configuration keys, as a table in the configuration's own shape.
fn flag_table(a: &TrainArgs, algo: Algo, total_key: &str) -> Result<toml::Table> {
    let mut t = toml::Table::new();
    let mut set = |key: &str, v: toml::Value| {
        trainer::set_config_key(&mut t, key, v).map_err(|e| anyhow::anyhow!("{key}: {e}"))
    };
    let int = |v: u64| toml::Value::Integer(v as i64);
    let float = |v: f32| toml::Value::Float(v.into());
    let widths = |v: &[usize]| toml::Value::Array(v.iter().map(|&w| int(w as u64)).collect());
    if let Some(v) = a.updates {
        set(total_key, int(v))?;
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
        physics: sim::Physics::Rapier,
    })
}

/// Run `smile train`.
pub fn run(mut a: TrainArgs) -> Result<()> {
    let (family, ds) = match a.env {
        Some(family) => (family, crate::read_demos(&a.demos, "--demos", family)?),
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
        let algo: Algo = rec
            .algo
            .parse()
            .with_context(|| format!("{}", a.out.join(RUN_FILE).display()))?;
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
        Algo::Smile | Algo::SmileStateOnly => train_with::<Smile>(a, algo, family, &ds, demos_sha),
        Algo::MetaBc | Algo::MetaDagger => train_with::<MetaBc>(a, algo, family, &ds, demos_sha),
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
    physics: sim::Physics,
) -> Result<trainer::DirLock> {
    let lock = trainer::DirLock::acquire(&a.out)?;
    let info = RunInfo {
        algo: algo.name().into(),
        expert: expert.map(|p| p.to_string_lossy().into_owned()),
        expert_os: expert
            .filter(|p| p.to_str().is_none())
            .map(|p| p.as_os_str().to_owned()),
        demos_sha256: Some(demos_sha256),
        physics,
    };
    trainer::checkpoint::write_atomic(
        &a.out.join(RUN_FILE),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    Ok(lock)
}

/// Meta-DAgger's relabelling expert: `--expert` (a `smile expert` run or a folder of them),
/// or point-goal's scripted PD controller; none for the other algorithms.
fn relabelling_expert(
    a: &TrainArgs,
    algo: Algo,
    family: Family,
) -> Result<(Option<trainer::expert::ExpertSet>, Option<PathBuf>)> {
    if !algo.needs_expert() {
        if let Some(p) = &a.expert {
            bail!(
                "--expert {} is Meta-DAgger's relabelling expert; {algo} learns from the demos                  alone (drop --expert, or train --algo meta-dagger)",
                p.display()
            );
        }
        return Ok((None, None));
    }
    let scripted = a.expert.as_deref() == Some(std::path::Path::new(SCRIPTED_PD));
    match &a.expert {
        Some(p) if !scripted => {
            eprintln!("{algo}: relabelling with the expert {}", p.display());
            let set = trainer::expert::ExpertSet::load(&[p])
                .with_context(|| format!("loading expert {}", p.display()))?;
            Ok((Some(set), Some(p.clone())))
        }
        _ if family == Family::PointGoal => {
            eprintln!("{algo}: relabelling with the scripted point-goal PD expert");
            let pd = trainer::expert::Expert::ScriptedPd(sim::PointGoalPdExpert::default());
            Ok((Some(pd.into()), Some(PathBuf::from(SCRIPTED_PD))))
        }
        _ => bail!("{algo} on {family} needs --expert (a `smile expert` run)"),
    }
}

/// Trains (or resumes) any meta-learner: the configuration from flags over file over
/// defaults, the run directory, the progress bar and its messages.
fn train_with<L: MetaLearner>(
    a: TrainArgs,
    algo: Algo,
    family: Family,
    ds: &DemoDataset,
    demos_sha: String,
) -> Result<()> {
    let mut cfg: L::Config = read_config::<L>(&a, algo, ds.physics)?;
    L::configure(&mut cfg, algo, family);
    let (expert, expert_path) = relabelling_expert(&a, algo, family)?;
    let data = MetaData::from_dataset(ds, family, L::holdout_every(&cfg))
        .with_context(|| format!("--demos {}", a.demos.display()))?;
    let (n_train, n_val) = (data.train.len(), data.val.len());
    let mut run = if a.resume {
        let run = L::resume_from(&a.out, data, expert, &cfg)?;
        check_resume(&a, &cfg, run.settings(), L::RESUMABLE)?;
        run
    } else {
        L::start(cfg, data, expert)?
    };
    let cfg = run.settings().clone();
    let _lock = start_run_dir(&a, algo, expert_path.as_deref(), demos_sha, ds.physics)?;
    trainer::checkpoint::write_atomic(
        &a.out.join("config.toml"),
        toml::to_string(&cfg)?.as_bytes(),
    )?;
    if a.resume {
        eprintln!("resuming from {} {}", L::STEP_WORD, run.done());
    }
    eprintln!(
        "{algo}: {n_train} training tasks, {n_val} held-out train tasks; {} {}",
        run.total(),
        L::STEP_NAME
    );
    let pb = trainer::progress_bar(run.total(), a.quiet, L::STEP_NAME);
    pb.set_position(run.done());
    let res = run.run(&a.out, &mut |e| match e {
        Progress::Steps(s) => pb.set_position(s),
        Progress::Eval {
            step,
            metric,
            best,
            val_mse,
        } => {
            let text = match val_mse {
                Some(mse) => format!("val mse {mse:.5}, held-out metric {metric:.4}"),
                None => format!("held-out train-task metric {metric:.4} (best {best:.4})"),
            };
            if a.quiet {
                eprintln!("{} {step}: {text}", L::STEP_WORD);
            }
            pb.set_message(text);
        }
        Progress::Checkpoint(_) => {}
        Progress::Stopped(s) => eprintln!(
            "early stop at {} {s}: the held-out selection metric stopped improving",
            L::STEP_WORD
        ),
    });
    pb.finish();
    res.with_context(|| format!("{algo} training in {}", a.out.display()))?;
    eprintln!("wrote {}", a.out.join(trainer::META_POLICY_FILE).display());
    Ok(())
}
