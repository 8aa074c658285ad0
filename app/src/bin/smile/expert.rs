//! `smile expert`: an oracle SAC expert (or the scripted PD expert) for a family.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use sim::{EnvConfig, Family};
use trainer::Progress;
use trainer::expert::{self, Expert, ExpertConfig, ExpertTrainer};

/// Which expert `smile expert` produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExpertKind {
    /// SAC trained on the oracle observation (observation + task parameter).
    Sac,
    /// sim's scripted point-goal PD controller (point-goal only; nothing is trained).
    ScriptedPd,
    /// ant-linclass only: classifies with the true hyperplane and drives the ant-goal expert
    /// given by --goal-expert to the chosen target (nothing is trained).
    ScriptedLinclass,
}

/// Arguments of `smile expert`.
#[derive(Args, Debug)]
pub struct ExpertArgs {
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass [default:
    /// point-goal, or the --config file's `env`].
    #[arg(long)]
    env: Option<Family>,
    /// Physics backend: rapier or mujoco (a `--features mujoco` build) [default: rapier, or
    /// the --config file's `physics`].
    #[arg(long)]
    physics: Option<sim::Physics>,
    /// Expert kind.
    #[arg(long, value_enum, default_value_t = ExpertKind::Sac)]
    kind: ExpertKind,
    /// --kind scripted-linclass: the ant-goal SAC expert it drives (a `smile expert --env
    /// ant-goal` run directory or policy file, e.g. assets/experts/ant-goal).
    #[arg(long)]
    goal_expert: Option<PathBuf>,
    /// --kind scripted-linclass: aim the ant-goal expert this many times as far as the chosen
    /// target, so it crosses the decision radius within the episode (1.2 suits the Rapier
    /// expert; see assets/experts/ant-linclass*/README.md).
    #[arg(long, default_value_t = sim::ant_linclass::AIM_SCALE)]
    aim_scale: f32,
    /// TOML file with an `ExpertConfig` (flags given here override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Run directory (checkpoint, metrics.jsonl, config.toml, policy.safetensors, eval.json)
    /// [default: runs/expert-<env>[-nominal]-s<seed>; runs/expert-point-goal-pd for
    /// --kind scripted-pd].
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// Continue the run in this directory from its checkpoint (its saved config is used).
    #[arg(long, conflicts_with_all = ["config", "env", "physics"])]
    resume: Option<PathBuf>,
    /// Total environment steps [default: 30000, or the --config file's].
    #[arg(long)]
    total_steps: Option<u64>,
    /// Seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Learner threads, the cores the SAC updates use (the config's `learner_threads`,
    /// default 1): large matrix products split across them; the same weights on any count.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256))]
    learner_threads: Option<u16>,
    /// Hidden widths of actor and critics, e.g. 256,256.
    #[arg(long, value_delimiter = ',')]
    hidden: Option<Vec<usize>>,
    /// Minibatch size.
    #[arg(long)]
    batch_size: Option<usize>,
    /// Random-action steps before learning.
    #[arg(long)]
    learning_starts: Option<u64>,
    /// Episode length override (at least 1).
    #[arg(long, value_parser = crate::positive)]
    horizon: Option<usize>,
    /// Train a per-task expert on this meta-train task index.
    #[arg(long, conflicts_with = "task_value")]
    task_index: Option<usize>,
    /// Train a per-task expert on the task with this parameter (goal angle, target velocity
    /// or dynamics seed), e.g. a meta-test task.
    #[arg(long, allow_hyphen_values = true)]
    task_value: Option<f64>,
    /// walker-dyn only: train on the unmodified dynamics (the task value
    /// `sim::WALKER_NOMINAL_SEED`, in neither split): the "base" policy of `smile eval --base`.
    #[arg(long, conflicts_with_all = ["task_index", "task_value", "resume"])]
    nominal: bool,
    /// Checkpoint every N env steps.
    #[arg(long)]
    checkpoint_every: Option<u64>,
    /// Evaluate deterministically every N env steps (0 = never), logged as eval/metric.
    #[arg(long)]
    eval_every: Option<u64>,
    /// Warm start from another expert run's checkpoint (a run directory of `smile expert`):
    /// its actor, critics and temperature; fresh replay buffer; the first --learning-starts
    /// steps act with the loaded policy instead of at random.
    #[arg(long, conflicts_with = "resume")]
    init_from: Option<PathBuf>,
    /// Ship the best-evaluated weights instead of the last (every --eval-every steps the
    /// weights are evaluated; the best go to policy-best.safetensors and, if the final weights
    /// do worse, to policy.safetensors).
    #[arg(long)]
    keep_best: bool,
    /// Deterministic evaluation episodes per meta-test task at the end.
    #[arg(long, default_value_t = 2)]
    eval_episodes: usize,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The flags that set `ExpertConfig` keys, as a table in the config's own shape.
fn flag_table(a: &ExpertArgs) -> Result<toml::Table> {
    let mut t = toml::Table::new();
    let mut set = |key: &str, v: toml::Value| {
        trainer::set_config_key(&mut t, key, v).map_err(|e| anyhow::anyhow!("{key}: {e}"))
    };
    let int = |v: u64| toml::Value::Integer(v as i64);
    if let Some(v) = a.env {
        set("env", v.name().into())?;
    }
    if let Some(v) = a.physics {
        set("physics", v.name().into())?;
    }
    for (key, v) in [
        ("total_steps", a.total_steps),
        ("seed", a.seed),
        ("learner_threads", a.learner_threads.map(u64::from)),
        ("sac.batch_size", a.batch_size.map(|v| v as u64)),
        ("learning_starts", a.learning_starts),
        ("checkpoint_every", a.checkpoint_every),
        ("eval_every", a.eval_every),
        ("horizon", a.horizon.map(|v| v as u64)),
        ("task_index", a.task_index.map(|v| v as u64)),
    ] {
        if let Some(v) = v {
            set(key, int(v))?;
        }
    }
    if let Some(v) = &a.hidden {
        set(
            "sac.hidden",
            v.iter().map(|&w| int(w as u64)).collect::<Vec<_>>().into(),
        )?;
    }
    if let Some(v) = a.task_value {
        set("task_value", v.into())?;
    }
    if a.keep_best {
        set("keep_best", true.into())?;
    }
    Ok(t)
}

fn effective_config(a: &ExpertArgs) -> Result<ExpertConfig> {
    let text = match &a.config {
        Some(p) => {
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?
        }
        None => String::new(),
    };
    let what = a.config.as_ref().map_or("reading the flags".into(), |p| {
        format!("parsing {}", p.display())
    });
    let mut cfg: ExpertConfig =
        trainer::from_toml_with_flags(&text, flag_table(a)?).context(what)?;
    // A path is set here, not through TOML, which holds only UTF-8 strings.
    if a.init_from.is_some() {
        cfg.init_from = a.init_from.clone();
    }
    if cfg.keep_best && cfg.eval_every == 0 {
        bail!("--keep-best needs evaluations: set --eval-every above 0");
    }
    if a.nominal {
        let Some(nominal) = cfg.env.spec().nominal_task else {
            bail!(
                "--nominal trains on a family's nominal task (walker-dyn's unmodified walker); {} \
                 has none",
                cfg.env
            );
        };
        // A config file's task_index would silently win over the flag otherwise.
        cfg.task_index = None;
        cfg.task_value = Some(nominal.value());
    }
    cfg.sac.validate()?;
    Ok(cfg)
}

/// Run `smile expert`.
pub fn run(a: ExpertArgs) -> Result<()> {
    if a.kind == ExpertKind::ScriptedPd {
        let env = a.env.unwrap_or(Family::PointGoal);
        if env != Family::PointGoal {
            bail!("the scripted PD expert exists only for point-goal, not {env}");
        }
        let dir = a
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("runs/expert-point-goal-pd"));
        trainer::checkpoint::ensure_fresh_run_dir(&dir)?;
        std::fs::create_dir_all(&dir)?;
        expert::export_scripted_pd(&dir)?;
        return finish(&dir, a.eval_episodes, None, EnvConfig::default());
    }
    if a.kind == ExpertKind::ScriptedLinclass {
        let env = a.env.unwrap_or(Family::AntLinClass);
        if env != Family::AntLinClass {
            bail!("the scripted classification expert exists only for ant-linclass, not {env}");
        }
        let Some(goal) = &a.goal_expert else {
            bail!(
                "--kind scripted-linclass drives an ant-goal expert: give it with --goal-expert \
                 (e.g. assets/experts/ant-goal)"
            );
        };
        let dir = a
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("runs/expert-ant-linclass-scripted"));
        trainer::checkpoint::ensure_fresh_run_dir(&dir)?;
        std::fs::create_dir_all(&dir)?;
        expert::export_scripted_linclass(goal, a.aim_scale, &dir)
            .with_context(|| format!("--goal-expert {}", goal.display()))?;
        return finish(&dir, a.eval_episodes, None, EnvConfig::default());
    }
    if a.goal_expert.is_some() {
        bail!("--goal-expert is for --kind scripted-linclass");
    }
    let (mut run, dir) = match &a.resume {
        Some(dir) => {
            if !dir.join(trainer::checkpoint::CHECKPOINT_FILE).exists()
                && dir.join("config.toml").exists()
            {
                bail!(
                    "--resume {}: no checkpoint yet (the run was interrupted before its first \
                     one), so there is nothing to continue; start it again with the same flags \
                     and -o {} (its partial files are replaced)",
                    dir.display(),
                    dir.display()
                );
            }
            let run = ExpertTrainer::resume(dir, a.total_steps)
                .with_context(|| format!("resuming from {}", dir.display()))?;
            (run, dir.clone())
        }
        None => {
            let cfg = effective_config(&a)?;
            let nominal = if a.nominal { "-nominal" } else { "" };
            let dir = a.out.clone().unwrap_or_else(|| {
                let plant = match cfg.physics {
                    sim::Physics::Rapier => String::new(),
                    other => format!("-{other}"),
                };
                PathBuf::from(format!(
                    "runs/expert-{}{plant}{nominal}-s{}",
                    cfg.env, cfg.seed
                ))
            });
            trainer::checkpoint::ensure_fresh_run_dir(&dir)?;
            if let (Some(v), [task]) = (cfg.task_value, cfg.tasks()?.as_slice()) {
                // sim's tolerant lookup: 0.4909 names test goal 0.490874 exactly.
                eprintln!(
                    "--task-value {v}: a per-task expert on {} (value {})",
                    task.label(),
                    task.value()
                );
            }
            (ExpertTrainer::new(cfg)?, dir)
        }
    };
    // One writer per run directory: a second `smile expert` on it is refused with our pid.
    let _lock = trainer::DirLock::acquire(&dir)?;
    if a.resume.is_none() {
        // Under the lock: what a run killed before its first checkpoint left goes first, so
        // this run's log does not continue the dead one's.
        let removed = trainer::checkpoint::clear_interrupted_run(&dir)?;
        if !removed.is_empty() {
            eprintln!(
                "{} held a run interrupted before its first checkpoint (nothing to resume); \
                 starting over: removed {}",
                dir.display(),
                removed.join(", ")
            );
        }
    }
    trainer::checkpoint::write_atomic(
        &dir.join("config.toml"),
        toml::to_string_pretty(run.config())?.as_bytes(),
    )?;
    let pb = smile_app::progress::bar(run.config().total_steps, a.quiet, "steps");
    pb.set_position(run.env_steps());
    let result = expert::train(&mut run, &dir, &mut |ev| match ev {
        Progress::Steps(s) => pb.set_position(s),
        Progress::Episode {
            episodic_return,
            metric,
            sps,
            ..
        } => pb.set_message(format!(
            "sps {sps:.0} return {episodic_return:.2} metric {metric:.3}"
        )),
        Progress::Checkpoint(s) => pb.println(format!("checkpoint at step {s}")),
        _ => {}
    });
    pb.finish_and_clear();
    if result.is_ok()
        && let Some(b) = run.best_eval()
    {
        println!(
            "best periodic evaluation: {:.4} at env step {} (policy-best.safetensors); \
             policy.safetensors holds whichever of it and the final weights evaluated better",
            b.metric, b.env_steps
        );
    }
    if let Err(e) = result {
        let ck = dir.join(trainer::checkpoint::CHECKPOINT_FILE);
        let kept = if ck.exists() {
            format!("; last good checkpoint kept at {}", ck.display())
        } else {
            String::new()
        };
        bail!(
            "training stopped at env step {}: {e}{kept}",
            run.env_steps()
        );
    }
    let env_cfg = EnvConfig {
        horizon: run.config().horizon,
        ..EnvConfig::default()
    };
    let tasks = match (run.config().task_index, run.config().task_value) {
        (None, None) => None,
        _ => Some(run.config().tasks()?),
    };
    finish(&dir, a.eval_episodes, tasks, env_cfg)
}

/// Evaluate the exported expert deterministically (episodes as in training) and write
/// `eval.json`.
fn finish(
    dir: &Path,
    episodes: usize,
    own_tasks: Option<Vec<sim::Task>>,
    env_cfg: EnvConfig,
) -> Result<()> {
    let ex = Expert::load(dir)?;
    let family = ex.family();
    // The expert is evaluated on the plant it was trained on.
    let env_cfg = EnvConfig {
        physics: ex.physics(),
        ..env_cfg
    };
    let (tasks, label) = match own_tasks {
        Some(t) => (t, "its own task"),
        None => (family.test_tasks(), "meta-test tasks"),
    };
    let rep = expert::evaluate(&ex, &tasks, episodes, env_cfg)?;
    let kind = format!("{:?}", family.metric_kind());
    println!(
        "{} expert in {}: {kind} = {:.4}, last-step sample {:.4} (mean over {} {label}, \
         {episodes} deterministic episodes each)",
        ex.name(),
        dir.display(),
        rep.mean,
        rep.final_sample_mean,
        tasks.len()
    );
    let json = serde_json::json!({
        "expert": ex.name(), "env": family.name(), "physics": ex.physics().name(),
        "metric": kind, "report": rep,
        "tasks": tasks.iter().map(|t| t.label()).collect::<Vec<_>>(),
        "episodes_per_task": episodes, "horizon": env_cfg.horizon,
    });
    std::fs::write(
        dir.join("eval.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: super::ExpertArgs,
    }

    #[test]
    fn flags_lie_over_the_config_file_which_lies_over_the_defaults() {
        let file = std::env::temp_dir().join(format!("expert-flags-{}.toml", std::process::id()));
        std::fs::write(
            &file,
            "seed = 3\nlearning_starts = 77\n[sac]\nbatch_size = 32\n",
        )
        .unwrap();
        let cli = Cli::try_parse_from([
            "expert",
            "--config",
            file.to_str().unwrap(),
            "--seed",
            "9",
            "--hidden",
            "64,64",
        ])
        .unwrap();
        let cfg = super::effective_config(&cli.args).unwrap();
        let defaults = trainer::expert::ExpertConfig::default();
        assert_eq!((cfg.seed, cfg.learning_starts), (9, 77));
        assert_eq!(
            (cfg.sac.batch_size, cfg.sac.hidden.clone()),
            (32, vec![64, 64])
        );
        assert_eq!(cfg.sac.actor_lr, defaults.sac.actor_lr);
        assert_eq!(cfg.total_steps, defaults.total_steps);
        std::fs::remove_file(&file).unwrap();
    }
}
