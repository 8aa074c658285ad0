//! Metrics log: one JSON object per line (`metrics.jsonl` in the run directory) with stable
//! CleanRL-style names: `losses/qf`, `losses/actor`, `losses/alpha`, `charts/alpha`,
//! `charts/entropy`, `charts/episodic_return`, `charts/metric`, `charts/sps`. Every line has
//! `step` (environment steps) and `wall_s` (seconds since the log was opened).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::sac::SacStats;
use crate::{Error, Result};

/// File name of the metrics log inside a run directory.
pub const METRICS_FILE: &str = "metrics.jsonl";

/// An append-only JSON-lines metrics writer.
pub struct MetricsLog {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    t0: Instant,
}

impl MetricsLog {
    /// Open (append to) `dir/metrics.jsonl`.
    pub fn open(dir: &Path) -> Result<Self> {
        let path = dir.join(METRICS_FILE);
        let io = |e| Error::Io {
            path: path.clone(),
            source: e,
        };
        std::fs::create_dir_all(dir).map_err(io)?;
        let f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(io)?;
        Ok(Self {
            path,
            file: std::io::BufWriter::new(f),
            t0: Instant::now(),
        })
    }

    /// Write one line `{"step": step, "wall_s": .., name: value, ...}` (non-finite values are
    /// written as null).
    pub fn log(&mut self, step: u64, values: &[(&str, f64)]) -> Result<()> {
        let mut obj = serde_json::Map::new();
        obj.insert("step".into(), step.into());
        obj.insert("wall_s".into(), self.t0.elapsed().as_secs_f64().into());
        for (k, v) in values {
            obj.insert(
                (*k).into(),
                serde_json::Number::from_f64(*v).map_or(serde_json::Value::Null, Into::into),
            );
        }
        let line = serde_json::Value::Object(obj).to_string();
        writeln!(self.file, "{line}")
            .and_then(|_| self.file.flush())
            .map_err(|e| Error::Io {
                path: self.path.clone(),
                source: e,
            })
    }
}

/// The SAC scalars under their log names.
pub fn sac_fields(s: &SacStats) -> [(&'static str, f64); 6] {
    [
        ("losses/qf", s.qf_loss as f64),
        ("losses/qf1_value", s.qf1_mean as f64),
        ("losses/actor", s.actor_loss as f64),
        ("losses/alpha", s.alpha_loss as f64),
        ("charts/alpha", s.alpha as f64),
        ("charts/entropy", s.entropy as f64),
    ]
}
