//! The export report: what `smile export` measured about a policy blob, written beside it as
//! `<blob>.json` and read back by `firmware-sim` (which plant to run, which blob it describes,
//! the host's per-task metric to compare the device with). One definition for the writer and
//! the reader, here on the floor both stand on.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::kinds::Physics;

use crate::family::Family;

/// One task's result for one method (an evaluation's row; the report's per-task lists).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskResult {
    /// Task label, e.g. `goal_angle=0.0982`.
    pub task: String,
    /// The task parameter (goal angle, target velocity, dynamics seed).
    pub value: f64,
    /// Mean metric over all sizes, draws and rollouts.
    pub metric: f32,
    /// Mean metric per context size (same order as the protocol's sizes).
    pub by_context_size: Vec<f32>,
    /// Classification families: the fraction of episodes that made no decision.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_op_rate: Option<f32>,
}

/// Blob-vs-float differences on held-out contexts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Parity {
    /// Contexts compared (one per task of the contexts file, its first trajectory).
    pub contexts: usize,
    /// Actions compared.
    pub actions: usize,
    /// Max abs difference of z.
    pub z_max_abs_diff: f32,
    /// Max abs difference of actions (each side with its own z: end to end).
    pub action_max_abs_diff: f32,
    /// Mean abs difference of actions.
    pub action_mean_abs_diff: f32,
    /// Mean abs difference of actions when the blob's policy is given the float z: the
    /// policy's own share of the error (the rest comes from the blob's z).
    #[serde(default)]
    pub action_mean_abs_diff_same_z: f32,
}

/// What an export measured: blob size, parity with the float policy and the family's metric
/// with both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExportReport {
    /// Blob size in bytes.
    pub bytes: usize,
    /// SHA-256 of the blob this report describes (lower-case hex): `firmware-sim compare`
    /// refuses a report beside another blob (an interrupted re-export). Empty in reports
    /// written before the field.
    #[serde(default)]
    pub blob_sha256: String,
    /// `f32`, `w8a32` or `w8a8`.
    pub quant: String,
    /// The higher precision of the first and last layer of each MLP (`w8a32` or `f32`) when
    /// the blob keeps them finer than `quant` (`smile export --edges`); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edges: Option<String>,
    /// The precision of every layer of the context encoder and z head (`w8a32` or `f32`) when
    /// the blob keeps them finer than `quant` (`smile export --context-quant`); absent
    /// otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub context: Option<String>,
    /// Adam steps of the quantization-aware fine-tune the blob's weights came from (`smile
    /// export --qat-steps`); absent when the blob quantizes the trained weights as they are.
    /// The float metric and the parity are then those of the policy before the fine-tune.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub qat_steps: Option<usize>,
    /// Algorithm of the exported policy.
    pub algo: String,
    /// The family, written by its name.
    pub env: Family,
    /// The plant the policy was trained and verified on (reports written before the MuJoCo
    /// backend are Rapier's); the device runs it there.
    #[serde(default)]
    pub physics: Physics,
    /// z / action differences on held-out contexts.
    pub parity: Parity,
    /// Metric name.
    pub metric: String,
    /// Split of the contexts the metric ran on.
    pub split: String,
    /// The metric with the blob policy (mean over tasks).
    pub metric_blob: f32,
    /// The metric with the float policy (mean over tasks).
    pub metric_candle: f32,
    /// `(blob - float) / |float|`.
    pub metric_relative_difference: f32,
    /// Per-task blob results.
    pub per_task_blob: Vec<TaskResult>,
    /// Per-task float results.
    pub per_task_candle: Vec<TaskResult>,
}

/// A report that cannot be read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The report.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file is not an export report (what is wrong or missing is in `reason`).
    #[error("{} is not an export report: {reason}", path.display())]
    Parse {
        /// The report.
        path: PathBuf,
        /// What is wrong: serde's message, naming the field.
        reason: String,
    },
}

impl ExportReport {
    /// Where `smile export` writes the report of `blob`: `<blob>.json`.
    pub fn path_beside(blob: &Path) -> PathBuf {
        let mut p = blob.as_os_str().to_owned();
        p.push(".json");
        PathBuf::from(p)
    }

    /// Reads the report at `path`.
    pub fn read(path: &Path) -> Result<Self, ReportError> {
        let text = std::fs::read_to_string(path).map_err(|source| ReportError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| ReportError::Parse {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Writes the report to `path` (pretty JSON, atomically).
    pub fn write(&self, path: &Path) -> Result<(), ReportError> {
        let json = serde_json::to_string_pretty(self).map_err(|e| ReportError::Parse {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        crate::fsio::write_atomic(path, json.as_bytes()).map_err(|source| ReportError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}
