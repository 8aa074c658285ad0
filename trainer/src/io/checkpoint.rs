//! Checkpoints: one safetensors file holding every tensor of a run (weights, targets, Adam
//! moments, replay buffers) with a small JSON document (counters, RNG state, config) in its
//! `__metadata__` header under the key `smile`.
//!
//! A single file written to a temporary name and renamed over the old one is atomic on POSIX
//! file systems, so a killed run always leaves either the previous or the new checkpoint,
//! never a mix. A readable copy of the metadata is written beside it (`checkpoint.json`,
//! informational only).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use candle_core::{DType, Device, Tensor};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use crate::error::{Error, Result};

/// File name of the checkpoint inside a run directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.safetensors";

/// File name of an exported expert policy (`smile expert`) inside its run directory.
pub const POLICY_FILE: &str = "policy.safetensors";

/// File name of an expert run's best periodically evaluated policy (with `keep_best`).
pub const BEST_POLICY_FILE: &str = "policy-best.safetensors";
/// Metadata key holding the JSON document.
const META_KEY: &str = "smile";
/// Format tag stored in the metadata, checked on load.
pub const CHECKPOINT_FORMAT: &str = "smile-checkpoint-v1";

/// Files whose presence means a directory already holds a run that a fresh start would
/// destroy: a checkpoint (resumable) or a finished expert policy. A meta-policy counts only when
/// it is finished (or carries no training mark, as files made outside a run): an unfinished one
/// beside no checkpoint is what a run killed before its first checkpoint leaves, and that run
/// can only be started over ([`clear_interrupted_run`]).
const RUN_MARKERS: [&str; 2] = [CHECKPOINT_FILE, POLICY_FILE];

/// What a run writes into its directory before its first checkpoint (logs, event files, the
/// policy kept by an early evaluation, the compute count). A run interrupted before that
/// checkpoint left nothing to resume from; starting it again removes these first, so the new
/// run's log does not continue the dead one's (two step-0 rows, two event files).
const INTERRUPTED_RUN_FILES: [&str; 8] = [
    crate::io::METRICS_FILE,
    "tb",
    crate::model::META_POLICY_FILE,
    "last",
    "checkpoint.json",
    "compute.json",
    BEST_POLICY_FILE,
    ".policy-best-copy",
];

/// Refuses to start a *fresh* run in `dir` when it already holds one: starting over would
/// overwrite its checkpoint and trained policy. Continue it by resuming, or choose another
/// directory. A directory left by a run interrupted before its first checkpoint passes: there
/// is nothing to continue, and [`clear_interrupted_run`] clears it once the new run holds the
/// directory's lock.
pub fn ensure_fresh_run_dir(dir: &Path) -> Result<()> {
    let refuse = |what: &str| {
        Err(Error::input(
            crate::error::Input::Resume,
            format!(
                "{} already holds a run ({what}); resume it to continue it, or choose another \
                 output directory (nothing was overwritten)",
                dir.display()
            ),
        ))
    };
    if let Some(m) = RUN_MARKERS.iter().find(|m| dir.join(m).exists()) {
        return refuse(m);
    }
    let policy = dir.join(crate::model::META_POLICY_FILE);
    if policy.exists() {
        match crate::model::MetaPolicy::training_mark(&policy) {
            Ok(Some(mark)) if !mark.finished => {}
            Ok(Some(_)) => return refuse("a finished meta_policy.safetensors"),
            Ok(None) => return refuse("meta_policy.safetensors, made outside a training run"),
            Err(e) => {
                return Err(Error::Checkpoint {
                    path: policy,
                    reason: format!(
                        "cannot tell whether this run finished ({e}); move it away to start a \
                         new run in {}",
                        dir.display()
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Removes what a run interrupted before its first checkpoint left in `dir` (the caller holds
/// the directory's lock and has checked [`ensure_fresh_run_dir`] under it); returns the names
/// removed, for the message that says so.
pub fn clear_interrupted_run(dir: &Path) -> Result<Vec<&'static str>> {
    ensure_fresh_run_dir(dir)?;
    let mut removed = Vec::new();
    for name in INTERRUPTED_RUN_FILES {
        let path = dir.join(name);
        match sim::remove_any(&path) {
            Ok(true) => removed.push(name),
            Ok(false) => {}
            Err(e) => return Err(Error::Io { path, source: e }),
        }
    }
    Ok(removed)
}

fn ckpt_err(path: &Path, reason: impl Into<String>) -> Error {
    Error::Checkpoint {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Write `tensors` and `meta` to `dir/checkpoint.safetensors` atomically (temp file + rename),
/// with a readable copy of the metadata beside it.
pub fn save(dir: &Path, tensors: &[(String, Tensor)], meta: &serde_json::Value) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| ckpt_err(dir, e.to_string()))?;
    let path = dir.join(CHECKPOINT_FILE);
    let doc = save_file(&path, tensors, meta)?;
    let pretty = serde_json::to_string_pretty(&doc).unwrap_or_default();
    write_atomic(&dir.join("checkpoint.json"), pretty.as_bytes())?;
    Ok(path)
}

/// Write `tensors` and `meta` to the safetensors file `path` atomically; returns the metadata
/// document as written (with its format tag).
pub fn save_file(
    path: &Path,
    tensors: &[(String, Tensor)],
    meta: &serde_json::Value,
) -> Result<serde_json::Value> {
    let mut bufs: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = Vec::with_capacity(tensors.len());
    for (name, t) in tensors {
        let t = t.contiguous()?;
        let (dtype, bytes) = match t.dtype() {
            DType::F32 => (
                Dtype::F32,
                t.flatten_all()?
                    .to_vec1::<f32>()?
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect(),
            ),
            DType::U32 => (
                Dtype::U32,
                t.flatten_all()?
                    .to_vec1::<u32>()?
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect(),
            ),
            other => {
                return Err(ckpt_err(
                    path,
                    format!("{name}: unsupported dtype {other:?}"),
                ));
            }
        };
        bufs.push((name.clone(), dtype, t.dims().to_vec(), bytes));
    }
    let views = bufs
        .iter()
        .map(|(n, d, s, b)| Ok((n.as_str(), TensorView::new(*d, s.clone(), b)?)))
        .collect::<std::result::Result<Vec<_>, safetensors::SafeTensorError>>()
        .map_err(|e| ckpt_err(path, e.to_string()))?;
    let mut doc = meta.clone();
    doc["format"] = serde_json::Value::from(CHECKPOINT_FORMAT);
    let info = HashMap::from([(META_KEY.to_string(), doc.to_string())]);
    let bytes = safetensors::serialize(views, Some(info))
        .map(sim::canonical_safetensors)
        .map_err(|e| ckpt_err(path, e.to_string()))?;
    write_atomic(path, &bytes)?;
    Ok(doc)
}

/// Write `bytes` to `path` atomically ([`sim::write_atomic`]: temporary sibling, fsync,
/// rename, the temporary removed on failure); an error names the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    sim::write_atomic(path, bytes).map_err(Error::io(path))
}

/// SHA-256 of `bytes`, lower-case hex ([`sim::sha256_hex`]).
pub use sim::sha256_hex;

/// SHA-256 of the file at `path` ([`sha256_hex`]), an error naming the file.
pub fn sha256_file(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(Error::io(path))?;
    Ok(sha256_hex(&bytes))
}

/// A loaded checkpoint: tensors by name and the metadata document.
#[derive(Debug)]
pub struct Loaded {
    path: PathBuf,
    tensors: HashMap<String, Tensor>,
    /// The JSON metadata written by [`save`].
    pub meta: serde_json::Value,
}

impl Loaded {
    /// The tensor called `name`, or a clear error naming the file and the tensor.
    pub fn get(&self, name: &str) -> Result<Tensor> {
        self.tensors
            .get(name)
            .cloned()
            .ok_or_else(|| ckpt_err(&self.path, format!("missing tensor `{name}`")))
    }

    /// Where it was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A random generator saved with [`rng_state`] under metadata field `key`.
    pub fn meta_rng(&self, key: &str) -> Result<ChaCha8Rng> {
        rng_from_state(&self.meta_field::<serde_json::Value>(key)?).ok_or_else(|| {
            Error::CheckpointState {
                path: self.path.clone(),
                reason: format!("metadata field `{key}` is not a ChaCha8 state"),
            }
        })
    }

    /// A metadata field deserialised, or an error naming the field.
    pub fn meta_field<T: serde::de::DeserializeOwned>(&self, key: &str) -> Result<T> {
        let v = self
            .meta
            .get(key)
            .cloned()
            .ok_or_else(|| Error::CheckpointState {
                path: self.path.clone(),
                reason: format!("metadata has no field `{key}`"),
            })?;
        serde_json::from_value(v).map_err(|e| Error::CheckpointState {
            path: self.path.clone(),
            reason: format!("metadata field `{key}`: {e}"),
        })
    }
}

/// The largest magnitude a stored float may have: beyond it its square overflows f32, so no
/// trained network, optimiser moment or replay row holds one.
const MAX_STORED: f32 = 1.8e19;

/// Load `dir/checkpoint.safetensors` (or `dir` itself if it is a file). Truncated, corrupt or
/// foreign files give [`Error::Checkpoint`] naming the path and the problem.
pub fn load(dir: &Path) -> Result<Loaded> {
    let path = if dir.is_dir() {
        dir.join(CHECKPOINT_FILE)
    } else {
        dir.to_path_buf()
    };
    let bytes = std::fs::read(&path).map_err(|e| ckpt_err(&path, e.to_string()))?;
    // A shipped policy (its folder lists its SHA-256) must be the file shipped.
    sim::check_shipped_bytes(&path, &bytes)?;
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| ckpt_err(&path, format!("not a valid safetensors file: {e}")))?;
    let (_, header) = SafeTensors::read_metadata(&bytes)
        .map_err(|e| ckpt_err(&path, format!("bad header: {e}")))?;
    let doc = header
        .metadata()
        .as_ref()
        .and_then(|m| m.get(META_KEY))
        .ok_or_else(|| ckpt_err(&path, "no smile metadata (not a smile checkpoint)"))?;
    let meta: serde_json::Value = serde_json::from_str(doc)
        .map_err(|e| ckpt_err(&path, format!("metadata is not JSON: {e}")))?;
    if meta.get("format").and_then(|f| f.as_str()) != Some(CHECKPOINT_FORMAT) {
        return Err(ckpt_err(
            &path,
            format!("unknown format (expected {CHECKPOINT_FORMAT})"),
        ));
    }
    let mut tensors = HashMap::new();
    for name in st.names() {
        let view = st
            .tensor(name)
            .map_err(|e| ckpt_err(&path, e.to_string()))?;
        let shape = view.shape().to_vec();
        let data = view.data();
        let t = match view.dtype() {
            Dtype::F32 => {
                let v: Vec<f32> = data
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                // Every reader (resume, warm start, a policy) refuses a diverged file here, by
                // name, before a NaN surfaces far away as a loss or an action (through a ReLU a
                // NaN weight comes out 0: a policy would evaluate to a plausible number).
                // A finite value whose square overflows f32 (3e38) is as diverged: the first
                // matrix product or Adam moment makes it infinite, far from the file.
                if let Some(i) = v.iter().position(|x| x.is_nan() || x.abs() > MAX_STORED) {
                    let what = if v[i].is_finite() {
                        "a value whose square overflows f32"
                    } else {
                        "a non-finite value"
                    };
                    return Err(ckpt_err(
                        &path,
                        format!(
                            "tensor `{name}` holds {what} ({} at index {i}): the run that \
                             wrote it diverged; resume from an earlier checkpoint or train again",
                            v[i]
                        ),
                    ));
                }
                Tensor::from_vec(v, shape, &Device::Cpu)?
            }
            Dtype::U32 => {
                let v: Vec<u32> = data
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                Tensor::from_vec(v, shape, &Device::Cpu)?
            }
            other => {
                return Err(ckpt_err(
                    &path,
                    format!("{name}: unsupported dtype {other:?}"),
                ));
            }
        };
        tensors.insert(name.to_string(), t);
    }
    Ok(Loaded {
        path,
        tensors,
        meta,
    })
}

/// ChaCha8 state as JSON: seed (hex), stream and word position (decimal strings).
pub fn rng_state(rng: &ChaCha8Rng) -> serde_json::Value {
    let seed: String = rng.get_seed().iter().map(|b| format!("{b:02x}")).collect();
    serde_json::json!({
        "seed": seed,
        "stream": rng.get_stream().to_string(),
        "word_pos": rng.get_word_pos().to_string(),
    })
}

/// Inverse of [`rng_state`]; `None` if `v` is not such a state.
fn rng_from_state(v: &serde_json::Value) -> Option<ChaCha8Rng> {
    let hex = v["seed"].as_str()?;
    if hex.len() != 64 {
        return None;
    }
    let mut seed = [0u8; 32];
    for (i, b) in seed.iter_mut().enumerate() {
        *b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).ok()?;
    }
    let stream: u64 = v["stream"].as_str()?.parse().ok()?;
    let word_pos: u128 = v["word_pos"].as_str()?.parse().ok()?;
    let mut rng = ChaCha8Rng::from_seed(seed);
    rng.set_stream(stream);
    rng.set_word_pos(word_pos);
    Some(rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_corruption() {
        let dir = std::env::temp_dir().join(format!("smile-ckpt-{}", std::process::id()));
        let t = Tensor::new(&[[1.0f32, 2.0], [3.0, 4.0]], &Device::Cpu).unwrap();
        let c = Tensor::new(&[7u32, 8], &Device::Cpu).unwrap();
        let meta = serde_json::json!({"step": 5});
        save(&dir, &[("w".into(), t.clone()), ("c".into(), c)], &meta).unwrap();
        let l = load(&dir).unwrap();
        assert_eq!(
            l.get("w").unwrap().to_vec2::<f32>().unwrap(),
            t.to_vec2::<f32>().unwrap()
        );
        assert_eq!(l.meta_field::<u64>("step").unwrap(), 5);
        assert!(
            l.get("nope")
                .unwrap_err()
                .to_string()
                .contains("missing tensor `nope`")
        );
        // Truncate the file: a clear error, not a panic.
        let p = dir.join(CHECKPOINT_FILE);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 5]).unwrap();
        let e = load(&dir).unwrap_err().to_string();
        assert!(
            e.contains("checkpoint") && e.contains("not a valid safetensors"),
            "{e}"
        );
        std::fs::write(&p, b"garbage").unwrap();
        assert!(load(&dir).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
