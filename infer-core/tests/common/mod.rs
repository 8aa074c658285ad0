//! Shared helpers for infer-core's integration tests: seeded random inputs.
#![allow(dead_code)]

use infer_core::{Calibration, ContextEncoder, Dims, FloatModel, Model, ModelKind, Policy};

/// SplitMix64 uniform in [-1, 1).
pub struct Rng(pub u64);

impl Rng {
    pub fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    }
    pub fn vec(&mut self, n: usize, scale: f32) -> Vec<f32> {
        (0..n).map(|_| self.uniform() * scale).collect()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (((self.uniform() + 1.0) * 0.5) * n as f32) as usize % n
    }
}

pub fn transition_dim(m: &FloatModel) -> usize {
    match m.kind {
        ModelKind::StateAction => 2 * m.obs_dim + m.act_dim,
        ModelKind::StateOnly => 2 * m.obs_dim,
    }
}

/// A context of `trajectories` trajectories of 5..=20 raw transitions each.
pub fn context(rng: &mut Rng, m: &FloatModel, trajectories: usize) -> Vec<Vec<Vec<f32>>> {
    (0..trajectories)
        .map(|_| {
            let steps = 5 + rng.below(16);
            (0..steps)
                .map(|_| rng.vec(transition_dim(m), 1.5))
                .collect()
        })
        .collect()
}

pub fn calibration(rng: &mut Rng, m: &FloatModel) -> Calibration {
    Calibration {
        contexts: (0..16).map(|i| context(rng, m, 1 + i % 4)).collect(),
        observations: (0..64).map(|_| rng.vec(m.obs_dim, 1.5)).collect(),
    }
}

pub fn model(kind: ModelKind, hidden: usize, seed: u64) -> FloatModel {
    FloatModel::random(kind, Dims::default_with_hidden(hidden), seed)
}

/// Streams `context` through a blob's encoder and returns z.
pub fn blob_latent(model: &Model<'_>, context: &[Vec<Vec<f32>>]) -> Vec<f32> {
    let h = *model.header();
    let (o, a) = (h.obs_dim as usize, h.act_dim as usize);
    let mut enc = ContextEncoder::<128>::new(model).unwrap();
    for trajectory in context {
        for t in trajectory {
            match h.kind {
                ModelKind::StateAction => enc.push(&t[..o], &t[o..o + a], &t[o + a..]).unwrap(),
                ModelKind::StateOnly => enc.push(&t[..o], &[], &t[o..]).unwrap(),
            }
        }
        enc.end_trajectory();
    }
    let mut z = vec![0.0; h.z_dim as usize];
    enc.latent(&mut z).unwrap();
    z
}

pub fn blob_act(model: &Model<'_>, obs: &[f32], z: &[f32]) -> Vec<f32> {
    let mut policy = Policy::<128>::new(model).unwrap();
    let mut action = vec![0.0; model.header().act_dim as usize];
    policy.act(obs, z, &mut action).unwrap();
    action
}
