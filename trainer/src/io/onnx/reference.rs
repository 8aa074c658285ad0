//! The trainer's z and actions on held-out contexts, padded and masked as a runtime gets
//! them: what a runtime's outputs are held against.

use std::collections::HashMap;

use sim::{DemoDataset, Trajectory};

use crate::error::{Error, Result};
use crate::io::export::{check_demos_fit, raw_transitions};
use crate::model::ConditionedActor;
use crate::model::MetaPolicy;

/// One context of a [`Reference`], as a runtime is fed it, with the trainer's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceContext {
    /// Index of the task in the demo file.
    pub task: usize,
    /// `[trajectories, steps, transition]` of `context`.
    pub shape: [usize; 3],
    /// Raw transitions, row-major, padded (padding is finite junk, masked out).
    pub context: Vec<f32>,
    /// `[trajectories, steps]`: 1 for a real step.
    pub mask: Vec<f32>,
    /// The trainer's z (posterior mean) for the unmasked transitions.
    pub z: Vec<f32>,
    /// Raw observations `[n, obs_dim]`: the states of all the task's trajectories.
    pub observations: Vec<f32>,
    /// The trainer's deterministic actions `[n, act_dim]` for them with `z`.
    pub actions: Vec<f32>,
}

/// Contexts with the trainer's z and actions, to hold a runtime's outputs against.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Observation width.
    pub obs_dim: usize,
    /// Action width.
    pub act_dim: usize,
    /// Latent width.
    pub z_dim: usize,
    /// The plant the policy and the contexts' states come from.
    pub physics: sim::Physics,
    /// The contexts.
    pub contexts: Vec<ReferenceContext>,
}

/// The value a padded cell holds: finite, and far from any demo value, so that a graph which
/// let padding through would be caught.
const PAD: f32 = 3.25;

/// The trainer's z and actions on every task of `demos` (held-out contexts), two contexts a
/// task: its first trajectory alone, and all its trajectories padded to a common length
/// plus two junk steps and one junk trajectory, all masked out. Observations: the states of
/// all the task's trajectories. Reference values come from [`ConditionedActor`] on `mp`, the
/// path evaluation and the blob parity use.
pub fn reference(mp: &MetaPolicy, demos: &DemoDataset) -> Result<Reference> {
    check_demos_fit(mp, demos, "the contexts")?;
    let (od, ad, zd) = (demos.obs_dim, demos.act_dim, mp.z_dim());
    let so = mp.encoder.config().state_only;
    let td = if so { 2 * od } else { 2 * od + ad };
    let mut mp = mp.clone();
    let mut contexts = Vec::new();
    for (task, t) in demos.tasks.iter().enumerate() {
        let trajs: Vec<&Trajectory> = t.trajectories.iter().filter(|t| !t.is_empty()).collect();
        if trajs.is_empty() {
            continue;
        }
        let observations: Vec<f32> = trajs.iter().flat_map(|t| t.obs.iter().copied()).collect();
        for (ctx, pad_steps, pad_trajs) in [(&trajs[..1], 0, 0), (&trajs[..], 2, 1)] {
            let z = ConditionedActor::latent(&mut mp, ctx)?;
            let steps = ctx.iter().map(|t| t.len()).max().unwrap_or(0) + pad_steps;
            let n = ctx.len() + pad_trajs;
            let mut context = vec![PAD; n * steps * td];
            let mut mask = vec![0.0f32; n * steps];
            for (j, traj) in ctx.iter().enumerate() {
                for (i, row) in raw_transitions(traj, od, ad, so).iter().enumerate() {
                    let at = (j * steps + i) * td;
                    context[at..at + td].copy_from_slice(row);
                    mask[j * steps + i] = 1.0;
                }
            }
            let mut actions = vec![0.0f32; observations.len() / od * ad];
            for (o, a) in observations
                .chunks_exact(od)
                .zip(actions.chunks_exact_mut(ad))
            {
                ConditionedActor::act(&mut mp, o, &z, a)?;
            }
            contexts.push(ReferenceContext {
                task,
                shape: [n, steps, td],
                context,
                mask,
                z,
                observations: observations.clone(),
                actions,
            });
        }
    }
    if contexts.is_empty() {
        return Err(Error::Data("the contexts hold no transitions".into()));
    }
    Ok(Reference {
        obs_dim: od,
        act_dim: ad,
        z_dim: zd,
        physics: mp.physics,
        contexts,
    })
}

impl Reference {
    /// Observations over all contexts.
    pub fn observation_count(&self) -> usize {
        self.contexts
            .iter()
            .map(|c| c.observations.len() / self.obs_dim.max(1))
            .sum()
    }

    /// As safetensors: per context `i`, `{i}.context`, `{i}.mask`, `{i}.z` (`[1, z_dim]`),
    /// `{i}.observation`, `{i}.action`; the header metadata maps `{i}.task` to the task index.
    pub fn to_safetensors(&self) -> Result<Vec<u8>> {
        use safetensors::tensor::{Dtype, TensorView};
        let bytes = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
        let mut owned: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
        let mut meta = HashMap::new();
        for (i, c) in self.contexts.iter().enumerate() {
            let [n, s, td] = c.shape;
            let rows = c.observations.len() / self.obs_dim.max(1);
            owned.push((format!("{i}.context"), vec![n, s, td], bytes(&c.context)));
            owned.push((format!("{i}.mask"), vec![n, s], bytes(&c.mask)));
            owned.push((format!("{i}.z"), vec![1, self.z_dim], bytes(&c.z)));
            owned.push((
                format!("{i}.observation"),
                vec![rows, self.obs_dim],
                bytes(&c.observations),
            ));
            owned.push((
                format!("{i}.action"),
                vec![rows, self.act_dim],
                bytes(&c.actions),
            ));
            meta.insert(format!("{i}.task"), c.task.to_string());
        }
        meta.insert("contexts".into(), self.contexts.len().to_string());
        meta.insert("physics".into(), self.physics.name().to_string());
        let views = owned
            .iter()
            .map(|(name, shape, data)| {
                TensorView::new(Dtype::F32, shape.clone(), data)
                    .map(|v| (name.clone(), v))
                    .map_err(|e| Error::Data(format!("reference tensor {name}: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        safetensors::tensor::serialize(views, Some(meta))
            .map(sim::canonical_safetensors)
            .map_err(|e| Error::Serialise {
                what: "the ONNX reference tensors",
                reason: e.to_string(),
            })
    }
}
