//! Sets of experts (per-task experts for demos) and deterministic expert evaluation with the
//! family's metric. Re-exported from [`crate::algo::expert`].

use std::path::Path;

use serde::Serialize;
use sim::{EnvConfig, EpisodeMetric, Family, Task};

use super::policy::Expert;
use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::io::checkpoint::POLICY_FILE;

/// The task value a per-task expert was trained on (`smile expert --task-value`, `--nominal`),
/// `None` for a general expert; `path` is a run directory or a policy file.
pub fn trained_task_value(path: &Path) -> Result<Option<f64>> {
    let file = if path.is_dir() {
        path.join(POLICY_FILE)
    } else {
        path.to_path_buf()
    };
    Ok(checkpoint::load(&file)?
        .meta
        .get("task_value")
        .and_then(|v| v.as_f64()))
}

/// The name a run records for point-goal's scripted PD controller as its relabelling expert
/// (and that names it as one).
pub const SCRIPTED_PD: &str = "scripted-pd";

/// Several experts for one family: per-task experts (trained with one task, their policy
/// file records its `task_value`) and at most one general expert. Demos pick, for each task,
/// the per-task expert of that task, else the general one.
#[derive(Debug, Clone)]
pub struct ExpertSet {
    family: Family,
    physics: sim::Physics,
    general: Option<(Expert, String)>,
    per_task: Vec<(Task, Expert, String)>,
}

impl From<Expert> for ExpertSet {
    fn from(e: Expert) -> Self {
        Self {
            family: e.family(),
            physics: e.physics(),
            general: Some((e, "the given expert".into())),
            per_task: Vec::new(),
        }
    }
}

impl ExpertSet {
    /// Meta-DAgger's relabelling expert: the one `given` (a run, a policy file or a folder
    /// of per-task experts), else on point-goal its scripted PD controller (also named by
    /// [`SCRIPTED_PD`]); returns it with a line saying which it is.
    pub(crate) fn relabelling(given: Option<&Path>, family: Family) -> Result<(Self, String)> {
        match given {
            Some(p) if p != Path::new(SCRIPTED_PD) => {
                let set = Self::load(&[p])
                    .map_err(|e| Error::Usage(format!("loading expert {}: {e}", p.display())))?;
                Ok((set, format!("relabelling with the expert {}", p.display())))
            }
            _ if family == Family::POINT_GOAL => {
                let pd = Expert::ScriptedPd(sim::PointGoalPdExpert::default());
                Ok((
                    pd.into(),
                    "relabelling with the scripted point-goal PD expert".into(),
                ))
            }
            _ => Err(Error::input(
                crate::error::Input::Expert,
                format!("meta-dagger on {family} needs an expert to relabel with (an expert run)"),
            )),
        }
    }

    /// Load every path (run directories or policy files) as in [`Expert::load`]. A directory
    /// without a policy file of its own stands for every expert in it (its `*.safetensors`
    /// policy files and run directories, in name order): a folder of per-task experts, e.g.
    /// `assets/experts/walker-dyn/per-task`.
    pub fn load(paths: &[impl AsRef<Path>]) -> Result<Self> {
        let mut set: Option<Self> = None;
        let mut expanded = Vec::new();
        for p in paths {
            expanded.extend(expand_expert_folder(p.as_ref())?);
        }
        for p in &expanded {
            let p = p.as_path();
            let ex = Expert::load(p)?;
            let task_value = trained_task_value(p)?;
            let s = set.get_or_insert_with(|| Self {
                family: ex.family(),
                physics: ex.physics(),
                general: None,
                per_task: Vec::new(),
            });
            if ex.family() != s.family {
                return Err(Error::WrongFamily {
                    what: format!("the expert {}, beside the others", p.display()),
                    found: ex.family(),
                    expected: s.family,
                });
            }
            let what = || format!("the expert {}, beside the others", p.display());
            Error::same_plant(what, ex.physics(), s.physics)?;
            let source = p.display().to_string();
            match task_value {
                // The task it was trained on, as the family's tolerant lookup names it.
                Some(v) => s.per_task.push((s.family.task_named(v)?, ex, source)),
                None if s.general.is_none() => s.general = Some((ex, source)),
                None => {
                    return Err(Error::input(
                        crate::error::Input::Expert,
                        "more than one general expert given: give one, plus per-task experts \
                         (each trained on one task value)",
                    ));
                }
            }
        }
        set.ok_or_else(|| Error::input(crate::error::Input::Expert, "no expert given"))
    }

    /// The family of every expert in the set.
    pub fn family(&self) -> Family {
        self.family
    }

    /// The plant every expert in the set was trained on.
    pub fn physics(&self) -> sim::Physics {
        self.physics
    }

    /// Dataset label: the single expert's name, or `<name>-per-task`.
    pub fn name(&self) -> String {
        match (&self.general, self.per_task.first()) {
            (Some((g, _)), None) => g.name().to_string(),
            (_, Some((_, e, _))) => format!("{}-per-task", e.name()),
            (None, None) => String::new(),
        }
    }

    /// The expert to use in `task`: the per-task expert trained on it (its value within the
    /// family's tolerance, [`Task::same_task`]), else the general one.
    pub fn for_task(&self, task: &Task) -> Result<&Expert> {
        self.chosen(task).map(|(e, _)| e)
    }

    /// Which expert [`ExpertSet::for_task`] uses in `task`, for messages: `runs/e7 (trained on
    /// dynamics_seed=7)` or `runs/e (general expert)`.
    pub fn describe_choice(&self, task: &Task) -> Result<String> {
        self.chosen(task).map(|(_, d)| d)
    }

    fn chosen(&self, task: &Task) -> Result<(&Expert, String)> {
        if let Some((t, e, path)) = self.per_task.iter().find(|(t, _, _)| t.same_task(task)) {
            return Ok((e, format!("{path} (trained on {})", t.label())));
        }
        if let Some((e, path)) = &self.general {
            return Ok((e, format!("{path} (general expert)")));
        }
        let trained: Vec<String> = self.per_task.iter().map(|(t, _, _)| t.label()).collect();
        Err(Error::input(
            crate::error::Input::Expert,
            format!(
                "no expert for task {}: the per-task experts were trained on {}; add its expert \
                 or a general one",
                task.label(),
                trained.join(", ")
            ),
        ))
    }
}

/// `path` itself, or for a folder of experts (a directory without `policy.safetensors`) the
/// experts in it, sorted by name; an empty folder is an error.
fn expand_expert_folder(path: &Path) -> Result<Vec<std::path::PathBuf>> {
    // A run directory: itself (an unfinished one is named as such by `Expert::load`).
    let ckpt = crate::io::checkpoint::CHECKPOINT_FILE;
    if !path.is_dir() || path.join(POLICY_FILE).exists() || path.join(ckpt).exists() {
        return Ok(vec![path.to_path_buf()]);
    }
    let io = Error::io(path);
    let mut found = Vec::new();
    for entry in std::fs::read_dir(path).map_err(io)? {
        let p = entry.map_err(io)?.path();
        let policy_file = p.is_file() && p.extension().is_some_and(|e| e == "safetensors");
        if policy_file || p.join(POLICY_FILE).is_file() {
            found.push(p);
        }
    }
    if found.is_empty() {
        return Err(Error::Usage(format!(
            "{} holds no expert: give an expert run directory, its {POLICY_FILE}, or a \
             folder of them",
            path.display()
        )));
    }
    found.sort();
    Ok(found)
}

/// Result of [`evaluate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalReport {
    /// Per task: the family's metric averaged over episodes.
    pub per_task: Vec<f32>,
    /// Mean of `per_task`.
    pub mean: f32,
    /// Mean over all episodes of the metric sample at the last step (for point-goal: the final
    /// distance to the goal; for cheetah-vel: the final |v - v*|; for ant-linclass: the
    /// latched decision, so P(correct) - P(wrong)).
    pub final_sample_mean: f32,
}

/// The family's metric over `tasks`, `episodes` deterministic rollouts each (reset seeds
/// `1_000_000 + k`, the same in every task).
pub fn evaluate(
    expert: &Expert,
    tasks: &[Task],
    episodes: usize,
    env_cfg: EnvConfig,
) -> Result<EvalReport> {
    evaluate_under_noise(expert, tasks, episodes, env_cfg, 0.0)
}

/// [`evaluate`] with reset seeds of each task's own ([`eval_seed`] with `distinct_starts`), as
/// demos' distinct starts. Where the task reaches an expert only through a few choices, the
/// same seeds in every task walk the same walks: ant-linclass's scripted expert sees its
/// hyperplane only through one of two targets, so [`evaluate`]'s 32 tasks x 10 episodes are 20
/// distinct walks, and these are 320.
pub fn evaluate_distinct(
    expert: &Expert,
    tasks: &[Task],
    episodes: usize,
    env_cfg: EnvConfig,
) -> Result<EvalReport> {
    evaluate_episodes(expert, tasks, episodes, env_cfg, 0.0, true)
}

/// [`evaluate`] with Gaussian noise of standard deviation `action_noise` added to every
/// action before the plant clips it (`ActionNoise`, seeded by the reset seed).
pub fn evaluate_under_noise(
    expert: &Expert,
    tasks: &[Task],
    episodes: usize,
    env_cfg: EnvConfig,
    action_noise: f32,
) -> Result<EvalReport> {
    evaluate_episodes(expert, tasks, episodes, env_cfg, action_noise, false)
}

/// The reset seed of an expert evaluation's episode `k` of task `task` (of `episodes` a
/// task): `1_000_000 + k` in every task, or with `distinct_starts` `1_000_000 + task *
/// episodes + k`.
pub fn eval_seed(task: usize, k: usize, episodes: usize, distinct_starts: bool) -> u64 {
    let first = if distinct_starts { task * episodes } else { 0 };
    sim::seeds::EXPERT_EVAL_SEED + (first + k) as u64
}

/// The evaluation, episode `k` of task `i` reset with [`eval_seed`].
fn evaluate_episodes(
    expert: &Expert,
    tasks: &[Task],
    episodes: usize,
    env_cfg: EnvConfig,
    action_noise: f32,
    distinct_starts: bool,
) -> Result<EvalReport> {
    let family = expert.family();
    let what = || format!("the {} expert", expert.name());
    Error::same_plant(what, expert.physics(), env_cfg.physics)?;
    let mut env = sim::make_env(family, env_cfg)?;
    let mut oracle = vec![0.0f32; family.oracle_obs_dim()];
    let mut action = vec![0.0f32; family.act_dim()];
    let mut per_task = Vec::with_capacity(tasks.len());
    let (mut final_sum, mut n) = (0.0f32, 0usize);
    for (i, task) in tasks.iter().enumerate() {
        let mut sum = 0.0f32;
        for k in 0..episodes {
            let seed = eval_seed(i, k, episodes, distinct_starts);
            env.reset(task, seed)?;
            let mut noise = crate::data::ActionNoise::new(action_noise, seed);
            let mut m = EpisodeMetric::new(family);
            loop {
                env.oracle_observation(&mut oracle)?;
                expert.act(&oracle, &mut action)?;
                noise.add_to(&mut action);
                let tr = env.step(&action)?;
                m.record(&tr.info);
                if tr.done {
                    final_sum += tr.info.metric_sample;
                    n += 1;
                    break;
                }
            }
            sum += m.value();
        }
        per_task.push(sum / episodes.max(1) as f32);
    }
    let mean = per_task.iter().sum::<f32>() / per_task.len().max(1) as f32;
    Ok(EvalReport {
        per_task,
        mean,
        final_sample_mean: final_sum / n.max(1) as f32,
    })
}
