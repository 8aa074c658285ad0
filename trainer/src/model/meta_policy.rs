//! A trained meta-policy: the context encoder of [`crate::ContextEncoder`] composed with the
//! tanh-Gaussian policy on `[norm(obs), z]`; `action = tanh(mu)` (sim's actions live in
//! `[-1, 1]`, so `act_scale = 1`, `act_offset = 0`). Saved as one safetensors file, and
//! converted to [`infer_core::FloatModel`] for export with exactly infer-core's semantics
//! (tested against `FloatModel::latent` / `FloatModel::act` and the f32 blob).

use std::path::Path;

use candle_core::Tensor;
use rand::Rng;
use sim::{Family, Trajectory};

use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::model::Mlp;
use crate::model::TanhGaussianPolicy;
use crate::model::{ContextConfig, ContextEncoder, ObsNorm};

/// File name of a trained meta-policy inside a run directory.
pub const META_POLICY_FILE: &str = "meta_policy.safetensors";

/// How far the training that wrote a meta-policy file had got, stored in the file itself so a
/// policy from a killed run cannot pass for a finished one (a copied file keeps it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TrainingMark {
    /// Update pairs (SMILe) or gradient steps (Meta-BC) done when the file was written.
    pub updates: u64,
    /// The run's budget.
    pub total_updates: u64,
    /// True only once training ended (budget spent or early stop) and this file was final.
    pub finished: bool,
}

/// A trained meta-policy: encoder, conditioned policy and observation statistics.
#[derive(Debug, Clone)]
pub struct MetaPolicy {
    /// Task family.
    pub family: Family,
    /// Which algorithm produced it (`smile`, `smile-state-only`, `meta-bc`, `meta-dagger`).
    pub algo: String,
    /// Observation normalisation (from the meta-train demos).
    pub norm: ObsNorm,
    /// The context encoder.
    pub encoder: ContextEncoder,
    /// The policy on `[norm(obs), z]`.
    pub policy: TanhGaussianPolicy,
}

/// Appends `m`'s tensors as `prefix.0`, `prefix.1`, ... (weights and biases in order).
pub(crate) fn mlp_tensors(prefix: &str, m: &Mlp, out: &mut Vec<(String, Tensor)>) {
    for (i, v) in m.vars().iter().enumerate() {
        out.push((format!("{prefix}.{i}"), v.as_tensor().detach()));
    }
}

/// Loads `m`'s tensors written by [`mlp_tensors`] under `prefix`.
pub(crate) fn mlp_load(prefix: &str, m: &Mlp, get: &dyn Fn(&str) -> Result<Tensor>) -> Result<()> {
    let ts = (0..m.vars().len())
        .map(|i| get(&format!("{prefix}.{i}")))
        .collect::<Result<Vec<_>>>()?;
    m.load_from(&ts)
}

/// One [`Mlp`] as infer-core layers (weights transposed to `[out][in]`), ReLU between layers,
/// the last activation identity; only the first `keep_out` outputs of the last layer are kept.
pub fn mlp_to_layers(m: &Mlp, keep_out: Option<usize>) -> Result<Vec<infer_core::FloatLayer>> {
    let vars = m.vars();
    let n = vars.len() / 2;
    let mut layers = Vec::with_capacity(n);
    for l in 0..n {
        let w = vars[2 * l].as_tensor().detach(); // (in, out)
        let b = vars[2 * l + 1].as_tensor().detach().flatten_all()?;
        let (in_dim, mut out_dim) = w.dims2()?;
        let (mut wt, mut bias) = (w.t()?.contiguous()?, b);
        if l + 1 == n
            && let Some(k) = keep_out
        {
            wt = wt.narrow(0, 0, k)?.contiguous()?;
            bias = bias.narrow(0, 0, k)?;
            out_dim = k;
        }
        layers.push(infer_core::FloatLayer {
            in_dim,
            out_dim,
            weights: wt.flatten_all()?.to_vec1::<f32>()?,
            bias: bias.to_vec1::<f32>()?,
            activation: if l + 1 == n {
                infer_core::Activation::Identity
            } else {
                infer_core::Activation::Relu
            },
        });
    }
    Ok(layers)
}

impl MetaPolicy {
    /// Latent width.
    pub fn z_dim(&self) -> usize {
        self.encoder.z_dim()
    }

    /// Posterior mean of z for a context of trajectories.
    pub fn latent(&self, context: &[&Trajectory]) -> Result<Vec<f32>> {
        self.encoder.latent(&self.norm, context)
    }

    /// The action for a raw observation given z: `tanh(mu)` if deterministic, else a sample.
    pub fn act(
        &self,
        obs: &[f32],
        z: &[f32],
        deterministic: bool,
        rng: &mut impl Rng,
    ) -> Result<Vec<f32>> {
        let mut x = self.norm.apply(obs);
        x.extend_from_slice(z);
        self.policy.act(&x, deterministic, rng)
    }

    /// The blob structure of this policy: encoder, the mean rows of the Gaussian head, and the
    /// mean rows of the policy's last layer, with the observation statistics and unit action
    /// scaling.
    pub fn to_float_model(&self) -> Result<infer_core::FloatModel> {
        let (od, ad) = (self.norm.mean.len(), self.policy.act_dim());
        Ok(infer_core::FloatModel {
            kind: if self.encoder.config().state_only {
                infer_core::ModelKind::StateOnly
            } else {
                infer_core::ModelKind::StateAction
            },
            obs_dim: od,
            act_dim: ad,
            r_dim: self.encoder.config().r_dim,
            z_dim: self.z_dim(),
            obs_mean: self.norm.mean.clone(),
            obs_std: self.norm.std.clone(),
            act_scale: vec![1.0; ad],
            act_offset: vec![0.0; ad],
            encoder: mlp_to_layers(&self.encoder.phi, None)?,
            z_head: mlp_to_layers(&self.encoder.head, Some(self.z_dim()))?,
            policy: mlp_to_layers(self.policy.net(), Some(ad))?,
        })
    }

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
            "algo": self.algo,
            "context": self.encoder.config(),
            "norm": self.norm,
            "policy_widths": self.policy.net().widths(),
            "training": mark,
        });
        checkpoint::save_file(&dir.join(META_POLICY_FILE), &ts, &meta).map(|_| ())
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
    /// how to finish it; `allow` turns the refusal into a warning on stderr.
    pub fn ensure_finished(path: &Path, allow: bool) -> Result<()> {
        let file = Self::file_of(path);
        let Some(mark) = Self::training_mark(&file)? else {
            return Ok(());
        };
        if mark.finished {
            return Ok(());
        }
        let dir = file.parent().unwrap_or(Path::new("."));
        let err = Error::Unfinished {
            path: file.clone(),
            updates: mark.updates,
            total: mark.total_updates,
            resume: format!("smile train --resume -o {} --demos DEMOS", dir.display()),
        };
        if allow {
            eprintln!("warning: {err} (used anyway: --allow-unfinished)");
            Ok(())
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
        let ck = checkpoint::load(&file)?;
        ck.ensure_finite()?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("meta-policy") {
            return Err(Error::Checkpoint {
                path: file,
                reason: "not a meta-policy file".into(),
            });
        }
        let family: Family = ck.meta_field("env")?;
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
            algo: ck.meta_field("algo")?,
            norm,
            encoder,
            policy,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::context::tests::{close, setup};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn float_model_matches_candle_and_infer_core() {
        for state_only in [false, true] {
            let (enc, norm, trajs) = setup(state_only);
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let policy = TanhGaussianPolicy::new(8, 2, &[16, 16], (-20.0, 2.0), &mut rng).unwrap();
            let mp = MetaPolicy {
                family: Family::PointGoal,
                algo: "test".into(),
                norm,
                encoder: enc,
                policy,
            };
            let fm = mp.to_float_model().unwrap();
            let refs: Vec<&Trajectory> = trajs.iter().collect();
            let raw: Vec<Vec<Vec<f32>>> = trajs
                .iter()
                .map(|t| {
                    (0..t.len())
                        .map(|i| {
                            let tr = t.transition(i, 4, 2).unwrap();
                            let mut v = tr.obs.to_vec();
                            if !state_only {
                                v.extend_from_slice(tr.action);
                            }
                            v.extend_from_slice(tr.next_obs);
                            v
                        })
                        .collect()
                })
                .collect();
            let z_candle = mp.latent(&refs).unwrap();
            let z_float = fm.latent(&raw);
            assert!(
                close(&z_float, &z_candle, 1e-4),
                "{z_float:?} vs {z_candle:?}"
            );
            let obs = [0.5f32, -1.0, 0.2, 0.1];
            let a_candle = mp.act(&obs, &z_candle, true, &mut rng).unwrap();
            let a_float = fm.act(&obs, &z_float);
            assert!(close(&a_float, &a_candle, 1e-4));
            // The f32 blob through infer-core's streaming encoder and policy.
            let blob =
                infer_core::write_blob(&fm, infer_core::Quant::F32, &Default::default()).unwrap();
            let model = infer_core::Model::from_bytes(&blob).unwrap();
            let mut ce = infer_core::ContextEncoder::<64>::new(&model).unwrap();
            for t in &trajs {
                for i in 0..t.len() {
                    let tr = t.transition(i, 4, 2).unwrap();
                    ce.push(tr.obs, tr.action, tr.next_obs).unwrap();
                }
                ce.end_trajectory();
            }
            let mut z_blob = vec![0.0f32; 4];
            ce.latent(&mut z_blob).unwrap();
            assert!(close(&z_blob, &z_candle, 1e-4));
            let mut pol = infer_core::Policy::<64>::new(&model).unwrap();
            let mut a_blob = [0.0f32; 2];
            pol.act(&obs, &z_blob, &mut a_blob).unwrap();
            assert!(close(&a_blob, &a_candle, 1e-4));
        }
    }

    #[test]
    fn save_load_round_trip() {
        let (enc, norm, trajs) = setup(true);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let policy = TanhGaussianPolicy::new(8, 2, &[16], (-20.0, 2.0), &mut rng).unwrap();
        let mp = MetaPolicy {
            family: Family::PointGoal,
            algo: "meta-bc".into(),
            norm,
            encoder: enc,
            policy,
        };
        let dir = std::env::temp_dir().join(format!("smile-meta-policy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        mp.save(&dir).unwrap();
        let back = MetaPolicy::load(&dir).unwrap();
        let refs: Vec<&Trajectory> = trajs.iter().collect();
        assert_eq!(back.latent(&refs).unwrap(), mp.latent(&refs).unwrap());
        assert_eq!(back.norm, mp.norm);
        assert!(back.encoder.config().state_only);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
