//! Input equalisation before `w8a8` quantization (feature `alloc`).
//!
//! A `w8a8` layer quantizes its whole input vector with one scale, set by its widest input.
//! The first layers read normalised observations next to `z` (policy) or the action (encoder),
//! and z-scored velocities can span four times the range of everything else: their range then
//! sets a step so coarse that positions lose the precision a goal-reaching policy needs. This
//! rescales each observation dimension whose calibrated range exceeds the other inputs' range
//! down to it (through the blob's `obs_std`) and multiplies the matching weight columns of both
//! first layers by the same factor, so the float function is unchanged and every input gets
//! about the same resolution.

extern crate alloc;

use alloc::vec;
use alloc::vec::Vec;

use crate::format::ModelKind;
use crate::writer::{Calibration, FloatModel};

/// Largest absolute value per component of `x` folded into `max`.
fn fold_max(max: &mut [f32], x: &[f32]) {
    max.iter_mut().zip(x).for_each(|(m, v)| *m = m.max(v.abs()));
}

/// A float-equivalent copy of `model` with every normalised observation dimension confined to
/// the range of the first layers' other inputs (z and the action) on `calib`.
pub(crate) fn equalised(model: &FloatModel, calib: &Calibration) -> FloatModel {
    let (o, a) = (model.obs_dim, model.act_dim);
    let mut obs_max = vec![0.0f32; o];
    let mut other = 0.0f32;
    for obs in &calib.observations {
        fold_max(&mut obs_max, &model.normalise(obs));
    }
    for context in &calib.contexts {
        for t in context.iter().flatten() {
            fold_max(&mut obs_max, &model.normalise(&t[..o]));
            let next_at = match model.kind {
                ModelKind::StateAction => {
                    other = t[o..o + a].iter().fold(other, |m, v| m.max(v.abs()));
                    o + a
                }
                ModelKind::StateOnly => o,
            };
            fold_max(&mut obs_max, &model.normalise(&t[next_at..next_at + o]));
        }
        other = model
            .latent(context)
            .iter()
            .fold(other, |m, v| m.max(v.abs()));
    }
    if !(other.is_finite() && other > 0.0) {
        return model.clone();
    }
    // Only ever compress (factor >= 1): a dimension narrower than the rest keeps its scale, so
    // a nearly constant input is never blown up.
    let factor: Vec<f32> = obs_max
        .iter()
        .map(|&m| {
            if m.is_finite() && m > other {
                m / other
            } else {
                1.0
            }
        })
        .collect();
    let mut eq = model.clone();
    eq.obs_std
        .iter_mut()
        .zip(&factor)
        .for_each(|(s, f)| *s *= f);
    let scale_columns = |layer: &mut crate::writer::FloatLayer, at: usize| {
        for row in layer.weights.chunks_exact_mut(layer.in_dim) {
            row[at..at + o]
                .iter_mut()
                .zip(&factor)
                .for_each(|(w, f)| *w *= f);
        }
    };
    if let Some(first) = eq.policy.first_mut() {
        scale_columns(first, 0);
    }
    if let Some(first) = eq.encoder.first_mut() {
        scale_columns(first, 0);
        let next_at = match model.kind {
            ModelKind::StateAction => o + a,
            ModelKind::StateOnly => o,
        };
        scale_columns(first, next_at);
    }
    eq
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::writer::Dims;

    fn calib(model: &FloatModel) -> Calibration {
        // Observation dimension 1 spans 6x the range of the others, as z-scored velocities do.
        let obs = |i: usize| -> Vec<f32> {
            (0..model.obs_dim)
                .map(|d| {
                    let v = ((i * 7 + d * 3) % 11) as f32 / 5.0 - 1.0;
                    if d == 1 { 6.0 * v } else { v }
                })
                .collect()
        };
        let t_dim = match model.kind {
            ModelKind::StateAction => 2 * model.obs_dim + model.act_dim,
            ModelKind::StateOnly => 2 * model.obs_dim,
        };
        let transition = |i: usize| -> Vec<f32> {
            let mut t = obs(i);
            t.resize(t_dim - model.obs_dim, 0.5);
            t.extend(obs(i + 1));
            t
        };
        Calibration {
            contexts: (0..4)
                .map(|c| vec![(0..6).map(|s| transition(c * 6 + s)).collect()])
                .collect(),
            observations: (0..32).map(obs).collect(),
        }
    }

    #[test]
    fn equalised_model_computes_the_same_function_with_confined_inputs() {
        for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
            let model = FloatModel::random(kind, Dims::default_with_hidden(16), 5);
            let calib = calib(&model);
            let eq = equalised(&model, &calib);
            let f: Vec<f32> = eq
                .obs_std
                .iter()
                .zip(&model.obs_std)
                .map(|(a, b)| a / b)
                .collect();
            assert!(
                f[1] > 1.0 && f[1] > f[0],
                "the wide dimension was not compressed: {f:?}"
            );
            for (i, context) in calib.contexts.iter().enumerate() {
                let (z, z_eq) = (model.latent(context), eq.latent(context));
                for (a, b) in z.iter().zip(&z_eq) {
                    assert!((a - b).abs() <= 1e-4 * (1.0 + a.abs()), "{a} vs {b}");
                }
                let obs = &calib.observations[i];
                for (a, b) in model.act(obs, &z).iter().zip(&eq.act(obs, &z)) {
                    assert!((a - b).abs() <= 1e-4, "{a} vs {b}");
                }
            }
            // The widest normalised observation now spans no more than z and the action do.
            let other = calib
                .contexts
                .iter()
                .flat_map(|c| eq.latent(c))
                .fold(0.5f32, |m, v| m.max(v.abs()));
            for obs in &calib.observations {
                assert!(eq.normalise(obs).iter().all(|v| v.abs() <= other * 1.0001));
            }
        }
    }
}
