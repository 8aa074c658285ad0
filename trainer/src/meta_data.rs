//! What every meta-learner shares: the meta-train demos split into training tasks and held-out
//! *train* tasks (for validation / progress; the meta-test tasks are never read here), context
//! sampling, and episode rollouts of a context-conditioned policy.
//!
//! Honesty rule: [`MetaData::from_dataset`] refuses a dataset whose split is `test` or that
//! contains any task outside the family's meta-train list.

use rand::Rng;
use rand::seq::SliceRandom;
use sim::{
    DemoDataset, EnvConfig, Environment, EpisodeMetric, Family, MetricKind, Split, Task, TaskDemos,
    Trajectory,
};

use crate::context::{ContextSpec, ObsNorm};
use crate::meta_policy::MetaPolicy;
use crate::{Error, Result};

/// Meta-train demos, split into training tasks and held-out train tasks.
#[derive(Debug, Clone)]
pub struct MetaData {
    /// Task family.
    pub family: Family,
    /// Observation statistics of all meta-train demo states (training + held-out tasks).
    pub norm: ObsNorm,
    /// Demos of the tasks trained on.
    pub train: Vec<TaskDemos>,
    /// Demos of held-out meta-train tasks (validation; never trained on).
    pub val: Vec<TaskDemos>,
}

/// `true` if `a` is a better value than `b` for a metric of this kind (NaN is never better).
pub fn better(kind: MetricKind, a: f32, b: f32) -> bool {
    if a.is_nan() {
        return false;
    }
    if b.is_nan() {
        return true;
    }
    match kind {
        MetricKind::Return => a > b,
        MetricKind::MinGoalDistance | MetricKind::MeanVelocityError => a < b,
    }
}

impl MetaData {
    /// Splits `ds`: every `holdout_every`-th task (indices `holdout_every-1, 2*holdout_every-1,
    /// ...`) is held out for validation; 0 holds none out.
    ///
    /// Errors if the dataset is a meta-test split, holds a task that is not a meta-train task of
    /// its family, is of another family, or has a task without trajectories.
    pub fn from_dataset(ds: &DemoDataset, family: Family, holdout_every: usize) -> Result<Self> {
        if ds.split == Split::Test {
            return Err(Error::Config(
                "refusing to train on a meta-test dataset (split = test): training must never \
                 see meta-test tasks or their demos"
                    .into(),
            ));
        }
        ds.ensure_family(family)
            .map_err(|e| Error::Sim(e.to_string()))?;
        let train_tasks = family.train_tasks();
        for td in &ds.tasks {
            if !train_tasks.contains(&td.task) {
                return Err(Error::Config(format!(
                    "dataset task {} is not a meta-train task of {family}; refusing to train on it",
                    td.task
                )));
            }
            if td.trajectories.iter().all(Trajectory::is_empty) {
                return Err(Error::Config(format!(
                    "task {} has no demo transitions",
                    td.task
                )));
            }
        }
        let norm = ObsNorm::from_demos(ds)?;
        let (mut train, mut val) = (Vec::new(), Vec::new());
        for (i, td) in ds.tasks.iter().enumerate() {
            if holdout_every > 0 && i % holdout_every == holdout_every - 1 {
                val.push(td.clone());
            } else {
                train.push(td.clone());
            }
        }
        if train.is_empty() {
            return Err(Error::Config(
                "no training tasks left after the hold-out".into(),
            ));
        }
        Ok(Self {
            family,
            norm,
            train,
            val,
        })
    }
}

/// A context of up to `max` distinct trajectories of `demos` in random order, with `k` drawn
/// uniformly from `1..=n` (the reference's few-shot mask).
pub fn sample_context<'a>(demos: &'a TaskDemos, max: usize, rng: &mut impl Rng) -> ContextSpec<'a> {
    let mut trajectories: Vec<&Trajectory> = demos
        .trajectories
        .iter()
        .filter(|t| !t.is_empty())
        .collect();
    trajectories.shuffle(rng);
    trajectories.truncate(max.max(1));
    let k = rng.random_range(1..=trajectories.len());
    ContextSpec { trajectories, k }
}

/// `n` distinct task indices out of `0..len` (all of them, shuffled, if `n >= len`).
pub fn distinct_tasks(len: usize, n: usize, rng: &mut impl Rng) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..len).collect();
    idx.shuffle(rng);
    idx.truncate(n.min(len));
    idx
}

/// One step of a rollout as seen by a callback.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    /// Observation before the step.
    pub obs: &'a [f32],
    /// Oracle observation before the step (observation + task parameter).
    pub oracle: &'a [f32],
    /// Action taken (after clipping to [-1, 1]).
    pub action: &'a [f32],
    /// Observation after the step.
    pub next_obs: &'a [f32],
    /// True terminal (not a time-limit truncation).
    pub terminated: bool,
}

/// Outcome of one episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// The family's metric (min distance, mean |v - v*|, return).
    pub metric: f32,
    /// Undiscounted return.
    pub ret: f32,
    /// Steps taken.
    pub steps: usize,
}

/// A policy callback: `act(obs, action)` writes the action for a raw observation.
pub type ActFn<'a> = dyn FnMut(&[f32], &mut [f32]) -> Result<()> + 'a;

/// Runs one episode of `task` from reset seed `seed`; `act(obs, action)` chooses actions and
/// `on_step` sees every transition.
pub fn run_episode(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    act: &mut ActFn<'_>,
    on_step: &mut dyn FnMut(&Step<'_>) -> Result<()>,
) -> Result<Episode> {
    let sim_err = |e: sim::SimError| Error::Sim(e.to_string());
    let mut obs = env.reset(task, seed).map_err(sim_err)?.to_vec();
    let mut oracle = vec![0.0f32; env.oracle_obs_dim()];
    let mut action = vec![0.0f32; env.act_dim()];
    let mut metric = EpisodeMetric::new(env.family());
    let (mut ret, mut steps) = (0.0f32, 0usize);
    loop {
        env.oracle_observation(&mut oracle).map_err(sim_err)?;
        act(&obs, &mut action)?;
        for a in action.iter_mut() {
            *a = a.clamp(-1.0, 1.0);
        }
        let tr = env.step(&action).map_err(sim_err)?;
        metric.record(&tr.info);
        ret += tr.reward;
        steps += 1;
        let done = tr.done;
        on_step(&Step {
            obs: &obs,
            oracle: &oracle,
            action: &action,
            next_obs: tr.obs,
            terminated: tr.info.terminated,
        })?;
        obs.copy_from_slice(tr.obs);
        if done {
            return Ok(Episode {
                metric: metric.value(),
                ret,
                steps,
            });
        }
    }
}

/// Mean metric of deterministic rollouts of `mp` on `tasks`: per task, `contexts` draws of one
/// context trajectory (trajectory `d % n`) and `episodes` rollouts each; z = posterior mean.
pub fn quick_eval(
    mp: &MetaPolicy,
    tasks: &[TaskDemos],
    contexts: usize,
    episodes: usize,
    env_cfg: EnvConfig,
) -> Result<f32> {
    if tasks.is_empty() {
        return Ok(f32::NAN);
    }
    let mut env = sim::make_env(mp.family, env_cfg).map_err(|e| Error::Sim(e.to_string()))?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    use rand::SeedableRng;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for td in tasks {
        for d in 0..contexts.max(1) {
            let traj = &td.trajectories[d % td.trajectories.len()];
            let z = mp.latent(&[traj])?;
            for e in 0..episodes.max(1) {
                let seed = 3_000_000 + (d * 1000 + e) as u64;
                let ep = run_episode(
                    env.as_mut(),
                    &td.task,
                    seed,
                    &mut |o, a| {
                        a.copy_from_slice(&mp.act(o, &z, true, &mut rng)?);
                        Ok(())
                    },
                    &mut |_| Ok(()),
                )?;
                sum += ep.metric as f64;
                n += 1;
            }
        }
    }
    Ok((sum / n as f64) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dataset(split: Split, tasks: Vec<Task>) -> DemoDataset {
        let mut ds = DemoDataset::new(Family::PointGoal, split, "scripted-pd");
        let mut env = sim::make_env(
            Family::PointGoal,
            EnvConfig {
                horizon: Some(5),
                ..EnvConfig::default()
            },
        )
        .unwrap();
        let pd = sim::PointGoalPdExpert::default();
        for task in tasks {
            let tr = sim::record_trajectory(env.as_mut(), &task, 0, |o, a| pd.act(o, a).unwrap())
                .unwrap();
            ds.tasks.push(TaskDemos {
                task,
                trajectories: vec![tr],
            });
        }
        ds
    }

    #[test]
    fn refuses_meta_test_data() {
        let fam = Family::PointGoal;
        let test = dataset(Split::Test, fam.test_tasks()[..2].to_vec());
        let e = MetaData::from_dataset(&test, fam, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("meta-test"), "{e}");
        // A test task smuggled into a file labelled train is refused too.
        let mixed = dataset(
            Split::Train,
            vec![fam.train_tasks()[0], fam.test_tasks()[3]],
        );
        let e = MetaData::from_dataset(&mixed, fam, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a meta-train task"), "{e}");
        let ok = dataset(Split::Train, fam.train_tasks()[..8].to_vec());
        let md = MetaData::from_dataset(&ok, fam, 4).unwrap();
        assert_eq!((md.train.len(), md.val.len()), (6, 2));
        assert_eq!(md.val[0].task, fam.train_tasks()[3]);
    }
}
