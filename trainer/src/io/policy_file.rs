//! The meta-policy's file, `meta_policy.safetensors`: its networks' tensors, the metadata to
//! rebuild them (family, algorithm, encoder configuration, observation statistics, policy
//! widths) and the [`TrainingMark`] of the run that wrote it. An `impl MetaPolicy` here, beside
//! the other files the trainer writes, so that the networks in `model/` need no file code.

use std::path::Path;

use sim::Family;

use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::model::{
    ContextConfig, ContextEncoder, META_POLICY_FILE, MetaPolicy, ObsNorm, TanhGaussianPolicy,
    TrainingMark, mlp_load, mlp_tensors,
};

impl MetaPolicy {
    /// Writes `dir/meta_policy.safetensors` atomically, without a training mark (a policy
    /// made outside a training run).
    pub fn save(&self, dir: &Path) -> Result<()> {
        self.save_marked(dir, None)
    }

    /// Writes `dir/meta_policy.safetensors` atomically with how far its training had got.
    pub fn save_marked(&self, dir: &Path, mark: Option<TrainingMark>) -> Result<()> {
        let mut ts = Vec::new();
        mlp_tensors("phi", &self.encoder.phi, &mut ts);
        mlp_tensors("head", &self.encoder.head, &mut ts);
        mlp_tensors("policy", self.policy.net(), &mut ts);
        let meta = serde_json::json!({
            "kind": "meta-policy",
            "env": self.family.name(),
            "physics": self.physics.name(),
            "algo": self.algo,
            "context": self.encoder.config(),
            "norm": self.norm,
            "policy_widths": self.policy.net().widths(),
            "training": mark,
        });
        checkpoint::save_file(&dir.join(META_POLICY_FILE), &ts, &meta).map(|_| ())
    }

    /// A meta-learner's end of training in its run directory `dir`: this (last) policy in
    /// `dir/last/`, and the kept (best) policy in `dir/meta_policy.safetensors` marked
    /// finished; this one takes its place when no evaluation kept one, or when
    /// `replaces_kept` (SMILe without held-out tasks, whose evaluations keep nothing).
    pub(crate) fn save_final(
        &self,
        dir: &Path,
        mark: TrainingMark,
        replaces_kept: bool,
    ) -> Result<()> {
        let last = dir.join("last");
        std::fs::create_dir_all(&last).map_err(Error::io(&last))?;
        self.save_marked(&last, Some(mark))?;
        if replaces_kept || !dir.join(META_POLICY_FILE).exists() {
            self.save_marked(dir, Some(mark))
        } else {
            // The kept (best) policy was written mid-run, marked unfinished: now it is final.
            Self::mark_finished(dir)
        }
    }

    /// Marks the meta-policy file at `path` (a run directory or the file) finished, keeping its
    /// weights: training calls it once the budget is spent or it stopped early.
    pub fn mark_finished(path: &Path) -> Result<()> {
        let file = Self::file_of(path);
        let mp = Self::load(&file)?;
        let mut mark = Self::training_mark(&file)?.unwrap_or(TrainingMark {
            updates: 0,
            total_updates: 0,
            finished: true,
        });
        mark.finished = true;
        let dir = file.parent().unwrap_or(Path::new("."));
        mp.save_marked(dir, Some(mark))
    }

    /// The training mark of a meta-policy file (or a run directory's); `None` for files
    /// written before marks existed, or outside a training run.
    pub fn training_mark(path: &Path) -> Result<Option<TrainingMark>> {
        let file = Self::file_of(path);
        let ck = checkpoint::load(&file)?;
        match ck.meta.get("training") {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(_) => ck.meta_field("training").map(Some),
        }
    }

    /// Refuses a meta-policy whose training did not finish (killed, or still running), saying
    /// how to finish it; `allow` turns the refusal into a warning, returned for the caller to
    /// show.
    pub fn ensure_finished(path: &Path, allow: bool) -> Result<Option<String>> {
        let file = Self::file_of(path);
        let Some(mark) = Self::training_mark(&file)? else {
            return Ok(None);
        };
        if mark.finished {
            return Ok(None);
        }
        let dir = file.parent().unwrap_or(Path::new("."));
        let err = Error::Unfinished {
            path: file.clone(),
            updates: mark.updates,
            total: mark.total_updates,
            run: dir.to_path_buf(),
        };
        if allow {
            Ok(Some(format!("warning: {err} (used anyway, as asked)")))
        } else {
            Err(err)
        }
    }

    fn file_of(path: &Path) -> std::path::PathBuf {
        if path.is_dir() {
            path.join(META_POLICY_FILE)
        } else {
            path.to_path_buf()
        }
    }

    /// Loads a meta-policy from a run directory or a `meta_policy.safetensors` file.
    pub fn load(path: &Path) -> Result<Self> {
        let file = if path.is_dir() {
            path.join(META_POLICY_FILE)
        } else {
            path.to_path_buf()
        };
        // `load` refuses a non-finite weight, naming the tensor.
        let ck = checkpoint::load(&file)?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("meta-policy") {
            return Err(Error::Checkpoint {
                path: file,
                reason: "not a meta-policy file".into(),
            });
        }
        let family: Family = ck.meta_field("env")?;
        // Files written before the MuJoCo backend have no `physics`: Rapier's.
        let physics =
            sim::Physics::from_name_or_default(ck.meta.get("physics").and_then(|p| p.as_str()))
                .map_err(|e| Error::Checkpoint {
                    path: file.clone(),
                    reason: e.to_string(),
                })?;
        let cfg: ContextConfig = ck.meta_field("context")?;
        let norm: ObsNorm = ck.meta_field("norm")?;
        let widths: Vec<usize> = ck.meta_field("policy_widths")?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        use rand::SeedableRng;
        let (od, ad) = (family.obs_dim(), family.act_dim());
        let encoder = ContextEncoder::new(od, ad, cfg, &mut rng)?;
        if widths.len() < 2
            || widths[0] != od + encoder.z_dim()
            || *widths.last().unwrap_or(&0) != 2 * ad
        {
            return Err(Error::Shape(format!(
                "policy widths {widths:?} do not fit {family}"
            )));
        }
        let policy = TanhGaussianPolicy::new(
            widths[0],
            ad,
            &widths[1..widths.len() - 1],
            (-20.0, 2.0),
            &mut rng,
        )?;
        let get = |n: &str| ck.get(n);
        mlp_load("phi", &encoder.phi, &get)?;
        mlp_load("head", &encoder.head, &get)?;
        mlp_load("policy", policy.net(), &get)?;
        Ok(Self {
            family,
            physics,
            algo: ck.meta_field("algo")?,
            norm,
            encoder,
            policy,
        })
    }
}
