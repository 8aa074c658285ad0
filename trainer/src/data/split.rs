//! The meta-train demos split into training tasks and held-out *train* tasks (for validation
//! and checkpoint selection; the meta-test tasks are never read here), and the sampling of
//! tasks and contexts every meta-learner shares.
//!
//! Honesty rule: [`MetaData::from_dataset`] refuses a dataset whose split is `test` or that
//! contains any task outside the family's meta-train list.

use rand::Rng;
use rand::seq::SliceRandom;
use sim::{DemoDataset, Family, Split, TaskDemos, Trajectory};

use crate::error::{Error, Result};
use crate::model::{ContextEncoder, ContextSpec, MetaPolicy, ObsNorm, TanhGaussianPolicy};

/// Meta-train demos, split into training tasks and held-out train tasks.
#[derive(Debug, Clone)]
pub struct MetaData {
    /// Task family.
    pub family: Family,
    /// The plant the demos were recorded on.
    pub physics: sim::Physics,
    /// Observation statistics of all meta-train demo states (training + held-out tasks).
    pub norm: ObsNorm,
    /// Demos of the tasks trained on.
    pub train: Vec<TaskDemos>,
    /// Demos of held-out meta-train tasks (validation; never trained on).
    pub val: Vec<TaskDemos>,
}

impl MetaData {
    /// The meta-policy `algo` trains on these demos, on `physics`: `encoder` and `policy` (the
    /// live weights, shared) over the demos' family and observation statistics.
    pub fn meta_policy(
        &self,
        physics: sim::Physics,
        algo: &str,
        encoder: &ContextEncoder,
        policy: &TanhGaussianPolicy,
    ) -> MetaPolicy {
        MetaPolicy {
            family: self.family,
            physics,
            algo: algo.into(),
            norm: self.norm.clone(),
            encoder: encoder.clone(),
            policy: policy.clone(),
        }
    }

    /// Errors unless these demos are of `family` and were recorded on `physics`: what a
    /// learner configured for that family and plant can train on.
    pub fn ensure_fits(&self, family: Family, physics: sim::Physics) -> Result<()> {
        if self.family != family {
            return Err(Error::WrongFamily {
                what: "the demos, for the config's `env`".into(),
                found: self.family,
                expected: family,
            });
        }
        Error::same_plant(|| "the demos".into(), self.physics, physics)
    }

    /// Splits `ds`: every `holdout_every`-th task (indices `holdout_every-1, 2*holdout_every-1,
    /// ...`) is held out for validation; 0 holds none out.
    ///
    /// Errors if the dataset is a meta-test split, holds a task that is not a meta-train task of
    /// its family, is of another family, or has a task without trajectories.
    pub fn from_dataset(ds: &DemoDataset, family: Family, holdout_every: usize) -> Result<Self> {
        if ds.split == Split::Test {
            return Err(Error::Data(
                "refusing to train on a meta-test dataset (split = test): training must never \
                 see meta-test tasks or their demos"
                    .into(),
            ));
        }
        ds.ensure_family(family)?;
        let train_tasks = family.train_tasks();
        for td in &ds.tasks {
            if !train_tasks.iter().any(|t| t.same_task(&td.task)) {
                return Err(Error::Data(format!(
                    "dataset task {} is not a meta-train task of {family}; refusing to train on it",
                    td.task
                )));
            }
            if td.trajectories.iter().all(Trajectory::is_empty) {
                return Err(Error::Data(format!(
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
            return Err(Error::Data(
                "no training tasks left after the hold-out".into(),
            ));
        }
        Ok(Self {
            family,
            physics: ds.physics,
            norm,
            train,
            val,
        })
    }
}

/// How training draws a context from a task's demos.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContextDraw {
    /// Most trajectories per context (`k` is uniform in `1..=` the number drawn).
    pub max_trajectories: usize,
    /// Most transitions encoded per trajectory, drawn at random without replacement each time
    /// (an unbiased estimate of the per-trajectory mean the encoder takes); 0 = all of them.
    pub max_steps: usize,
}

/// A context of up to `draw.max_trajectories` distinct trajectories of `demos` in random
/// order, with `k` drawn uniformly from `1..=n` (the reference's few-shot mask), and, when
/// `draw.max_steps > 0`, that many random transitions of each unmasked trajectory longer
/// than it. With `max_steps == 0` the random draws are exactly those of earlier versions.
pub fn sample_context<'a>(
    demos: &'a TaskDemos,
    draw: ContextDraw,
    rng: &mut impl Rng,
) -> ContextSpec<'a> {
    let mut trajectories: Vec<&Trajectory> = demos
        .trajectories
        .iter()
        .filter(|t| !t.is_empty())
        .collect();
    trajectories.shuffle(rng);
    trajectories.truncate(draw.max_trajectories.max(1));
    let k = rng.random_range(1..=trajectories.len());
    let mut steps = Vec::new();
    if draw.max_steps > 0 && trajectories[..k].iter().any(|t| t.len() > draw.max_steps) {
        steps = trajectories[..k]
            .iter()
            .map(|t| {
                let n = t.len();
                if n <= draw.max_steps {
                    (0..n).collect()
                } else {
                    let mut idx = rand::seq::index::sample(rng, n, draw.max_steps).into_vec();
                    idx.sort_unstable();
                    idx
                }
            })
            .collect();
    }
    ContextSpec {
        trajectories,
        k,
        steps,
    }
}

/// `n` distinct task indices out of `0..len` (all of them, shuffled, if `n >= len`).
pub fn distinct_tasks(len: usize, n: usize, rng: &mut impl Rng) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..len).collect();
    idx.shuffle(rng);
    idx.truncate(n.min(len));
    idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::{EnvConfig, Task};

    fn dataset(split: Split, tasks: Vec<Task>) -> DemoDataset {
        let mut ds = DemoDataset::new(Family::POINT_GOAL, split, "scripted-pd");
        let mut env = sim::make_env(
            Family::POINT_GOAL,
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
        let fam = Family::POINT_GOAL;
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

    #[test]
    fn context_draws_cap_the_steps_of_unmasked_trajectories() {
        use rand::SeedableRng;
        let fam = Family::POINT_GOAL;
        let mut ds = dataset(Split::Train, fam.train_tasks()[..1].to_vec());
        let tr = ds.tasks[0].trajectories[0].clone();
        ds.tasks[0].trajectories = vec![tr.clone(), tr.clone(), tr];
        let demos = &ds.tasks[0];
        let draw = |max_steps| ContextDraw {
            max_trajectories: 2,
            max_steps,
        };
        // 0 = every step: no step lists and the same draws as a cap that never bites.
        let mut a = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut b = a.clone();
        for _ in 0..20 {
            let (x, y) = (
                sample_context(demos, draw(0), &mut a),
                sample_context(demos, draw(5), &mut b),
            );
            assert!(x.steps.is_empty() && y.steps.is_empty());
            assert_eq!((x.k, x.trajectories.len()), (y.k, 2));
        }
        // A cap of 3 of 5 steps: one sorted list of 3 distinct steps per unmasked trajectory.
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..50 {
            let c = sample_context(demos, draw(3), &mut a);
            assert_eq!(c.steps.len(), c.k);
            for idx in &c.steps {
                assert_eq!(idx.len(), 3);
                assert!(idx.windows(2).all(|w| w[0] < w[1]) && idx[2] < 5);
                seen.insert(idx.clone());
            }
        }
        assert!(seen.len() > 3, "the steps are redrawn: {seen:?}");
    }
}
