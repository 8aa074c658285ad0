//! Evaluation with the paper's protocols (reference §5), on a split's tasks with contexts from
//! a demo file: deterministic actions, z = posterior mean.
//!
//! | family | context sizes | draws x rollouts | per-episode metric |
//! |---|---|---|---|
//! | point-goal | 1 | 3 x 10 | min distance to the goal |
//! | cheetah-vel | 1, 2, 3, 4 | 3 x 5 | mean over steps of abs(v - v*) |
//! | walker-dyn | 1 | 3 x 1 | return; with a base and expert(s) also the normalised metric |
//! | ant-goal | 1 | 3 x 10 | min distance of the torso to the goal |
//! | ant-linclass | 1, 2, 4, 8 | 3 x 5 | success (1 correct target first, else 0); also the no-op rate |
//!
//! Draw `d` of size `k` for task `i` uses `k` distinct trajectories chosen by a seeded RNG
//! (seed from `(i, k, d)`), so every method sees the same contexts; rollout `r` of draw `d`
//! resets with [`episode_seed`]`(d, r)`. Outputs: JSON ([`EvalReport`]), a markdown table and
//! an SVG plot (metric per task, one line per method).
//!
//! walker-dyn's normalised metric (Table 2 left): per test task the returns R_base of a policy
//! trained on the unmodified dynamics and R_expert of the task's expert, rolled out
//! deterministically with the same episode seeds and horizon as the methods
//! ([`norm`]); per method the mean over tasks with R_expert > R_base of
//! (R_pi - R_base) / (R_expert - R_base) ([`normalised_score`]), the other tasks skipped and
//! counted.

use std::path::Path;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sim::{DemoDataset, EnvConfig, Family, MetricKind, Physics, Split, Task, Trajectory};

use crate::data::{ActionNoise, run_episode};
use crate::error::{Error, Result};

pub use crate::model::ConditionedActor;

/// Context sizes, draws and rollouts of a family's protocol.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Protocol {
    /// Context sizes (trajectories per context).
    pub context_sizes: Vec<usize>,
    /// Context draws per size.
    pub draws: usize,
    /// Deterministic rollouts per draw.
    pub rollouts: usize,
    /// Episode length override (None: the family's horizon).
    #[serde(default)]
    pub horizon: Option<usize>,
    /// Standard deviation of Gaussian noise added to every action before the plant clips it
    /// (a robustness probe of compounding error; 0, the paper's protocol, adds none). Drawn
    /// from a stream seeded by the episode's seed, so evaluations repeat exactly.
    #[serde(default)]
    pub action_noise: f32,
    /// walker-dyn: the SMILe authors' walker evaluation (their `terminal = False`): every
    /// episode runs the whole horizon and the alive bonus keeps accruing after a fall, so
    /// returns compare with the paper's. false, this project's protocol: a fall ends the
    /// episode. Reports record which one made them (the field is written only when true, so
    /// reports of this project's protocol read as they did before it existed).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub run_through_falls: bool,
    /// The plant the episodes run on: the physics the policy was trained on (`smile eval` takes
    /// it from the checkpoint and refuses demos of another plant). Reports record it.
    #[serde(default)]
    pub physics: Physics,
}

impl Protocol {
    /// The episode options of this protocol.
    pub fn env_config(&self) -> EnvConfig {
        EnvConfig {
            horizon: self.horizon,
            healthy_termination: !self.run_through_falls,
            physics: self.physics,
        }
    }

    /// The protocol's name in reports: which walker evaluation made the numbers.
    pub fn label(&self) -> &'static str {
        if self.run_through_falls {
            "authors' (episodes run through falls)"
        } else {
            "falls end episodes"
        }
    }

    /// The reference protocol of `family` (§5), from its spec ([`sim::EvalDefaults`]).
    pub fn for_family(family: Family) -> Self {
        let defaults = family.spec().eval;
        Self {
            context_sizes: defaults.context_sizes.to_vec(),
            draws: defaults.draws,
            rollouts: defaults.rollouts,
            horizon: None,
            action_noise: 0.0,
            run_through_falls: false,
            physics: Physics::Rapier,
        }
    }
}

/// One task's result for one method: the export report's rows are the same type.
pub use sim::TaskResult;

/// One method's results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// Display name (algorithm and run directory).
    pub name: String,
    /// Per task.
    pub tasks: Vec<TaskResult>,
    /// Mean over tasks.
    pub mean: f32,
    /// Std over tasks.
    pub std_over_tasks: f32,
    /// Mean and std over all episodes (pooled), as the paper's Table 1.
    pub episode_mean: f32,
    /// Std over all episodes.
    pub episode_std: f32,
    /// Mean over tasks per context size.
    pub by_context_size: Vec<f32>,
    /// Classification families: the no-op rate (episodes without a decision), mean over tasks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_op_rate: Option<f32>,
    /// Classification families: the no-op rate per context size, mean over tasks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_op_by_context_size: Option<Vec<f32>>,
    /// walker-dyn's normalised metric, when the evaluation had reference returns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalised: Option<NormalisedScore>,
}

/// Per-task returns of the normalised metric's reference policies, in the order of the
/// methods' tasks, over the same episode seeds and horizon as the methods.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceReturns {
    /// The base policy (trained on the unmodified dynamics).
    pub base: String,
    /// The expert(s).
    pub expert: String,
    /// R_base per task.
    pub base_returns: Vec<f32>,
    /// R_expert per task.
    pub expert_returns: Vec<f32>,
    /// The task parameters, in the same order (checked against the methods' tasks).
    #[serde(default)]
    pub task_values: Vec<f64>,
    /// Mean episode length of the base per task (a walker's survival: a fall ends the
    /// episode before the horizon).
    #[serde(default)]
    pub base_steps: Vec<f32>,
    /// Mean episode length of the expert per task.
    #[serde(default)]
    pub expert_steps: Vec<f32>,
}

impl ReferenceReturns {
    /// Mean R_base over the tasks.
    pub fn base_mean(&self) -> f32 {
        mean_std(&self.base_returns).0
    }

    /// Mean R_expert over the tasks.
    pub fn expert_mean(&self) -> f32 {
        mean_std(&self.expert_returns).0
    }
}

/// One method's normalised score, (R_pi - R_base) / (R_expert - R_base) averaged over the tasks
/// where R_expert > R_base.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalisedScore {
    /// Mean over the tasks used; `None` when every task was skipped.
    pub score: Option<f32>,
    /// Per task; `None` where the task was skipped.
    pub per_task: Vec<Option<f32>>,
    /// Tasks with R_expert > R_base.
    pub tasks_used: usize,
    /// Tasks with R_expert <= R_base (or a non-finite reference return).
    pub tasks_skipped: usize,
}

/// The normalised metric of one method from per-task returns (all three in the same task
/// order): tasks where the expert is not better than the base are skipped, as in the paper
/// (equal returns would divide by zero).
pub fn normalised_score(method: &[f32], base: &[f32], expert: &[f32]) -> Result<NormalisedScore> {
    if method.len() != base.len() || method.len() != expert.len() {
        return Err(Error::Shape(format!(
            "normalised metric: {} method returns, {} base returns, {} expert returns",
            method.len(),
            base.len(),
            expert.len()
        )));
    }
    if let Some(r) = method.iter().find(|r| !r.is_finite()) {
        return Err(Error::Data(format!(
            "normalised metric: a method return is {r}; every episode must have a finite return"
        )));
    }
    // `>` is false for NaN, so a non-finite reference return also skips the task.
    let per_task: Vec<Option<f32>> = (method.iter().zip(base).zip(expert))
        .map(|((&r, &b), &e)| (e > b && e.is_finite() && b.is_finite()).then(|| (r - b) / (e - b)))
        .collect();
    let used: Vec<f32> = per_task.iter().flatten().copied().collect();
    Ok(NormalisedScore {
        score: (!used.is_empty()).then(|| mean_std(&used).0),
        tasks_used: used.len(),
        tasks_skipped: per_task.len() - used.len(),
        per_task,
    })
}

/// Reset seed of rollout `rollout` of context draw `draw` (every context size reuses them);
/// the reference policies of the normalised metric reuse them too, so all face the same
/// initial states.
pub fn episode_seed(draw: usize, rollout: usize) -> u64 {
    sim::seeds::EVALUATION_SEED + (draw * 1000 + rollout) as u64
}

/// A whole evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The family (by its name in the file).
    pub env: Family,
    /// Split evaluated.
    pub split: String,
    /// Metric name.
    pub metric: String,
    /// True if lower is better.
    pub lower_is_better: bool,
    /// The protocol used.
    pub protocol: Protocol,
    /// One entry per method.
    pub methods: Vec<MethodResult>,
    /// The normalised metric's reference returns (walker-dyn with `--base` and `--expert`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceReturns>,
}

/// Metric name of a family.
pub fn metric_name(kind: MetricKind) -> &'static str {
    match kind {
        MetricKind::MinGoalDistance => "min distance to goal",
        MetricKind::MeanVelocityError => "mean |v - v*|",
        MetricKind::Return => "return",
        MetricKind::ClassificationSuccess => "success rate",
    }
}

/// How a run is named in reports: `label (run directory name)`, e.g. `smile (smile-s0)`.
pub fn display_name(label: &str, path: &Path) -> String {
    let dir = path
        .file_name()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    format!("{label} ({dir})")
}

/// Mean and (population) standard deviation of `xs`; NaN for none.
pub fn mean_std(xs: &[f32]) -> (f32, f32) {
    if xs.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    let n = xs.len() as f64;
    let m = xs.iter().map(|x| *x as f64).sum::<f64>() / n;
    let v = xs.iter().map(|x| (*x as f64 - m).powi(2)).sum::<f64>() / n;
    (m as f32, v.sqrt() as f32)
}

/// Draw `d` of size `k` for task `i`: `k` distinct trajectories of `trajs` chosen by a RNG
/// seeded from `(i, k, d)`, so every method (and [`latents`]) sees the same contexts.
pub fn context_draw<'a>(
    trajs: &[&'a Trajectory],
    i: usize,
    k: usize,
    d: usize,
) -> Vec<&'a Trajectory> {
    let mut rng = ChaCha8Rng::seed_from_u64(((i as u64) << 32) ^ ((k as u64) << 16) ^ d as u64);
    let mut pick = trajs.to_vec();
    pick.shuffle(&mut rng);
    pick.truncate(k.min(trajs.len()));
    pick
}

/// The demos of each of `tasks`, from `contexts`; errors on a missing task or wrong family.
pub fn contexts_for<'a>(
    contexts: &'a DemoDataset,
    family: Family,
    tasks: &[Task],
) -> Result<Vec<&'a sim::TaskDemos>> {
    contexts.ensure_family(family)?;
    tasks
        .iter()
        .map(|t| {
            let i = family
                .find_task(t.value(), contexts.tasks.iter().map(|td| &td.task))
                .map_err(|e| {
                    Error::Data(format!(
                        "the contexts file has no demos for task {}: {e}",
                        t.label()
                    ))
                })?;
            let td = &contexts.tasks[i];
            if td.trajectories.iter().all(|tr| tr.is_empty()) {
                return Err(Error::Data(format!(
                    "the contexts file's demos of task {} are empty",
                    t.label()
                )));
            }
            Ok(td)
        })
        .collect()
}

/// Evaluates `actor` on `family`'s `split` tasks with contexts from `contexts`.
/// `on_task(i, n)` reports progress.
pub fn evaluate(
    actor: &mut dyn ConditionedActor,
    name: &str,
    family: Family,
    split: Split,
    contexts: &DemoDataset,
    protocol: &Protocol,
    on_task: &mut dyn FnMut(usize, usize),
) -> Result<MethodResult> {
    let tasks = family.tasks(split);
    evaluate_tasks(actor, name, family, &tasks, contexts, protocol, on_task)
}

/// One task's evaluation: its result, every episode's metric, and (a classifying family) the
/// no-op rate per context size.
struct TaskEvaluation {
    result: TaskResult,
    episodes: Vec<f32>,
    no_op_by_k: Option<Vec<f32>>,
}

/// Task number `i` under `protocol`: for each context size, `draws` contexts drawn from
/// `trajs`, `rollouts` episodes each from their fixed seeds.
fn evaluate_task(
    actor: &mut dyn ConditionedActor,
    env: &mut dyn sim::Environment,
    protocol: &Protocol,
    task: &Task,
    i: usize,
    trajs: &[&Trajectory],
) -> Result<TaskEvaluation> {
    let mut by_k = Vec::with_capacity(protocol.context_sizes.len());
    let mut no_op_by_k = Vec::with_capacity(protocol.context_sizes.len());
    let mut task_eps = Vec::new();
    let mut task_no_ops = Vec::new();
    for &k in &protocol.context_sizes {
        let mut eps = Vec::new();
        let mut no_ops = Vec::new();
        for d in 0..protocol.draws {
            let z = actor.latent(&context_draw(trajs, i, k, d))?;
            for r in 0..protocol.rollouts {
                let seed = episode_seed(d, r);
                let mut noise = ActionNoise::new(protocol.action_noise, seed);
                let ep = run_episode(
                    env,
                    task,
                    seed,
                    &mut |o, a| {
                        actor.act(o, &z, a)?;
                        noise.add_to(a);
                        Ok(())
                    },
                    &mut |_| Ok(()),
                )?;
                eps.push(ep.metric);
                no_ops.extend(ep.no_op.map(|n| if n { 1.0 } else { 0.0 }));
            }
        }
        by_k.push(mean_std(&eps).0);
        task_eps.extend(eps);
        no_op_by_k.push(mean_std(&no_ops).0);
        task_no_ops.extend(no_ops);
    }
    let classifies = !task_no_ops.is_empty();
    Ok(TaskEvaluation {
        result: TaskResult {
            task: task.label(),
            value: task.value(),
            metric: mean_std(&task_eps).0,
            by_context_size: by_k,
            no_op_rate: classifies.then(|| mean_std(&task_no_ops).0),
        },
        episodes: task_eps,
        no_op_by_k: classifies.then_some(no_op_by_k),
    })
}

/// [`evaluate`] on the given `tasks` (a split's, or the contexts file's own new tasks).
pub fn evaluate_tasks(
    actor: &mut dyn ConditionedActor,
    name: &str,
    family: Family,
    tasks: &[Task],
    contexts: &DemoDataset,
    protocol: &Protocol,
    on_task: &mut dyn FnMut(usize, usize),
) -> Result<MethodResult> {
    let what = || "the context demos".into();
    Error::same_plant(what, contexts.physics, protocol.physics)?;
    let demos = contexts_for(contexts, family, tasks)?;
    let mut env = sim::make_env(family, protocol.env_config())?;
    let mut results = Vec::with_capacity(tasks.len());
    let mut no_op_rows: Vec<Option<Vec<f32>>> = Vec::with_capacity(tasks.len());
    let mut all = Vec::new();
    for (i, (task, td)) in tasks.iter().zip(&demos).enumerate() {
        let trajs: Vec<&Trajectory> = td.trajectories.iter().filter(|t| !t.is_empty()).collect();
        let one = evaluate_task(actor, env.as_mut(), protocol, task, i, &trajs)?;
        all.extend_from_slice(&one.episodes);
        results.push(one.result);
        no_op_rows.push(one.no_op_by_k);
        on_task(i + 1, tasks.len());
    }
    let per_task: Vec<f32> = results.iter().map(|t| t.metric).collect();
    let (mean, std_over_tasks) = mean_std(&per_task);
    let (episode_mean, episode_std) = mean_std(&all);
    let by_context_size = (0..protocol.context_sizes.len())
        .map(|j| {
            mean_std(
                &results
                    .iter()
                    .map(|t| t.by_context_size[j])
                    .collect::<Vec<_>>(),
            )
            .0
        })
        .collect();
    // Per context size, the mean over tasks of the tasks' no-op rates.
    let no_op_rows: Option<Vec<Vec<f32>>> = no_op_rows.into_iter().collect();
    let no_op_by_context_size = no_op_rows.filter(|r| !r.is_empty()).map(|rows| {
        (0..protocol.context_sizes.len())
            .map(|j| mean_std(&rows.iter().map(|r| r[j]).collect::<Vec<_>>()).0)
            .collect()
    });
    let no_op_rate = results
        .iter()
        .map(|t| t.no_op_rate)
        .collect::<Option<Vec<f32>>>()
        .filter(|r| !r.is_empty())
        .map(|r| mean_std(&r).0);
    Ok(MethodResult {
        name: name.into(),
        tasks: results,
        mean,
        std_over_tasks,
        episode_mean,
        episode_std,
        by_context_size,
        no_op_rate,
        no_op_by_context_size,
        normalised: None,
    })
}

impl EvalReport {
    /// A report of `methods` evaluated on `family`'s `split` with `protocol`.
    pub fn new(
        family: Family,
        split: Split,
        protocol: Protocol,
        methods: Vec<MethodResult>,
    ) -> Self {
        Self {
            env: family,
            split: split.to_string(),
            metric: metric_name(family.metric_kind()).into(),
            lower_is_better: family.metric_kind().lower_is_better(),
            protocol,
            methods,
            reference: None,
        }
    }

    /// Adds the normalised metric: stores `reference` and scores every method against it.
    pub fn with_reference(mut self, reference: ReferenceReturns) -> Result<Self> {
        if self.lower_is_better {
            return Err(Error::Data(format!(
                "the normalised metric needs returns; {} reports {}",
                self.env, self.metric
            )));
        }
        for m in &mut self.methods {
            let values: Vec<f64> = m.tasks.iter().map(|t| t.value).collect();
            if !reference.task_values.is_empty() && reference.task_values != values {
                return Err(Error::Shape(format!(
                    "reference returns are for tasks {:?}, {} was evaluated on {values:?}",
                    reference.task_values, m.name
                )));
            }
            let returns: Vec<f32> = m.tasks.iter().map(|t| t.metric).collect();
            m.normalised = Some(normalised_score(
                &returns,
                &reference.base_returns,
                &reference.expert_returns,
            )?);
        }
        self.reference = Some(reference);
        Ok(self)
    }
}

/// Rolls `actor` once on `task` with the first `k` trajectories of `context` and writes the
/// episode as an animated SVG at `path`.
pub fn render_episode(
    actor: &mut dyn ConditionedActor,
    family: Family,
    task: &Task,
    context: &[&Trajectory],
    env_cfg: EnvConfig,
    path: &Path,
) -> Result<f32> {
    let mut env = sim::make_env(family, env_cfg)?;
    let z = actor.latent(context)?;
    env.reset(task, sim::seeds::EVALUATION_SEED)?;
    let mut frames = vec![env.frame()];
    let mut metric = sim::EpisodeMetric::new(family);
    let mut action = vec![0.0f32; family.act_dim()];
    loop {
        let obs = env.observation().to_vec();
        actor.act(&obs, &z, &mut action)?;
        let tr = env.step(&action)?;
        metric.record(&tr.info);
        let done = tr.done;
        frames.push(env.frame());
        if done {
            break;
        }
    }
    sim::render::write_animated_svg(&frames, env.control_dt(), path).map_err(Error::io(path))?;
    Ok(metric.value())
}

pub mod blob;
pub mod latents;
pub mod linclass;
pub mod norm;
mod request;
mod show;

pub use request::{EvalEvent, EvalRequest, evaluate_to_dir, write_report};

#[cfg(test)]
mod tests;
