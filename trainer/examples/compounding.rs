//! The paper's compounding-error argument on one plant: an expert and a meta-policy evaluated
//! under Gaussian action noise of growing sigma, over the family's full episodes.
//!
//! ```sh
//! cargo run --release -p trainer --example compounding -- \
//!   --expert assets/experts/cheetah-vel --policy runs/cv-bc \
//!   --contexts assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors \
//!   --sigmas 0,0.1,0.3 --rollouts 2 -o runs/compounding.json
//! ```
//!
//! For each sigma: the expert's metric on the meta-test tasks (`--rollouts` episodes each, the
//! expert's own evaluation seeds, as `evaluate_under_noise`) and the meta-policy's (one-demo
//! contexts, one draw, `--rollouts` episodes per task, as `smile eval`), as JSON and as a
//! markdown table on stdout; and how far each drifts from the expert's state distribution
//! along the episode: per step, the distance from the state to the nearest state of clean
//! expert episodes of the same task (standardised observations), by fifth of the episode.

use std::path::PathBuf;
use std::process::ExitCode;

use serde_json::json;
use sim::{DemoDataset, EnvConfig, Environment, Split, Task, Trajectory};
use trainer::eval::{self, ConditionedActor};
use trainer::expert::Expert;
use trainer::{ActFn, ActionNoise, MetaPolicy, run_episode};

struct Args {
    expert: PathBuf,
    policy: PathBuf,
    contexts: PathBuf,
    sigmas: Vec<f32>,
    rollouts: usize,
    out: Option<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut expert, mut policy, mut contexts, mut out) = (None, None, None, None);
    let (mut sigmas, mut rollouts) = (vec![0.0, 0.1, 0.3], 2);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--expert" => expert = Some(PathBuf::from(value)),
            "--policy" => policy = Some(PathBuf::from(value)),
            "--contexts" => contexts = Some(PathBuf::from(value)),
            "-o" | "--out" => out = Some(PathBuf::from(value)),
            "--rollouts" => {
                rollouts = value
                    .parse()
                    .ok()
                    .filter(|&r| r > 0)
                    .ok_or(format!("--rollouts {value}: expected a positive count"))?
            }
            "--sigmas" => {
                sigmas = value
                    .split(',')
                    .map(|s| {
                        s.parse::<f32>()
                            .ok()
                            .filter(|x| x.is_finite() && *x >= 0.0)
                            .ok_or(format!("--sigmas: `{s}` is not a standard deviation"))
                    })
                    .collect::<Result<_, _>>()?
            }
            other => return Err(format!("unknown flag {other}")),
        }
    }
    Ok(Args {
        expert: expert.ok_or("--expert is required")?,
        policy: policy.ok_or("--policy is required")?,
        contexts: contexts.ok_or("--contexts is required")?,
        sigmas,
        rollouts,
        out,
    })
}

/// Clean expert episodes per task whose states are the reference distribution (their own
/// seeds, so the expert's sigma-0 row measures the spread between two clean episodes).
const REFERENCE_EPISODES: u64 = 4;
const REFERENCE_SEED: u64 = sim::seeds::EXPERT_EVAL_SEED + 10_000;
/// Windows of the episode the drift is reported over (the horizon cut into equal parts).
const WINDOWS: usize = 5;

/// One policy's episodes at one sigma: the family's metric and the drift along the episode.
struct Measured {
    metric: f32,
    /// Mean nearest-reference distance over every step of every episode.
    drift: f32,
    /// The same per window of the horizon.
    drift_by_window: Vec<f32>,
}

/// The expert's state distribution per task, in standardised coordinates.
struct Reference {
    mean: Vec<f32>,
    inv_std: Vec<f32>,
    /// Per task, its reference states (standardised), one row of `obs_dim` each.
    states: Vec<Vec<f32>>,
}

impl Reference {
    fn new(raw: Vec<Vec<f32>>, obs_dim: usize) -> Self {
        let n = raw.iter().map(|s| s.len() / obs_dim).sum::<usize>().max(1) as f64;
        let mut mean = vec![0.0f64; obs_dim];
        let mut sq = vec![0.0f64; obs_dim];
        for row in raw.iter().flat_map(|s| s.chunks_exact(obs_dim)) {
            for (j, &x) in row.iter().enumerate() {
                mean[j] += x as f64 / n;
                sq[j] += (x as f64) * (x as f64) / n;
            }
        }
        // A dimension that does not vary in the reference (a constant) is left unscaled.
        let inv_std: Vec<f32> = mean
            .iter()
            .zip(&sq)
            .map(|(m, q)| (q - m * m).max(0.0).sqrt())
            .map(|s| if s > 1e-6 { (1.0 / s) as f32 } else { 1.0 })
            .collect();
        let mean: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
        let mut r = Self {
            mean,
            inv_std,
            states: Vec::new(),
        };
        r.states = raw.into_iter().map(|s| r.standardise(&s)).collect();
        r
    }

    fn standardise(&self, raw: &[f32]) -> Vec<f32> {
        let d = self.mean.len();
        raw.chunks_exact(d)
            .flat_map(|row| {
                row.iter()
                    .zip(self.mean.iter().zip(&self.inv_std))
                    .map(|(x, (m, i))| (x - m) * i)
            })
            .collect()
    }

    /// Distance from each state of `episode` (raw, row-major) to its nearest reference state
    /// of task `task`.
    fn distances(&self, task: usize, episode: &[f32]) -> Vec<f32> {
        let d = self.mean.len();
        let reference = &self.states[task];
        self.standardise(episode)
            .chunks_exact(d)
            .map(|s| {
                reference
                    .chunks_exact(d)
                    .map(|r| r.iter().zip(s).map(|(a, b)| (a - b) * (a - b)).sum::<f32>())
                    .fold(f32::INFINITY, f32::min)
                    .sqrt()
            })
            .collect()
    }
}

/// One episode's observations (before each step, row-major) and its metric.
fn episode(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    act: &mut ActFn<'_>,
) -> trainer::Result<(f32, Vec<f32>)> {
    let mut states = Vec::with_capacity(env.horizon() * env.obs_dim());
    let ep = run_episode(env, task, seed, act, &mut |s| {
        states.extend_from_slice(s.obs);
        Ok(())
    })?;
    Ok((ep.metric, states))
}

/// The expert acting on the oracle observation (observation, then the task's parameter).
fn expert_act<'a>(
    expert: &'a Expert,
    task: &'a Task,
    oracle: &'a mut [f32],
    noise: &'a mut ActionNoise,
) -> impl FnMut(&[f32], &mut [f32]) -> trainer::Result<()> + 'a {
    move |obs, action| {
        let n = obs.len();
        oracle[..n].copy_from_slice(obs);
        task.write_parameter(&mut oracle[n..])?;
        expert.act(oracle, action)?;
        noise.add_to(action);
        Ok(())
    }
}

/// Metric and drift over `episodes` (task index, metric, states).
fn measure(reference: &Reference, episodes: &[(usize, f32, Vec<f32>)], horizon: usize) -> Measured {
    let per_window = horizon.div_ceil(WINDOWS).max(1);
    let (mut sum, mut n) = (0.0f64, 0usize);
    let mut windows = [(0.0f64, 0usize); WINDOWS];
    for (task, _, states) in episodes {
        for (t, d) in reference.distances(*task, states).into_iter().enumerate() {
            sum += d as f64;
            n += 1;
            let w = &mut windows[(t / per_window).min(WINDOWS - 1)];
            w.0 += d as f64;
            w.1 += 1;
        }
    }
    // The metric as the evaluation reports it: per task the mean over its episodes, then the
    // mean over tasks.
    let tasks = reference.states.len();
    let per_task: Vec<f32> = (0..tasks)
        .map(|i| {
            let m: Vec<f32> = episodes.iter().filter(|e| e.0 == i).map(|e| e.1).collect();
            eval::mean_std(&m).0
        })
        .collect();
    Measured {
        metric: eval::mean_std(&per_task).0,
        drift: (sum / n.max(1) as f64) as f32,
        drift_by_window: windows
            .iter()
            .map(|(s, c)| (s / (*c).max(1) as f64) as f32)
            .collect(),
    }
}

/// The reference: clean expert episodes of every test task.
fn reference(
    env: &mut dyn sim::Environment,
    expert: &Expert,
    tasks: &[sim::Task],
) -> trainer::Result<Reference> {
    let mut oracle = vec![0.0f32; expert.family().oracle_obs_dim()];
    let mut raw = Vec::with_capacity(tasks.len());
    for task in tasks {
        let mut states = Vec::new();
        for k in 0..REFERENCE_EPISODES {
            let mut noise = ActionNoise::new(0.0, 0);
            let mut act = expert_act(expert, task, &mut oracle, &mut noise);
            states.extend(episode(env, task, REFERENCE_SEED + k, &mut act)?.1);
        }
        raw.push(states);
    }
    Ok(Reference::new(raw, env.obs_dim()))
}

fn run(a: &Args) -> trainer::Result<serde_json::Value> {
    trainer::threads::set_compute_threads(1);
    let expert = Expert::load(&a.expert)?;
    let mut policy = MetaPolicy::load(&a.policy)?;
    let contexts = DemoDataset::read(&a.contexts)?;
    let family = expert.family();
    let tasks = family.tasks(Split::Test);
    // Each on its own plant: the expert's and the policy's (the same one, or an error).
    if policy.physics != expert.physics() || contexts.physics != expert.physics() {
        return Err(trainer::Error::WrongPhysics {
            what: "the meta-policy or its contexts".into(),
            found: policy.physics,
            expected: expert.physics(),
        });
    }
    let plant = EnvConfig {
        physics: expert.physics(),
        ..EnvConfig::default()
    };
    let mut env = sim::make_env(family, plant)?;
    let horizon = env.horizon();
    let mut oracle = vec![0.0f32; family.oracle_obs_dim()];

    let reference = reference(env.as_mut(), &expert, &tasks)?;

    // The meta-policy's context: each task's first one-demo draw, as `smile eval` makes it.
    let demos = eval::contexts_for(&contexts, family, &tasks)?;
    let mut latents = Vec::with_capacity(tasks.len());
    for (i, td) in demos.iter().enumerate() {
        let trajs: Vec<&Trajectory> = td.trajectories.iter().filter(|t| !t.is_empty()).collect();
        latents.push(policy.latent(&eval::context_draw(&trajs, i, 1, 0))?);
    }

    let mut rows = Vec::new();
    println!(
        "| sigma | expert | expert drift | meta-policy | meta-policy drift | drift by fifth of the episode (meta-policy) |\n|---|---|---|---|---|---|"
    );
    for &sigma in &a.sigmas {
        let (mut by_expert, mut by_policy) = (Vec::new(), Vec::new());
        for (i, task) in tasks.iter().enumerate() {
            for r in 0..a.rollouts {
                // The expert's own evaluation seeds, as `evaluate_under_noise`.
                let seed = sim::seeds::EXPERT_EVAL_SEED + r as u64;
                let mut noise = ActionNoise::new(sigma, seed);
                let mut act = expert_act(&expert, task, &mut oracle, &mut noise);
                let (m, s) = episode(env.as_mut(), task, seed, &mut act)?;
                by_expert.push((i, m, s));
                // The meta-policy's evaluation seeds, as `smile eval` (draw 0).
                let seed = eval::episode_seed(0, r);
                let mut noise = ActionNoise::new(sigma, seed);
                let z = &latents[i];
                let mut act = |o: &[f32], a: &mut [f32]| -> trainer::Result<()> {
                    ConditionedActor::act(&mut policy, o, z, a)?;
                    noise.add_to(a);
                    Ok(())
                };
                let (m, s) = episode(env.as_mut(), task, seed, &mut act)?;
                by_policy.push((i, m, s));
            }
        }
        let e = measure(&reference, &by_expert, horizon);
        let p = measure(&reference, &by_policy, horizon);
        let windows: Vec<String> = p
            .drift_by_window
            .iter()
            .map(|d| format!("{d:.2}"))
            .collect();
        println!(
            "| {sigma} | {:.3} | {:.2} | {:.3} | {:.2} | {} |",
            e.metric,
            e.drift,
            p.metric,
            p.drift,
            windows.join(" / ")
        );
        rows.push(json!({
            "sigma": sigma,
            "expert": e.metric, "expert_drift": e.drift, "expert_drift_by_window": e.drift_by_window,
            "policy": p.metric, "policy_drift": p.drift, "policy_drift_by_window": p.drift_by_window,
        }));
    }
    Ok(json!({
        "family": family.to_string(),
        "physics": expert.physics().to_string(),
        "expert": a.expert.display().to_string(),
        "policy": a.policy.display().to_string(),
        "rollouts": a.rollouts,
        "drift": format!(
            "mean Euclidean distance, per step, from the state to the nearest state of {REFERENCE_EPISODES} clean expert \
             episodes of the same task (seeds {REFERENCE_SEED}..), every observation dimension standardised \
             over those reference states; by window: the horizon cut into {WINDOWS} equal parts"
        ),
        "rows": rows,
    }))
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    match run(&args) {
        Ok(report) => {
            if let Some(out) = &args.out {
                let text = serde_json::to_string_pretty(&report).expect("JSON serialises");
                if let Err(e) = std::fs::write(out, text) {
                    eprintln!("error: writing {}: {e}", out.display());
                    return ExitCode::FAILURE;
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
