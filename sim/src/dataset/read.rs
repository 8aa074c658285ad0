//! Parsing and validating a demo file; every failure is a [`DatasetError`], never a panic.

use std::collections::HashMap;

use safetensors::tensor::{Dtype, SafeTensors};

use super::{DatasetError, DemoDataset, FORMAT_NAME, FORMAT_VERSION, TaskDemos, Trajectory, names};
use crate::family::Family;
use crate::kinds::Physics;
use crate::task::Split;

/// Size of the little-endian header-length prefix of a safetensors file.
const PREFIX: usize = 8;

/// Checks the announced sizes against the buffer so that a short file is reported as truncated.
fn check_length(bytes: &[u8]) -> Result<(), DatasetError> {
    let Some(prefix) = bytes.get(..PREFIX) else {
        return Err(DatasetError::Truncated {
            expected: PREFIX,
            got: bytes.len(),
        });
    };
    let mut raw = [0u8; PREFIX];
    raw.copy_from_slice(prefix);
    let header_len = usize::try_from(u64::from_le_bytes(raw))
        .map_err(|_| DatasetError::Corrupt("header length does not fit in memory".into()))?;
    if header_len > 100_000_000 {
        return Err(DatasetError::Corrupt(format!(
            "header length {header_len} is implausible"
        )));
    }
    let header_end = PREFIX + header_len;
    let Some(header) = bytes.get(PREFIX..header_end) else {
        return Err(DatasetError::Truncated {
            expected: header_end,
            got: bytes.len(),
        });
    };
    let header: serde_json::Value = std::str::from_utf8(header)
        .ok()
        .and_then(|text| serde_json::from_str(text).ok())
        .ok_or_else(|| DatasetError::Corrupt("header is not valid UTF-8 JSON".into()))?;
    let data_len = header
        .as_object()
        .into_iter()
        .flatten()
        .filter_map(|(_, info)| info.get("data_offsets")?.get(1)?.as_u64())
        .max()
        .unwrap_or(0) as usize;
    let expected = header_end.saturating_add(data_len);
    if bytes.len() < expected {
        return Err(DatasetError::Truncated {
            expected,
            got: bytes.len(),
        });
    }
    Ok(())
}

fn meta<'a>(map: &'a HashMap<String, String>, key: &'static str) -> Result<&'a str, DatasetError> {
    map.get(key)
        .map(String::as_str)
        .ok_or(DatasetError::BadMetadata {
            key,
            reason: "missing".into(),
        })
}

fn meta_parse<T: std::str::FromStr>(
    map: &HashMap<String, String>,
    key: &'static str,
) -> Result<T, DatasetError>
where
    T::Err: std::fmt::Display,
{
    meta(map, key)?
        .parse()
        .map_err(|e: T::Err| DatasetError::BadMetadata {
            key,
            reason: e.to_string(),
        })
}

/// Reads a tensor of `dtype` and `shape` (None = any length on that axis) as raw bytes.
fn tensor<'a>(
    file: &SafeTensors<'a>,
    name: &'static str,
    dtype: Dtype,
    shape: &[Option<usize>],
) -> Result<(&'a [u8], Vec<usize>), DatasetError> {
    let view = file.tensor(name).map_err(|_| DatasetError::BadTensor {
        name,
        reason: "missing".into(),
    })?;
    if view.dtype() != dtype {
        return Err(DatasetError::BadTensor {
            name,
            reason: format!("dtype {:?}, expected {dtype:?}", view.dtype()),
        });
    }
    let found = view.shape();
    let matches = found.len() == shape.len()
        && found
            .iter()
            .zip(shape)
            .all(|(f, s)| s.is_none_or(|s| s == *f));
    if !matches {
        return Err(DatasetError::BadTensor {
            name,
            reason: format!("shape {found:?}, expected {shape:?}"),
        });
    }
    Ok((view.data(), found.to_vec()))
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn words(bytes: &[u8]) -> impl Iterator<Item = [u8; 8]> + '_ {
    bytes.chunks_exact(8).map(|c| {
        let mut word = [0u8; 8];
        word.copy_from_slice(c);
        word
    })
}

/// Reads an i64 offset/index tensor as non-negative usizes.
fn indices(bytes: &[u8], name: &'static str) -> Result<Vec<usize>, DatasetError> {
    words(bytes)
        .map(|w| {
            usize::try_from(i64::from_le_bytes(w)).map_err(|_| DatasetError::BadTensor {
                name,
                reason: "negative index".into(),
            })
        })
        .collect()
}

/// Checks that `offsets` starts at 0, never decreases and ends at `total`.
fn check_offsets(offsets: &[usize], total: usize, name: &str) -> Result<(), DatasetError> {
    let monotone = offsets.windows(2).all(|w| w[0] <= w[1]);
    if offsets.first() != Some(&0) || offsets.last() != Some(&total) || !monotone {
        return Err(DatasetError::Inconsistent(format!(
            "{name} must rise from 0 to {total}"
        )));
    }
    Ok(())
}

/// Checks that every task value and task parameter is finite (the per-trajectory tensors are
/// checked by [`DemoDataset::check`]).
fn check_task_floats(
    values: &[f64],
    parameters: &[f32],
    task_dim: usize,
) -> Result<(), DatasetError> {
    let non_finite = |tensor, task, value: f64| DatasetError::NonFinite {
        tensor,
        task,
        trajectory: None,
        value,
    };
    if let Some((task, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(non_finite(names::TASK_VALUES, task, value));
    }
    if let Some((i, &value)) = parameters.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(non_finite(
            names::TASK_PARAMETERS,
            i / task_dim.max(1),
            value.into(),
        ));
    }
    Ok(())
}

/// The metadata of a demo file: what it holds and its dimensions, checked against its family.
struct Meta {
    family: Family,
    physics: Physics,
    split: Split,
    expert: String,
    obs_dim: usize,
    act_dim: usize,
    task_dim: usize,
    subsample_factor: usize,
}

impl Meta {
    fn read(map: &HashMap<String, String>) -> Result<Self, DatasetError> {
        let format = map.get("format").map(String::as_str);
        if format != Some(FORMAT_NAME) {
            return Err(DatasetError::NotADemoFile(format!("format is {format:?}")));
        }
        let version: u32 = meta_parse(map, "format_version")?;
        if version != FORMAT_VERSION {
            return Err(DatasetError::UnsupportedVersion {
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        let family: Family = meta_parse(map, "family")?;
        let physics = Physics::from_name_or_default(map.get("physics").map(String::as_str))
            .map_err(|e| DatasetError::BadMetadata {
                key: "physics",
                reason: e.to_string(),
            })?;
        let meta = Meta {
            family,
            physics,
            split: meta_parse(map, "split")?,
            expert: meta(map, "expert")?.to_string(),
            obs_dim: meta_parse(map, "obs_dim")?,
            act_dim: meta_parse(map, "act_dim")?,
            task_dim: meta_parse(map, "task_dim")?,
            subsample_factor: meta_parse(map, "subsample_factor")?,
        };
        if meta.subsample_factor == 0 {
            return Err(DatasetError::BadMetadata {
                key: "subsample_factor",
                reason: "must be at least 1".into(),
            });
        }
        let dims = [
            ("obs_dim", family.obs_dim(), meta.obs_dim),
            ("act_dim", family.act_dim(), meta.act_dim),
            ("task_dim", family.task_dim(), meta.task_dim),
        ];
        DatasetError::check_lengths(dims)?;
        Ok(meta)
    }
}

/// The per-row tensors: every transition of every trajectory, in file order.
struct Rows {
    obs: Vec<f32>,
    next_obs: Vec<f32>,
    actions: Vec<f32>,
    rewards: Vec<f32>,
    dones: Vec<u8>,
    time_steps: Vec<u32>,
}

impl Rows {
    fn read(file: &SafeTensors<'_>, m: &Meta) -> Result<Self, DatasetError> {
        let (rewards, shape) = tensor(file, names::REWARDS, Dtype::F32, &[None])?;
        let n = shape[0];
        let rows_of = |name, width| tensor(file, name, Dtype::F32, &[Some(n), Some(width)]);
        let obs = f32s(rows_of(names::OBS, m.obs_dim)?.0);
        let next_obs = f32s(rows_of(names::NEXT_OBS, m.obs_dim)?.0);
        let actions = f32s(rows_of(names::ACTIONS, m.act_dim)?.0);
        let dones = tensor(file, names::DONES, Dtype::U8, &[Some(n)])?
            .0
            .to_vec();
        // A flag is 0 or 1: any other byte is a corrupt or foreign file, not "done".
        if let Some(i) = dones.iter().position(|&d| d > 1) {
            return Err(DatasetError::Inconsistent(format!(
                "`{}` row {i} holds {}, not a flag (0 or 1)",
                names::DONES,
                dones[i]
            )));
        }
        let time_steps = indices(
            tensor(file, names::TIME_STEPS, Dtype::I64, &[Some(n)])?.0,
            names::TIME_STEPS,
        )?
        .into_iter()
        .map(|t| {
            u32::try_from(t).map_err(|_| DatasetError::BadTensor {
                name: names::TIME_STEPS,
                reason: format!("time step {t} does not fit in u32"),
            })
        })
        .collect::<Result<Vec<u32>, _>>()?;
        Ok(Rows {
            obs,
            next_obs,
            actions,
            rewards: f32s(rewards),
            dones,
            time_steps,
        })
    }

    fn len(&self) -> usize {
        self.rewards.len()
    }
}

/// The index tensors: each task's value and parameters, which trajectories are its, and
/// where each trajectory's rows are.
struct Index {
    values: Vec<f64>,
    task_offsets: Vec<usize>,
    row_offsets: Vec<usize>,
    seeds: Vec<u64>,
    sub_offsets: Vec<usize>,
}

impl Index {
    fn read(file: &SafeTensors<'_>, m: &Meta, rows: usize) -> Result<Self, DatasetError> {
        let (values, shape) = tensor(file, names::TASK_VALUES, Dtype::F64, &[None])?;
        let k = shape[0];
        let shape = [Some(k), Some(m.task_dim)];
        let parameters = f32s(tensor(file, names::TASK_PARAMETERS, Dtype::F32, &shape)?.0);
        let values: Vec<f64> = words(values).map(f64::from_le_bytes).collect();
        check_task_floats(&values, &parameters, m.task_dim)?;
        let task_offsets = indices(
            tensor(file, names::TASK_TRAJ_OFFSETS, Dtype::I64, &[Some(k + 1)])?.0,
            names::TASK_TRAJ_OFFSETS,
        )?;
        let (row_offsets, shape) = tensor(file, names::TRAJ_OFFSETS, Dtype::I64, &[None])?;
        let t_count = shape[0].checked_sub(1).ok_or(DatasetError::BadTensor {
            name: names::TRAJ_OFFSETS,
            reason: "empty (needs trajectories + 1 entries)".into(),
        })?;
        let row_offsets = indices(row_offsets, names::TRAJ_OFFSETS)?;
        let seeds: Vec<u64> =
            words(tensor(file, names::TRAJ_SEEDS, Dtype::U64, &[Some(t_count)])?.0)
                .map(u64::from_le_bytes)
                .collect();
        let sub_name = names::TRAJ_SUBSAMPLE_OFFSETS;
        let sub_offsets = indices(
            tensor(file, sub_name, Dtype::I64, &[Some(t_count)])?.0,
            sub_name,
        )?;
        check_offsets(&row_offsets, rows, names::TRAJ_OFFSETS)?;
        check_offsets(&task_offsets, t_count, names::TASK_TRAJ_OFFSETS)?;
        Ok(Index {
            values,
            task_offsets,
            row_offsets,
            seeds,
            sub_offsets,
        })
    }
}

/// Cuts the rows into trajectories and the trajectories into tasks, as the index says.
fn assemble(m: &Meta, rows: &Rows, index: &Index) -> Result<Vec<TaskDemos>, DatasetError> {
    let (od, ad) = (m.obs_dim, m.act_dim);
    let mut tasks = Vec::with_capacity(index.values.len());
    for (task_index, &value) in index.values.iter().enumerate() {
        let task = m
            .family
            .task_from_value(value)
            .map_err(|e| DatasetError::Inconsistent(format!("task {task_index}: {e}")))?;
        let trajectories = (index.task_offsets[task_index]..index.task_offsets[task_index + 1])
            .map(|j| {
                let r = index.row_offsets[j]..index.row_offsets[j + 1];
                Trajectory {
                    seed: index.seeds[j],
                    subsample_offset: index.sub_offsets[j],
                    time_steps: rows.time_steps[r.clone()].to_vec(),
                    obs: rows.obs[r.start * od..r.end * od].to_vec(),
                    actions: rows.actions[r.start * ad..r.end * ad].to_vec(),
                    rewards: rows.rewards[r.clone()].to_vec(),
                    next_obs: rows.next_obs[r.start * od..r.end * od].to_vec(),
                    dones: rows.dones[r].iter().map(|&d| d != 0).collect(),
                }
            })
            .collect();
        tasks.push(TaskDemos { task, trajectories });
    }
    Ok(tasks)
}

impl DemoDataset {
    /// Parses and validates safetensors bytes written by [`DemoDataset::to_bytes`]: the
    /// metadata, the per-row tensors, the index, then the dataset as a whole.
    pub fn from_bytes(bytes: &[u8]) -> Result<DemoDataset, DatasetError> {
        check_length(bytes)?;
        let file =
            SafeTensors::deserialize(bytes).map_err(|e| DatasetError::Corrupt(e.to_string()))?;
        let (_, header) =
            SafeTensors::read_metadata(bytes).map_err(|e| DatasetError::Corrupt(e.to_string()))?;
        let empty = HashMap::new();
        let m = Meta::read(header.metadata().as_ref().unwrap_or(&empty))?;
        let rows = Rows::read(&file, &m)?;
        let index = Index::read(&file, &m, rows.len())?;
        let tasks = assemble(&m, &rows, &index)?;
        let dataset = DemoDataset {
            family: m.family,
            physics: m.physics,
            split: m.split,
            expert: m.expert,
            obs_dim: m.obs_dim,
            act_dim: m.act_dim,
            subsample_factor: m.subsample_factor,
            tasks,
        };
        dataset.check()?;
        Ok(dataset)
    }
}
