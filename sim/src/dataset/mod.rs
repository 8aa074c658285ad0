//! The demo dataset: expert trajectories grouped by task, stored as one safetensors file
//! (tensors + string metadata, readable from Python/numpy). Layout: `docs/DATASET.md`.

use std::collections::HashMap;
use std::path::Path;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, TensorView};

use crate::family::{Environment, Family, Task};

use crate::kinds::Physics;

use crate::task::Split;

pub use error::DatasetError;

/// Value of the `format` metadata key.
pub const FORMAT_NAME: &str = "smile-demos";
/// Value of the `format_version` metadata key written by this crate.
pub const FORMAT_VERSION: u32 = 1;

/// One expert trajectory, possibly subsampled: row `i` is the transition taken at time step
/// `time_steps[i]`, with its true one-step next observation.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Seed passed to `reset` when the trajectory was recorded.
    pub seed: u64,
    /// Subsampling offset `a`: kept steps satisfy `t % factor == a` (0 when not subsampled).
    pub subsample_offset: usize,
    /// Original time step of each kept transition.
    pub time_steps: Vec<u32>,
    /// Observations, row-major `[len, obs_dim]`.
    pub obs: Vec<f32>,
    /// Actions (clipped to [-1, 1]), row-major `[len, act_dim]`.
    pub actions: Vec<f32>,
    /// Rewards, `[len]`.
    pub rewards: Vec<f32>,
    /// Next observations, row-major `[len, obs_dim]`.
    pub next_obs: Vec<f32>,
    /// Terminal flags (true only when the task ended the episode, not at the horizon).
    pub dones: Vec<bool>,
}

/// Borrowed view of one stored transition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransitionRef<'a> {
    /// Observation s.
    pub obs: &'a [f32],
    /// Action a.
    pub action: &'a [f32],
    /// Reward r.
    pub reward: f32,
    /// Next observation s'.
    pub next_obs: &'a [f32],
    /// Terminal flag.
    pub done: bool,
}

impl Trajectory {
    /// An empty trajectory recorded from `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            ..Self::default()
        }
    }

    /// Number of stored transitions.
    pub fn len(&self) -> usize {
        self.rewards.len()
    }

    /// True when no transition is stored.
    pub fn is_empty(&self) -> bool {
        self.rewards.is_empty()
    }

    /// Appends one transition taken at time step `time_step`.
    pub fn push(&mut self, time_step: u32, transition: TransitionRef<'_>) {
        self.time_steps.push(time_step);
        self.obs.extend_from_slice(transition.obs);
        self.actions.extend_from_slice(transition.action);
        self.rewards.push(transition.reward);
        self.next_obs.extend_from_slice(transition.next_obs);
        self.dones.push(transition.done);
    }

    /// Transition `index` given the dataset dimensions; `None` past the end.
    pub fn transition(
        &self,
        index: usize,
        obs_dim: usize,
        act_dim: usize,
    ) -> Option<TransitionRef<'_>> {
        if index >= self.len() {
            return None;
        }
        Some(TransitionRef {
            obs: self.obs.get(index * obs_dim..(index + 1) * obs_dim)?,
            action: self.actions.get(index * act_dim..(index + 1) * act_dim)?,
            reward: self.rewards[index],
            next_obs: self.next_obs.get(index * obs_dim..(index + 1) * obs_dim)?,
            done: self.dones[index],
        })
    }

    /// Keeps the transitions whose time step `t` satisfies `t % factor == offset`.
    pub fn subsampled(&self, factor: usize, offset: usize, obs_dim: usize, act_dim: usize) -> Self {
        let mut kept = Trajectory {
            seed: self.seed,
            subsample_offset: offset,
            ..Trajectory::default()
        };
        for index in 0..self.len() {
            let t = self.time_steps[index] as usize;
            if t % factor == offset
                && let Some(transition) = self.transition(index, obs_dim, act_dim)
            {
                kept.push(self.time_steps[index], transition);
            }
        }
        kept
    }

    fn check_dims(&self, obs_dim: usize, act_dim: usize) -> Result<(), DatasetError> {
        let n = self.len();
        let checks = [
            ("trajectory time_steps", n, self.time_steps.len()),
            ("trajectory dones", n, self.dones.len()),
            ("trajectory obs", n * obs_dim, self.obs.len()),
            ("trajectory next_obs", n * obs_dim, self.next_obs.len()),
            ("trajectory actions", n * act_dim, self.actions.len()),
        ];
        DatasetError::check_lengths(checks)
    }

    /// Errors on the first NaN or infinite float, naming its tensor, task and trajectory.
    fn check_finite(&self, task: usize, trajectory: usize) -> Result<(), DatasetError> {
        let tensors: [(&'static str, &[f32]); 4] = [
            (names::OBS, &self.obs),
            (names::ACTIONS, &self.actions),
            (names::REWARDS, &self.rewards),
            (names::NEXT_OBS, &self.next_obs),
        ];
        for (tensor, values) in tensors {
            if let Some(&value) = values.iter().find(|v| !v.is_finite()) {
                return Err(DatasetError::NonFinite {
                    tensor,
                    task,
                    trajectory: Some(trajectory),
                    value: value.into(),
                });
            }
        }
        Ok(())
    }
}

/// The demonstrations of one task.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskDemos {
    /// The task demonstrated.
    pub task: Task,
    /// Its trajectories.
    pub trajectories: Vec<Trajectory>,
}

impl TaskDemos {
    /// Total transitions over this task's trajectories.
    pub fn transition_count(&self) -> usize {
        self.trajectories.iter().map(Trajectory::len).sum()
    }
}

/// A demo dataset: one family, one split, trajectories grouped by task.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoDataset {
    /// Task family.
    pub family: Family,
    /// The plant the demos were recorded on (metadata `physics`; a file without it is
    /// Rapier's, as every file written before the MuJoCo backend).
    pub physics: Physics,
    /// Split the tasks come from.
    pub split: Split,
    /// Name of the expert that produced the demos (e.g. `scripted-pd`, `sac-oracle`).
    pub expert: String,
    /// Observation dimension (the learner-facing observation).
    pub obs_dim: usize,
    /// Action dimension.
    pub act_dim: usize,
    /// Subsampling factor k (1 = every step kept).
    pub subsample_factor: usize,
    /// Demonstrations per task.
    pub tasks: Vec<TaskDemos>,
}

/// Names of the stored tensors (see `docs/DATASET.md`).
mod names {
    pub const OBS: &str = "obs";
    pub const ACTIONS: &str = "actions";
    pub const REWARDS: &str = "rewards";
    pub const NEXT_OBS: &str = "next_obs";
    pub const DONES: &str = "dones";
    pub const TIME_STEPS: &str = "time_steps";
    pub const TRAJ_OFFSETS: &str = "traj_offsets";
    pub const TRAJ_SEEDS: &str = "traj_seeds";
    pub const TRAJ_SUBSAMPLE_OFFSETS: &str = "traj_subsample_offsets";
    pub const TASK_TRAJ_OFFSETS: &str = "task_traj_offsets";
    pub const TASK_VALUES: &str = "task_values";
    pub const TASK_PARAMETERS: &str = "task_parameters";
}

impl DemoDataset {
    /// An empty dataset for `family` and `split`, not subsampled.
    pub fn new(family: Family, split: Split, expert: impl Into<String>) -> Self {
        Self {
            family,
            physics: Physics::Rapier,
            split,
            expert: expert.into(),
            obs_dim: family.obs_dim(),
            act_dim: family.act_dim(),
            subsample_factor: 1,
            tasks: Vec::new(),
        }
    }

    /// Total number of trajectories.
    pub fn trajectory_count(&self) -> usize {
        self.tasks.iter().map(|t| t.trajectories.len()).sum()
    }

    /// Total number of transitions.
    pub fn transition_count(&self) -> usize {
        self.tasks.iter().map(TaskDemos::transition_count).sum()
    }

    /// Errors unless the dataset is of `family` (with that family's dimensions).
    pub fn ensure_family(&self, family: Family) -> Result<(), DatasetError> {
        if self.family != family {
            return Err(DatasetError::FamilyMismatch {
                expected: family,
                found: self.family,
            });
        }
        self.check()
    }

    /// Errors unless the demos were recorded on `physics`: a demo of one plant is refused by
    /// a run on the other (its observations mean other things: the cheetah's rootz is absolute
    /// on Rapier, relative on MuJoCo, and the dynamics differ).
    pub fn ensure_physics(&self, physics: Physics) -> Result<(), DatasetError> {
        if self.physics == physics {
            Ok(())
        } else {
            Err(DatasetError::PhysicsMismatch {
                expected: physics,
                found: self.physics,
            })
        }
    }

    /// Checks dimensions, task families, per-trajectory lengths and that every stored float
    /// is finite ([`DatasetError::NonFinite`]). Both [`DemoDataset::to_bytes`] and
    /// [`DemoDataset::from_bytes`] run it: a file the reader would refuse is never written.
    pub fn check(&self) -> Result<(), DatasetError> {
        let dims = [
            ("obs_dim", self.family.obs_dim(), self.obs_dim),
            ("act_dim", self.family.act_dim(), self.act_dim),
        ];
        DatasetError::check_lengths(dims)?;
        if self.subsample_factor == 0 {
            return Err(DatasetError::Subsample("factor 0".into()));
        }
        let mut trajectory_index = 0;
        for (task_index, demos) in self.tasks.iter().enumerate() {
            // One entry per task: a repeated one would be drawn twice as often in training
            // and scored twice in an evaluation.
            if let Some(first) = self.tasks[..task_index]
                .iter()
                .position(|t| t.task == demos.task)
            {
                return Err(DatasetError::Inconsistent(format!(
                    "task {} appears twice (entries {first} and {task_index})",
                    demos.task.label()
                )));
            }
            if demos.task.family() != self.family {
                return Err(DatasetError::FamilyMismatch {
                    expected: self.family,
                    found: demos.task.family(),
                });
            }
            for trajectory in &demos.trajectories {
                trajectory.check_dims(self.obs_dim, self.act_dim)?;
                trajectory.check_finite(task_index, trajectory_index)?;
                trajectory_index += 1;
                if trajectory.subsample_offset >= self.subsample_factor {
                    return Err(DatasetError::Inconsistent(format!(
                        "subsample offset {} not below factor {}",
                        trajectory.subsample_offset, self.subsample_factor
                    )));
                }
            }
        }
        Ok(())
    }

    /// "Subsampling by k": for each trajectory draw an offset a in 0..k (seeded), keep step t
    /// when t mod k == a; each kept transition keeps its true one-step next observation.
    pub fn subsample(&self, factor: usize, seed: u64) -> Result<DemoDataset, DatasetError> {
        if factor == 0 {
            return Err(DatasetError::Subsample("factor must be at least 1".into()));
        }
        if self.subsample_factor != 1 {
            return Err(DatasetError::Subsample(format!(
                "dataset is already subsampled by {}",
                self.subsample_factor
            )));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let tasks = self
            .tasks
            .iter()
            .map(|demos| TaskDemos {
                task: demos.task,
                trajectories: demos
                    .trajectories
                    .iter()
                    .map(|trajectory| {
                        let offset = rng.random_range(0..factor);
                        trajectory.subsampled(factor, offset, self.obs_dim, self.act_dim)
                    })
                    .collect(),
            })
            .collect();
        Ok(DemoDataset {
            subsample_factor: factor,
            tasks,
            expert: self.expert.clone(),
            ..*self
        })
    }
}

/// Records one episode of `task` from reset seed `seed`, acting with `policy(oracle_obs,
/// action)`: the expert sees the oracle observation, the stored `obs` do not contain the task.
pub fn record_trajectory(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    mut policy: impl FnMut(&[f32], &mut [f32]),
) -> Result<Trajectory, DatasetError> {
    let mut obs = env.reset(task, seed)?.to_vec();
    let mut oracle = vec![0.0; env.oracle_obs_dim()];
    let mut action = vec![0.0; env.act_dim()];
    let mut trajectory = Trajectory::new(seed);
    for t in 0.. {
        env.oracle_observation(&mut oracle)?;
        policy(&oracle, &mut action);
        for a in action.iter_mut() {
            *a = a.clamp(-1.0, 1.0);
        }
        let transition = env.step(&action)?;
        trajectory.push(
            t,
            TransitionRef {
                obs: &obs,
                action: &action,
                reward: transition.reward,
                next_obs: transition.obs,
                done: transition.info.terminated,
            },
        );
        let done = transition.done;
        obs.copy_from_slice(transition.obs);
        if done {
            break;
        }
    }
    Ok(trajectory)
}

fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn f64_bytes(values: impl IntoIterator<Item = f64>) -> Vec<u8> {
    values.into_iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn i64_bytes(values: impl IntoIterator<Item = usize>) -> Vec<u8> {
    values
        .into_iter()
        .flat_map(|v| (v as i64).to_le_bytes())
        .collect()
}

/// One tensor of the file: its name, element type, shape and little-endian bytes.
type Tensor = (&'static str, Dtype, Vec<usize>, Vec<u8>);

impl DemoDataset {
    /// Serialises to safetensors bytes.
    pub fn to_bytes(&self) -> Result<Vec<u8>, DatasetError> {
        self.check()?;
        let trajectories: Vec<&Trajectory> =
            self.tasks.iter().flat_map(|t| &t.trajectories).collect();
        let mut owned = self.transition_tensors(&trajectories);
        owned.extend(self.index_tensors(&trajectories));
        let mut views = Vec::with_capacity(owned.len());
        for (name, dtype, shape, bytes) in &owned {
            let view = TensorView::new(*dtype, shape.clone(), bytes)
                .map_err(|e| DatasetError::Corrupt(format!("building {name}: {e}")))?;
            views.push((*name, view));
        }
        let metadata = self.metadata();
        safetensors::serialize(views, Some(metadata))
            .map(crate::fsio::canonical_safetensors)
            .map_err(|e| DatasetError::Corrupt(format!("serialising: {e}")))
    }

    /// The per-transition tensors: every trajectory's steps, one after another.
    fn transition_tensors(&self, trajectories: &[&Trajectory]) -> Vec<Tensor> {
        let n = self.transition_count();
        let concat = |field: fn(&Trajectory) -> &[f32]| -> Vec<u8> {
            f32_bytes(
                &trajectories
                    .iter()
                    .flat_map(|t| field(t).iter().copied())
                    .collect::<Vec<_>>(),
            )
        };
        vec![
            (
                names::OBS,
                Dtype::F32,
                vec![n, self.obs_dim],
                concat(|t| &t.obs),
            ),
            (
                names::ACTIONS,
                Dtype::F32,
                vec![n, self.act_dim],
                concat(|t| &t.actions),
            ),
            (names::REWARDS, Dtype::F32, vec![n], concat(|t| &t.rewards)),
            (
                names::NEXT_OBS,
                Dtype::F32,
                vec![n, self.obs_dim],
                concat(|t| &t.next_obs),
            ),
            (
                names::DONES,
                Dtype::U8,
                vec![n],
                trajectories
                    .iter()
                    .flat_map(|t| t.dones.iter().map(|&d| d as u8))
                    .collect(),
            ),
            (
                names::TIME_STEPS,
                Dtype::I64,
                vec![n],
                i64_bytes(
                    trajectories
                        .iter()
                        .flat_map(|t| t.time_steps.iter().map(|&s| s as usize)),
                ),
            ),
        ]
    }

    /// The index tensors: where each trajectory and each task's trajectories start, the
    /// trajectories' seeds and subsampling offsets, the tasks' values and parameters.
    fn index_tensors(&self, trajectories: &[&Trajectory]) -> Vec<Tensor> {
        let mut row_offsets = vec![0usize];
        for t in trajectories {
            row_offsets.push(row_offsets.last().copied().unwrap_or(0) + t.len());
        }
        let mut traj_offsets = vec![0usize];
        for demos in &self.tasks {
            traj_offsets.push(traj_offsets.last().copied().unwrap_or(0) + demos.trajectories.len());
        }
        let task_dim = self.family.task_dim();
        let parameters: Vec<f32> = self.tasks.iter().flat_map(|d| d.task.parameter()).collect();
        let k = self.tasks.len();
        let t_count = trajectories.len();
        vec![
            (
                names::TRAJ_OFFSETS,
                Dtype::I64,
                vec![t_count + 1],
                i64_bytes(row_offsets),
            ),
            (
                names::TRAJ_SEEDS,
                Dtype::U64,
                vec![t_count],
                trajectories
                    .iter()
                    .flat_map(|t| t.seed.to_le_bytes())
                    .collect(),
            ),
            (
                names::TRAJ_SUBSAMPLE_OFFSETS,
                Dtype::I64,
                vec![t_count],
                i64_bytes(trajectories.iter().map(|t| t.subsample_offset)),
            ),
            (
                names::TASK_TRAJ_OFFSETS,
                Dtype::I64,
                vec![k + 1],
                i64_bytes(traj_offsets),
            ),
            (
                names::TASK_VALUES,
                Dtype::F64,
                vec![k],
                f64_bytes(self.tasks.iter().map(|d| d.task.value())),
            ),
            (
                names::TASK_PARAMETERS,
                Dtype::F32,
                vec![k, task_dim],
                f32_bytes(&parameters),
            ),
        ]
    }

    /// The file's metadata: format, family, plant, split, expert, dimensions, task labels.
    fn metadata(&self) -> HashMap<String, String> {
        let task_dim = self.family.task_dim();
        let labels: Vec<String> = self.tasks.iter().map(|d| d.task.label()).collect();
        [
            ("format", FORMAT_NAME.to_string()),
            ("format_version", FORMAT_VERSION.to_string()),
            ("family", self.family.to_string()),
            ("physics", self.physics.to_string()),
            ("split", self.split.to_string()),
            ("expert", self.expert.clone()),
            ("obs_dim", self.obs_dim.to_string()),
            ("act_dim", self.act_dim.to_string()),
            ("task_dim", task_dim.to_string()),
            ("subsample_factor", self.subsample_factor.to_string()),
            ("tasks", serde_json::Value::from(labels).to_string()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    /// Writes the dataset to `path` (safetensors), atomically: a kill or a full disk leaves
    /// the previous file whole.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), DatasetError> {
        let path = path.as_ref();
        let bytes = self.to_bytes()?;
        crate::fsio::write_atomic(path, &bytes).map_err(|source| DatasetError::Io {
            path: path.display().to_string(),
            source,
        })
    }

    /// Reads a dataset written by [`DemoDataset::write`].
    pub fn read(path: impl AsRef<Path>) -> Result<DemoDataset, DatasetError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| DatasetError::Io {
            path: path.display().to_string(),
            source,
        })?;
        crate::shipped::check_shipped_bytes(path, &bytes)?;
        Self::from_bytes(&bytes)
    }
}

mod error;
mod read;
#[cfg(test)]
mod tests;
