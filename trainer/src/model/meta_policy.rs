//! A trained meta-policy: the context encoder of [`crate::model::ContextEncoder`] composed with the
//! tanh-Gaussian policy on `[norm(obs), z]`; `action = tanh(mu)` (sim's actions live in
//! `[-1, 1]`, so `act_scale = 1`, `act_offset = 0`). Saved as one safetensors file (the file's
//! reading and writing live with the other files, in `crate::io::policy_file`), and
//! converted to [`infer_core::FloatModel`] for export with exactly infer-core's semantics
//! (tested against `FloatModel::latent` / `FloatModel::act` and the f32 blob).

use candle_core::Tensor;
use rand::Rng;
use sim::{Family, Trajectory};

use crate::error::Result;
use crate::model::TanhGaussianPolicy;
use crate::model::{ContextEncoder, ObsNorm};
use crate::model::{Mlp, TensorLookup};

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
    /// The plant it was trained on (evaluation and the device run it there).
    pub physics: sim::Physics,
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
pub(crate) fn mlp_load(prefix: &str, m: &Mlp, get: TensorLookup) -> Result<()> {
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
}

/// Something that turns a context into z and acts deterministically given z: a candle
/// [`MetaPolicy`] or an exported blob (`eval::blob::BlobActor`). The evaluation protocols and
/// the ONNX reference values run any of them.
pub trait ConditionedActor {
    /// Posterior mean of z for a context of trajectories.
    fn latent(&mut self, context: &[&Trajectory]) -> Result<Vec<f32>>;
    /// Deterministic action for a raw observation.
    fn act(&mut self, obs: &[f32], z: &[f32], action: &mut [f32]) -> Result<()>;
}

impl ConditionedActor for MetaPolicy {
    fn latent(&mut self, context: &[&Trajectory]) -> Result<Vec<f32>> {
        MetaPolicy::latent(self, context)
    }
    fn act(&mut self, obs: &[f32], z: &[f32], action: &mut [f32]) -> Result<()> {
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0); // unused: deterministic
        action.copy_from_slice(&MetaPolicy::act(self, obs, z, true, &mut rng)?);
        Ok(())
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
                family: Family::POINT_GOAL,
                physics: sim::Physics::Rapier,
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
            family: Family::POINT_GOAL,
            physics: sim::Physics::Rapier,
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
