//! Export of a trained [`MetaPolicy`](crate::model::MetaPolicy) as ONNX, for runtimes other than infer-core.
//!
//! Two graphs and a description, in one directory (`smile export --format onnx -o DIR`):
//!
//! * [`ENCODER_FILE`]: raw context transitions -> the posterior mean of z. Inputs
//!   `context` `[trajectories, steps, transition]` (`[s, a, s']` or, state-only, `[s, s']`,
//!   raw) and `mask` `[trajectories, steps]` (1 for a real step, 0 for padding; a trajectory
//!   whose mask is all 0 does not count); output `z` `[1, z_dim]`. The graph is the trainer's
//!   encoder op for op:
//!
//!   ```text
//!   x = (context - M) / S                    M, S: the demo-state mean / std on s and s', 0 / 1 on a
//!   r = phi(x)                               MatMul, Add, Relu per layer: [trajectories, steps, r]
//!   rbar_j = sum_t mask_jt r_jt / max(sum_t mask_jt, 1)      Mul, ReduceSum, Max, Div
//!   s = sum_j rbar_j                         ReduceSum: the sum (not the mean) over trajectories
//!   z = head(s)[:z_dim]                      the head's mu rows only (as in the blob)
//!   ```
//! * [`POLICY_FILE`]: `observation` `[batch, obs_dim]` (raw) and `z` `[batch, z_dim]` ->
//!   `action` `[batch, act_dim]`, the deterministic `tanh(mu)` on `[(obs - mean) / std, z]`.
//! * [`META_FILE`]: the family, the algorithm, the opset, every input and output with its shape,
//!   the normalisation (the graphs apply it: feed raw observations).
//!
//! The weights and statistics come from [`MetaPolicy::to_float_model`](crate::model::MetaPolicy::to_float_model), the structure the blob
//! is written from, so the two exports cannot drift apart. The trajectory, step and batch axes
//! are symbolic (`dim_param`). [`reference`](fn@reference) computes the trainer's z and actions on held-out
//! contexts (padded and masked the way a runtime would get them), which `smile export` stores
//! as [`REFERENCE_FILE`] for `docs/scripts/onnx_parity.py`; `app/tests/onnx.rs` runs the
//! graphs with tract against the same values.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::checkpoint;

mod graph;
mod reference;

pub use graph::export;
pub use reference::{Reference, ReferenceContext, reference};

/// The ONNX operator set the graphs are written for (default domain).
pub const OPSET: i64 = 17;
/// The ONNX IR version that goes with [`OPSET`].
pub const IR_VERSION: i64 = 8;
/// The encoder graph's file name inside the export directory.
pub const ENCODER_FILE: &str = "encoder.onnx";
/// The policy graph's file name inside the export directory.
pub const POLICY_FILE: &str = "policy.onnx";
/// The description's file name inside the export directory.
pub const META_FILE: &str = "onnx.json";
/// The parity reference's file name inside the export directory (safetensors).
pub const REFERENCE_FILE: &str = "reference.safetensors";

/// Input and output names of the two graphs (static: a runtime can hard-code them).
pub mod names {
    /// Encoder input: raw transitions `[trajectories, steps, transition]`.
    pub const CONTEXT: &str = "context";
    /// Encoder input: `[trajectories, steps]`, 1 for a real step, 0 for padding.
    pub const MASK: &str = "mask";
    /// Encoder output `[1, z_dim]`, and policy input `[batch, z_dim]`.
    pub const Z: &str = "z";
    /// Policy input: raw observations `[batch, obs_dim]`.
    pub const OBSERVATION: &str = "observation";
    /// Policy output: `[batch, act_dim]`.
    pub const ACTION: &str = "action";
}

/// One graph input or output as [`META_FILE`] describes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TensorInfo {
    /// Its name in the graph.
    pub name: String,
    /// Always `float32`.
    pub dtype: String,
    /// Each dimension: a number, or the name of a symbolic axis.
    pub shape: Vec<serde_json::Value>,
}

/// One graph of the export.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraphInfo {
    /// File name inside the export directory.
    pub file: String,
    /// Inputs, in order.
    pub inputs: Vec<TensorInfo>,
    /// Outputs, in order.
    pub outputs: Vec<TensorInfo>,
}

/// The normalisation the graphs apply (feed them raw observations).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// What it is applied to.
    pub applied_to: String,
    /// Per-component mean of the meta-train demo states.
    pub obs_mean: Vec<f32>,
    /// Per-component std of the meta-train demo states.
    pub obs_std: Vec<f32>,
}

/// What [`META_FILE`] holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OnnxMeta {
    /// `smile-meta-policy-onnx`.
    pub format: String,
    /// ONNX operator set (default domain).
    pub opset: i64,
    /// ONNX IR version.
    pub ir_version: i64,
    /// Task family.
    pub family: String,
    /// Algorithm that trained the policy.
    pub algo: String,
    /// The plant it was trained on (`rapier` or `mujoco`); absent in exports made before this
    /// field: Rapier's.
    #[serde(default)]
    pub physics: sim::Physics,
    /// `state-action` (`[s, a, s']` transitions) or `state-only` (`[s, s']`).
    pub kind: String,
    /// The layout of one context transition.
    pub transition: String,
    /// Observation width.
    pub obs_dim: usize,
    /// Action width.
    pub act_dim: usize,
    /// Transition width (the context's last axis).
    pub transition_dim: usize,
    /// Per-transition representation width.
    pub r_dim: usize,
    /// Latent width.
    pub z_dim: usize,
    /// The context encoder.
    pub encoder: GraphInfo,
    /// The conditioned policy.
    pub policy: GraphInfo,
    /// The observation normalisation inside both graphs.
    pub normalisation: Normalisation,
    /// What the policy's output is, in words.
    pub action: String,
    /// How the encoder aggregates, in words.
    pub aggregation: String,
    /// The parity reference file, when one was written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceInfo>,
}

/// What [`META_FILE`] says of [`REFERENCE_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// File name inside the export directory.
    pub file: String,
    /// The demo file the contexts and observations come from.
    pub source: String,
    /// Contexts stored.
    pub contexts: usize,
    /// Observations stored (over all contexts).
    pub observations: usize,
}

/// The serialised graphs and their description.
#[derive(Debug, Clone)]
pub struct OnnxExport {
    /// `encoder.onnx` bytes.
    pub encoder: Vec<u8>,
    /// `policy.onnx` bytes.
    pub policy: Vec<u8>,
    /// The description.
    pub meta: OnnxMeta,
}

/// True if `dir` is empty or holds an earlier ONNX export (its description file and nothing
/// but the files an export writes): only such a directory is replaced.
fn replaceable(dir: &Path) -> Result<bool> {
    let ours = [ENCODER_FILE, POLICY_FILE, META_FILE, REFERENCE_FILE];
    let mut has_meta = false;
    let mut empty = true;
    for entry in std::fs::read_dir(dir).map_err(Error::io(dir))? {
        let name = entry.map_err(Error::io(dir))?.file_name();
        empty = false;
        match name.to_str() {
            Some(n) if n == META_FILE => has_meta = true,
            Some(n) if ours.contains(&n) => {}
            _ => return Ok(false),
        }
    }
    Ok(empty || has_meta)
}

/// What an export killed mid-way left beside `out` (hidden `.{name}.onnx-tmp-PID` and
/// `.{name}.onnx-old-PID` folders of processes no longer running): a half-written new export
/// is removed, and a previous export moved aside just before the kill goes back to `out` if
/// nothing replaced it. Exports still running (their PID alive) are left alone.
fn recover_dead_exports(parent: &Path, name: &str, out: &Path) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(rest) = file
            .to_str()
            .and_then(|f| f.strip_prefix(&format!(".{name}.onnx-")))
        else {
            continue;
        };
        let Some((kind, pid)) = rest.split_once('-') else {
            continue;
        };
        let alive = pid
            .parse::<u32>()
            .is_ok_and(|p| p == std::process::id() || Path::new("/proc").join(pid).exists());
        if alive {
            continue;
        }
        let path = entry.path();
        match kind {
            "old" if !out.exists() => std::fs::rename(&path, out).map_err(Error::io(out))?,
            "tmp" | "old" => std::fs::remove_dir_all(&path).map_err(Error::io(&path))?,
            _ => {}
        }
    }
    Ok(())
}

/// Writes `export` (and `reference`, if any) to the directory `out`: everything goes to a
/// temporary directory beside `out` first, which is renamed to `out` once complete, so a
/// failure leaves nothing half-written. An existing `out` is replaced only if it is empty or
/// an earlier ONNX export. Returns the file paths written.
pub fn write_dir(
    out: &Path,
    export: &OnnxExport,
    reference: Option<(&Reference, &str)>,
) -> Result<Vec<PathBuf>> {
    let usage = |why: String| Error::Usage(format!("cannot write {}: {why}", out.display()));
    let name = out
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| usage("not a directory name".into()))?;
    if out.is_file() {
        return Err(usage("it is a file; an ONNX export is a directory".into()));
    }
    if out.is_dir() && !replaceable(out)? {
        return Err(usage(
            "the directory holds other files than an ONNX export; choose a new or empty one".into(),
        ));
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| usage(e.to_string()))?;
    recover_dead_exports(&parent, name, out)?;
    let tmp = parent.join(format!(".{name}.onnx-tmp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir(&tmp).map_err(|e| usage(e.to_string()))?;
    let result = (|| -> Result<()> {
        let mut meta = export.meta.clone();
        checkpoint::write_atomic(&tmp.join(ENCODER_FILE), &export.encoder)?;
        checkpoint::write_atomic(&tmp.join(POLICY_FILE), &export.policy)?;
        if let Some((r, source)) = reference {
            checkpoint::write_atomic(&tmp.join(REFERENCE_FILE), &r.to_safetensors()?)?;
            meta.reference = Some(ReferenceInfo {
                file: REFERENCE_FILE.into(),
                source: source.into(),
                contexts: r.contexts.len(),
                observations: r.observation_count(),
            });
        }
        let json = serde_json::to_vec_pretty(&meta).map_err(|e| Error::Serialise {
            what: "onnx.json",
            reason: e.to_string(),
        })?;
        checkpoint::write_atomic(&tmp.join(META_FILE), &json)?;
        // Swap in: an earlier export moves aside first and goes once the new one is in place.
        let old = parent.join(format!(".{name}.onnx-old-{}", std::process::id()));
        let had_old = out.is_dir();
        if had_old {
            std::fs::rename(out, &old).map_err(Error::io(out))?;
        }
        if let Err(e) = std::fs::rename(&tmp, out) {
            if had_old {
                let _ = std::fs::rename(&old, out);
            }
            return Err(Error::io(out)(e));
        }
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(match e {
            Error::Usage(m) => Error::Usage(m),
            other => usage(other.to_string()),
        });
    }
    let mut files = vec![out.join(ENCODER_FILE), out.join(POLICY_FILE)];
    if reference.is_some() {
        files.push(out.join(REFERENCE_FILE));
    }
    files.push(out.join(META_FILE));
    Ok(files)
}
