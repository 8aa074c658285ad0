//! Verification of an exported blob: it is loaded with `infer_core::Model`, its z and actions
//! are compared with the candle policy on held-out contexts (max / mean absolute difference),
//! and the family's metric is run with the blob policy beside the float one.

use sim::{DemoDataset, Trajectory};

use crate::error::{Error, Result};
use crate::eval::ConditionedActor;
use crate::io::export::{BLOB_CAPACITY, check_demos_fit, load_blob};
use crate::model::MetaPolicy;

/// A loaded blob as a [`ConditionedActor`]: one infer-core policy runner, built once and
/// reused for every action (as on the device).
pub struct BlobActor<'m, 'a> {
    model: &'m infer_core::Model<'a>,
    policy: infer_core::Policy<'m, 'a, BLOB_CAPACITY>,
}

impl<'m, 'a> BlobActor<'m, 'a> {
    /// An actor on `model` (from [`load_blob`]).
    pub fn new(model: &'m infer_core::Model<'a>) -> Result<Self> {
        let policy = infer_core::Policy::<BLOB_CAPACITY>::new(model)
            .map_err(|e| Error::Shape(format!("blob does not fit the runner: {e}")))?;
        Ok(Self { model, policy })
    }

    /// The loaded model.
    pub fn model(&self) -> &infer_core::Model<'a> {
        self.model
    }
}

impl ConditionedActor for BlobActor<'_, '_> {
    fn latent(&mut self, context: &[&Trajectory]) -> Result<Vec<f32>> {
        let h = *self.model.header();
        let (od, ad) = (h.obs_dim as usize, h.act_dim as usize);
        let mut enc = infer_core::ContextEncoder::<BLOB_CAPACITY>::new(self.model)?;
        for t in context {
            for i in 0..t.len() {
                enc.push(
                    &t.obs[i * od..(i + 1) * od],
                    &t.actions[i * ad..(i + 1) * ad],
                    &t.next_obs[i * od..(i + 1) * od],
                )?;
            }
            enc.end_trajectory();
        }
        let mut z = vec![0.0f32; h.z_dim as usize];
        enc.latent(&mut z)?;
        Ok(z)
    }

    fn act(&mut self, obs: &[f32], z: &[f32], action: &mut [f32]) -> Result<()> {
        Ok(self.policy.act(obs, z, action)?)
    }
}

/// Blob-vs-candle differences on held-out contexts (the export report's field).
pub use sim::Parity;

/// Compares the blob with the candle policy on every task of `contexts` (context = the
/// task's first trajectory; observations = the states of all its trajectories).
pub fn parity(
    mp: &MetaPolicy,
    blob: &mut BlobActor<'_, '_>,
    contexts: &DemoDataset,
) -> Result<Parity> {
    let mut mp = mp.clone();
    let ad = contexts.act_dim;
    let (mut zmax, mut amax, mut asum, mut n, mut c) = (0.0f32, 0.0f32, 0.0f64, 0usize, 0usize);
    let mut same_z_sum = 0.0f64;
    let (mut a1, mut a2, mut a3) = (vec![0.0f32; ad], vec![0.0f32; ad], vec![0.0f32; ad]);
    for td in &contexts.tasks {
        let Some(first) = td.trajectories.iter().find(|t| !t.is_empty()) else {
            continue;
        };
        let zc = ConditionedActor::latent(&mut mp, &[first])?;
        let zb = blob.latent(&[first])?;
        zmax = zc
            .iter()
            .zip(&zb)
            .fold(zmax, |m, (a, b)| m.max((a - b).abs()));
        c += 1;
        for t in &td.trajectories {
            for o in t.obs.chunks_exact(contexts.obs_dim) {
                ConditionedActor::act(&mut mp, o, &zc, &mut a1)?;
                blob.act(o, &zb, &mut a2)?;
                blob.act(o, &zc, &mut a3)?;
                for ((x, y), w) in a1.iter().zip(&a2).zip(&a3) {
                    let d = (x - y).abs();
                    amax = amax.max(d);
                    asum += d as f64;
                    same_z_sum += (x - w).abs() as f64;
                    n += 1;
                }
            }
        }
    }
    Ok(Parity {
        contexts: c,
        actions: n / ad.max(1),
        z_max_abs_diff: zmax,
        action_max_abs_diff: amax,
        action_mean_abs_diff: (asum / n.max(1) as f64) as f32,
        action_mean_abs_diff_same_z: (same_z_sum / n.max(1) as f64) as f32,
    })
}

/// What [`verify`] measured (serialised next to the blob by `smile export`, read by
/// `firmware-sim`): one definition, in `sim`.
pub use sim::ExportReport;

/// What a loaded blob keeps finer than its own quantization, as an export report records it:
/// the policy's edge layers, and the context encoder with the z head (`None`: the blob's own).
pub fn finer_precisions(model: &infer_core::Model<'_>) -> (Option<String>, Option<String>) {
    use infer_core::Mlp;
    (
        finer_layers(model, &[Mlp::Policy], true),
        finer_layers(model, &[Mlp::Encoder, Mlp::ZHead], false),
    )
}

/// The precision the blob keeps finer than its own quantization: the first layer's of `mlps`
/// (`first_only`, the edges), or the coarsest of all their layers (the context encoder kept
/// finer throughout); `None` when it is the blob's own.
fn finer_layers(
    model: &infer_core::Model<'_>,
    mlps: &[infer_core::Mlp],
    first_only: bool,
) -> Option<String> {
    let header = model.header().quant;
    let mut quants = mlps.iter().flat_map(|&m| model.layer_quants(m));
    let q = if first_only {
        quants.next()?
    } else {
        quants.reduce(|a, b| if a.at_least(b) { b } else { a })?
    };
    (q != header).then(|| crate::io::export::quant_name(q))
}

/// Loads `blob` with infer-core, measures [`parity`] on `contexts` and runs the family's
/// metric (`protocol`) on the contexts' split with the blob and with the candle policy.
pub fn verify(
    mp: &MetaPolicy,
    blob: &[u8],
    quant: &str,
    contexts: &DemoDataset,
    protocol: &super::Protocol,
) -> Result<ExportReport> {
    check_demos_fit(mp, contexts, "the contexts")?;
    let model = load_blob(blob)?;
    let mut actor = BlobActor::new(&model)?;
    let parity = parity(mp, &mut actor, contexts)?;
    let (family, split) = (mp.family, contexts.split);
    // The family's metric with the blob's policy, then with the float one, same protocol.
    let metric = |actor: &mut dyn ConditionedActor, name: &str| {
        super::evaluate(
            actor,
            name,
            family,
            split,
            contexts,
            protocol,
            &mut |_, _| {},
        )
    };
    let blob_m = metric(&mut actor, "blob")?;
    let float_m = metric(&mut mp.clone(), "candle")?;
    let (edges, context) = finer_precisions(&model);
    Ok(ExportReport {
        bytes: blob.len(),
        blob_sha256: crate::io::checkpoint::sha256_hex(blob),
        quant: quant.into(),
        edges,
        context,
        qat_steps: None,
        algo: mp.algo.clone(),
        env: family,
        physics: mp.physics,
        parity,
        metric: super::metric_name(family.metric_kind()).into(),
        split: split.to_string(),
        metric_blob: blob_m.mean,
        metric_candle: float_m.mean,
        metric_relative_difference: (blob_m.mean - float_m.mean) / float_m.mean.abs().max(1e-9),
        per_task_blob: blob_m.tasks,
        per_task_candle: float_m.tasks,
    })
}
