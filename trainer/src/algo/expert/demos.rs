//! Demonstrations: deterministic expert rollouts written in `sim`'s dataset format
//! (`docs/DATASET.md`). Trajectory `j` of every task is reset with seed `seed + j` (with
//! [`DemoSpec::distinct_starts`], trajectory `j` of task `i` with `seed + i * per_task + j`), so a
//! file is a pure function of (expert, tasks, per-task count, seed, starts, subsampling).

use sim::{DemoDataset, EnvConfig, Family, Split, Task, TaskDemos};

use super::{Expert, ExpertSet};
use crate::error::{Error, Result};

/// What to record.
#[derive(Debug, Clone)]
pub struct DemoSpec {
    /// The tasks (a split's list or explicit ones).
    pub tasks: Vec<Task>,
    /// The split label stored in the file.
    pub split: Split,
    /// Trajectories per task.
    pub per_task: usize,
    /// Subsampling factor k (1 = keep every step); offsets drawn from `seed`.
    pub subsample: usize,
    /// Base reset seed.
    pub seed: u64,
    /// Reset each task's trajectories from seeds no other task uses (trajectory `j` of task `i`:
    /// `seed + i * per_task + j`) instead of the same seeds in every task (`seed + j`). Where the
    /// tasks share their goals (ant-linclass: two fixed targets), shared seeds make every task's
    /// demo `j` the same walk to the same goal, so the whole file holds `per_task` starts;
    /// distinct seeds give `tasks x per_task` starts, as an environment reset by its own
    /// generator would. Off in the shipped files.
    pub distinct_starts: bool,
    /// Episode options (horizon).
    pub env: EnvConfig,
}

/// Record `spec.per_task` deterministic expert episodes in every task.
pub fn record(expert: &Expert, spec: &DemoSpec) -> Result<DemoDataset> {
    let set = ExpertSet::from(expert.clone());
    record_with(&set, spec)
}

/// As [`record`], each task acted by its expert in `experts` (per-task experts).
pub fn record_with(experts: &ExpertSet, spec: &DemoSpec) -> Result<DemoDataset> {
    crate::io::require_positive(&[
        ("demos per task", spec.per_task as u64),
        ("subsample", spec.subsample as u64),
    ])?;
    let family: Family = experts.family();
    Error::same_plant(|| "the expert".into(), experts.physics(), spec.env.physics)?;
    let mut env = sim::make_env(family, spec.env)?;
    let mut ds = DemoDataset::new(family, spec.split, experts.name());
    ds.physics = spec.env.physics;
    let stride = seed_stride(spec)?;
    for (i, task) in spec.tasks.iter().enumerate() {
        let expert = experts.for_task(task)?;
        let mut trajectories = Vec::with_capacity(spec.per_task);
        let first = spec.seed + i as u64 * stride;
        for j in 0..spec.per_task {
            let mut failure = None;
            let seed = first + j as u64;
            let tr = sim::record_trajectory(env.as_mut(), task, seed, |o, a| {
                if let Err(e) = expert.act(o, a) {
                    failure.get_or_insert(e);
                }
            })?;
            if let Some(e) = failure {
                return Err(e);
            }
            trajectories.push(tr);
        }
        ds.tasks.push(TaskDemos {
            task: *task,
            trajectories,
        });
    }
    if spec.subsample > 1 {
        // A factor past the shortest demo keeps none of its transitions: a file of empty demos
        // is refused, not written (issue 72, item 4).
        let shortest = ds
            .tasks
            .iter()
            .flat_map(|t| t.trajectories.iter().map(|tr| tr.len()))
            .min()
            .unwrap_or(0);
        if spec.subsample > shortest {
            return Err(Error::Config(format!(
                "subsample {} is longer than the shortest demo ({shortest} steps): it would keep \
                 no transition of it",
                spec.subsample
            )));
        }
        ds = ds.subsample(spec.subsample, spec.seed)?;
    }
    Ok(ds)
}

/// How far apart consecutive tasks' first reset seeds are: `per_task` with distinct starts, 0
/// with shared ones. Refused when the last seed would not fit in 64 bits (it would wrap onto
/// seeds another trajectory used).
fn seed_stride(spec: &DemoSpec) -> Result<u64> {
    let per_task = spec.per_task as u64;
    let (stride, used) = match spec.distinct_starts {
        true => (per_task, (spec.tasks.len() as u64).checked_mul(per_task)),
        false => (0, Some(per_task)),
    };
    if used.and_then(|n| spec.seed.checked_add(n)).is_none() {
        return Err(Error::Config(format!(
            "seed {} leaves too few 64-bit seeds for {} demos a task in {} tasks: give a \
             smaller seed",
            spec.seed,
            spec.per_task,
            spec.tasks.len()
        )));
    }
    Ok(stride)
}
