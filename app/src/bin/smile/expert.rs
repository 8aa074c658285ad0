//! `smile expert`: an oracle SAC expert (or the scripted PD expert) for a family.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use sim::{EnvConfig, Family};
use trainer::Progress;
use trainer::expert::{self, Expert, ExpertConfig};
use trainer::run::{ExpertRequest, RunEvent};

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
    /// Continue the run in this directory from its checkpoint (its saved config is used); a
    /// run killed before its first checkpoint starts over with its recorded config. Only
    /// --total-steps may change; the flags that set the config are refused with it.
    #[arg(long, conflicts_with_all = [
        "config", "env", "physics", "seed", "learner_threads", "hidden", "batch_size",
        "learning_starts", "horizon", "task_index", "task_value", "checkpoint_every",
        "eval_every", "keep_best",
    ])]
    resume: Option<PathBuf>,
    /// Total environment steps [default: 30000, or the --config file's; on --resume, the
    /// run's].
    #[arg(long)]
    total_steps: Option<u64>,
    #[command(flatten)]
    learner: crate::train::LearnerFlags,
    /// Minibatch size.
    #[arg(long)]
    batch_size: Option<usize>,
    /// Random-action steps before learning.
    #[arg(long)]
    learning_starts: Option<u64>,
    /// Episode length override (at least 1).
    #[arg(long, value_parser = crate::horizon)]
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
    /// Deterministic evaluation episodes per meta-test task at the end, at least 1 (0 would
    /// write a metric no episode measured).
    #[arg(long, default_value_t = 2, value_parser = crate::positive)]
    eval_episodes: usize,
    /// Evaluate every task's episodes from reset seeds of its own, not the same seeds in every
    /// task: for --kind scripted-linclass, whose 32 tasks x 10 episodes are otherwise 20
    /// distinct walks (it sees the hyperplane only through one of two targets).
    #[arg(long)]
    distinct_starts: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The configuration: the `--config` file over the defaults, each flag given over the file.
fn effective_config(a: &ExpertArgs) -> Result<ExpertConfig> {
    let mut cfg: ExpertConfig = match &a.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            trainer::from_toml_over_defaults(&text)
                .with_context(|| format!("parsing {}", p.display()))?
        }
        None => ExpertConfig::default(),
    };
    cfg.env = a.env.unwrap_or(cfg.env);
    cfg.physics = a.physics.unwrap_or(cfg.physics);
    cfg.total_steps = a.total_steps.unwrap_or(cfg.total_steps);
    cfg.seed = a.learner.seed.unwrap_or(cfg.seed);
    cfg.learner_threads = a
        .learner
        .learner_threads
        .map_or(cfg.learner_threads, usize::from);
    cfg.sac.batch_size = a.batch_size.unwrap_or(cfg.sac.batch_size);
    cfg.learning_starts = a.learning_starts.unwrap_or(cfg.learning_starts);
    cfg.checkpoint_every = a.checkpoint_every.unwrap_or(cfg.checkpoint_every);
    cfg.eval_every = a.eval_every.unwrap_or(cfg.eval_every);
    if let Some(hidden) = &a.learner.hidden {
        cfg.sac.hidden = hidden.clone();
    }
    cfg.horizon = a.horizon.or(cfg.horizon);
    cfg.task_index = a.task_index.or(cfg.task_index);
    cfg.task_value = a.task_value.or(cfg.task_value);
    if a.init_from.is_some() {
        cfg.init_from = a.init_from.clone();
    }
    cfg.keep_best |= a.keep_best;
    if cfg.keep_best && cfg.eval_every == 0 {
        bail!("--keep-best needs evaluations: set --eval-every above 0");
    }
    if a.nominal {
        let Some(nominal) = cfg.env.nominal_task() else {
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
        let env = a.env.unwrap_or(Family::POINT_GOAL);
        if env != Family::POINT_GOAL {
            bail!("the scripted PD expert exists only for point-goal, not {env}");
        }
        let dir = a
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("runs/expert-point-goal-pd"));
        trainer::checkpoint::ensure_fresh_run_dir(&dir)?;
        std::fs::create_dir_all(&dir)?;
        expert::export_scripted_pd(&dir)?;
        return finish(&dir, &a, None, EnvConfig::default());
    }
    if a.kind == ExpertKind::ScriptedLinclass {
        let env = a.env.unwrap_or(Family::ANT_LINCLASS);
        if env != Family::ANT_LINCLASS {
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
        return finish(&dir, &a, None, EnvConfig::default());
    }
    if a.goal_expert.is_some() {
        bail!("--goal-expert is for --kind scripted-linclass");
    }
    let req = match &a.resume {
        Some(dir) => ExpertRequest {
            out: dir.clone(),
            config: None,
            total_steps: a.total_steps,
        },
        None => {
            let cfg = effective_config(&a)?;
            if let (Some(v), [task]) = (cfg.task_value, cfg.tasks()?.as_slice()) {
                // sim's tolerant lookup: 0.4909 names test goal 0.490874 exactly.
                let (label, value) = (task.label(), task.value());
                eprintln!("task value {v}: a per-task expert on {label} (value {value})");
            }
            let nominal = if a.nominal { "-nominal" } else { "" };
            let out = a.out.clone().unwrap_or_else(|| {
                let plant = match cfg.physics {
                    sim::Physics::Rapier => String::new(),
                    other => format!("-{other}"),
                };
                PathBuf::from(format!(
                    "runs/expert-{}{plant}{nominal}-s{}",
                    cfg.env, cfg.seed
                ))
            });
            ExpertRequest {
                out,
                config: Some(cfg),
                total_steps: None,
            }
        }
    };
    let cfg = train(&req, a.quiet)?;
    let env_cfg = EnvConfig {
        horizon: cfg.horizon,
        ..EnvConfig::default()
    };
    let tasks = match (cfg.task_index, cfg.task_value) {
        (None, None) => None,
        _ => Some(cfg.tasks()?),
    };
    finish(&req.out, &a, tasks, env_cfg)
}

/// Trains the run `req` describes, rendering its progress.
fn train(req: &ExpertRequest, quiet: bool) -> Result<ExpertConfig> {
    let mut pb = None;
    let res = trainer::run::train_expert(req, &mut |e| match &e {
        RunEvent::Started { total, done, .. } => {
            let bar = smile_app::progress::bar(*total, quiet, "steps");
            bar.set_position(*done);
            pb = Some(bar);
        }
        RunEvent::Progress(Progress::Steps(s), _) => pb.iter().for_each(|b| b.set_position(*s)),
        RunEvent::Progress(
            Progress::Episode {
                episodic_return,
                metric,
                ..
            },
            _,
        ) => pb
            .iter()
            .for_each(|b| b.set_message(format!("return {episodic_return:.2} metric {metric:.3}"))),
        RunEvent::Progress(Progress::Checkpoint(s), _) => pb
            .iter()
            .for_each(|b| b.println(format!("checkpoint at step {s}"))),
        e => {
            if let Some(line) = smile_app::progress::log_line(e) {
                eprintln!("{line}");
            }
        }
    });
    if let Some(bar) = pb {
        bar.finish_and_clear();
    }
    match (&req.config, res) {
        (
            None,
            Err(e @ (trainer::Error::Checkpoint { .. } | trainer::Error::CheckpointState { .. })),
        ) => Err(anyhow::Error::new(e).context(format!("resuming from {}", req.out.display()))),
        (_, res) => Ok(res?),
    }
}

/// Evaluate the exported expert deterministically (episodes as in training, or from distinct
/// starts) and write `eval.json`.
fn finish(
    dir: &Path,
    a: &ExpertArgs,
    own_tasks: Option<Vec<sim::Task>>,
    env_cfg: EnvConfig,
) -> Result<()> {
    let episodes = a.eval_episodes;
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
    let rep = if a.distinct_starts {
        expert::evaluate_distinct(&ex, &tasks, episodes, env_cfg)?
    } else {
        expert::evaluate(&ex, &tasks, episodes, env_cfg)?
    };
    let kind = format!("{:?}", family.metric_kind());
    println!(
        "{} expert in {}: {kind} = {:.4}, last-step sample {:.4} (mean over {} {label}, \
         {episodes} deterministic episodes each{})",
        ex.name(),
        dir.display(),
        rep.mean,
        rep.final_sample_mean,
        tasks.len(),
        if a.distinct_starts {
            ", from distinct starts"
        } else {
            ""
        }
    );
    let json = serde_json::json!({
        "expert": ex.name(), "env": family.name(), "physics": ex.physics().name(),
        "metric": kind, "report": rep,
        "tasks": tasks.iter().map(|t| t.label()).collect::<Vec<_>>(),
        "episodes_per_task": episodes, "horizon": env_cfg.horizon,
        "distinct_starts": a.distinct_starts,
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
