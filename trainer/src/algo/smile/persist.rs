//! Checkpoints of a SMILe run: every tensor, both optimisers, the replay buffers, the RNG and
//! the counters, so that a resumed run continues exactly.

use std::path::Path;

use candle_core::Tensor;

use super::{Smile, SmileConfig};
use crate::algo::sac::SacCounters;
use crate::data::MetaData;
use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::io::checkpoint::rng_state;
use crate::model::{mlp_load, mlp_tensors};

impl Smile {
    /// Writes the checkpoint (every tensor, the RNG, the counters and the config) to `dir`.
    pub fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        let mut ts: Vec<(String, Tensor)> = Vec::new();
        mlp_tensors("phi", &self.encoder.phi, &mut ts);
        mlp_tensors("head", &self.encoder.head, &mut ts);
        mlp_tensors("disc", self.disc.net(), &mut ts);
        let (sac_ts, sac_counters) = self.sac.state_tensors()?;
        ts.extend(sac_ts.into_iter().map(|(k, v)| (format!("sac.{k}"), v)));
        let steps = [
            self.disc_opt.save_into("disc_opt", &mut ts)?,
            self.enc_opt.save_into("enc_opt", &mut ts)?,
        ];
        ts.extend(self.replay.to_tensors("replay")?);
        let meta = serde_json::json!({
            "kind": "smile-run",
            "config": self.cfg,
            "norm": self.data.norm,
            "sac_counters": sac_counters,
            "adam_steps": steps,
            "updates": self.updates,
            "env_steps": self.env_steps,
            "episodes": self.episodes,
            "best": if self.best.is_nan() { serde_json::Value::Null } else { self.best.into() },
            "rng": rng_state(&self.rng),
        });
        checkpoint::save(dir, &ts, &meta)?;
        // The compute used so far (`cpu_budget_s`) beside the checkpoint, not in it: a timing
        // would make the checkpoints of two identical runs differ.
        checkpoint::write_atomic(
            &dir.join(COMPUTE_FILE),
            serde_json::json!({ "cpu_s": self.cpu_s })
                .to_string()
                .as_bytes(),
        )?;
        Ok(())
    }

    /// Resumes the run checkpointed in `dir` on the same `data`; `total_updates` overrides the
    /// saved target.
    pub fn resume(dir: &Path, data: MetaData, total_updates: Option<u64>) -> Result<Self> {
        let ck = checkpoint::load(dir)?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("smile-run") {
            return Err(Error::Checkpoint {
                path: ck.path().into(),
                reason: "not a SMILe run".into(),
            });
        }
        let mut cfg: SmileConfig = ck.meta_field("config")?;
        if let Some(t) = total_updates {
            cfg.total_updates = t;
        }
        let mut run = Self::new(cfg, data)?;
        let wrap = |e: Error| Error::CheckpointState {
            path: ck.path().to_path_buf(),
            reason: format!("does not match this configuration or data: {e}"),
        };
        let get = |n: &str| ck.get(n);
        mlp_load("phi", &run.encoder.phi, &get).map_err(wrap)?;
        mlp_load("head", &run.encoder.head, &get).map_err(wrap)?;
        mlp_load("disc", run.disc.net(), &get).map_err(wrap)?;
        let counters: SacCounters = ck.meta_field("sac_counters")?;
        run.sac
            .load_state(&|n| ck.get(&format!("sac.{n}")), counters)
            .map_err(wrap)?;
        let [disc_steps, enc_steps]: [u64; 2] = ck.meta_field("adam_steps")?;
        run.disc_opt
            .load_from("disc_opt", &get, disc_steps)
            .map_err(wrap)?;
        run.enc_opt
            .load_from("enc_opt", &get, enc_steps)
            .map_err(wrap)?;
        run.replay.load_tensors("replay", &get).map_err(wrap)?;
        run.updates = ck.meta_field("updates")?;
        run.env_steps = ck.meta_field("env_steps")?;
        run.cpu_s = read_compute(dir)?;
        run.episodes = ck.meta_field("episodes")?;
        run.best = ck.meta_field::<Option<f32>>("best")?.unwrap_or(f32::NAN);
        run.rng = ck.meta_rng("rng")?;
        Ok(run)
    }
}

/// The run's compute so far, written beside every checkpoint.
const COMPUTE_FILE: &str = "compute.json";

/// The CPU-seconds recorded in `dir`'s [`COMPUTE_FILE`]; 0 where there is none (a run from
/// before the compute budget). A file that does not hold a count is an error, not a reset.
fn read_compute(dir: &Path) -> Result<f64> {
    let path = dir.join(COMPUTE_FILE);
    let Ok(text) = std::fs::read_to_string(&path) else {
        return Ok(0.0);
    };
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v["cpu_s"].as_f64())
        .filter(|v| v.is_finite() && *v >= 0.0)
        .ok_or_else(|| Error::Checkpoint {
            path,
            reason: "does not hold the run's CPU-seconds ({\"cpu_s\": N}); restore it, or \
                     delete it to count the compute from this resume"
                .into(),
        })
}
