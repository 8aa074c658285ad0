//! What the writer refuses, and the checks that refuse it before anything is indexed: the
//! model's structure (every MLP chains from its input to its output width) and the `w8a8`
//! calibration rows (the model's dimensions, finite). Bad input is an error, never a panic.

use super::{Calibration, FloatLayer, FloatModel};
use crate::error::{Error, MAX_PARAMETER, Result};
use crate::format::MAX_LAYERS;

impl Calibration {
    /// Checks that there is calibration data and every row has `model`'s dimension and only
    /// finite values, so nothing downstream indexes past a row.
    pub(super) fn check(&self, model: &FloatModel) -> Result<()> {
        if self.contexts.is_empty() || self.observations.is_empty() {
            return Err(Error::MissingCalibration);
        }
        let row = |what, index, values: &[f32], expected, non_finite| {
            if values.len() != expected {
                return Err(Error::CalibrationLength {
                    what,
                    index,
                    expected,
                    got: values.len(),
                });
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite { part: non_finite });
            }
            Ok(())
        };
        for (index, obs) in self.observations.iter().enumerate() {
            let expected = model.obs_dim;
            row(
                "observation",
                index,
                obs,
                expected,
                "calibration observations",
            )?;
        }
        for (index, context) in self.contexts.iter().enumerate() {
            for t in context.iter().flatten() {
                let expected = model.transition_dim();
                row(
                    "context transition",
                    index,
                    t,
                    expected,
                    "calibration contexts",
                )?;
            }
        }
        Ok(())
    }
}

impl FloatModel {
    pub(super) fn check(&self) -> Result<()> {
        let vectors = [
            ("obs_mean", &self.obs_mean, self.obs_dim),
            ("obs_std", &self.obs_std, self.obs_dim),
            ("act_scale", &self.act_scale, self.act_dim),
            ("act_offset", &self.act_offset, self.act_dim),
        ];
        for (name, v, n) in vectors {
            if v.len() != n {
                return Err(Error::Shape(name));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(Error::NonFinite { part: name });
            }
        }
        if self.obs_std.iter().any(|s| *s <= 0.0) {
            return Err(Error::Shape("obs_std must be > 0"));
        }
        if [self.obs_dim, self.act_dim, self.r_dim, self.z_dim].contains(&0) {
            return Err(Error::Shape(
                "obs, act, r and z dimensions must be positive",
            ));
        }
        let mlps = [
            ("encoder", &self.encoder, self.transition_dim(), self.r_dim),
            ("z_head", &self.z_head, self.r_dim, self.z_dim),
            (
                "policy",
                &self.policy,
                self.obs_dim.saturating_add(self.z_dim),
                self.act_dim,
            ),
        ];
        for (name, layers, input, output) in mlps {
            if layers.len() > MAX_LAYERS {
                return Err(Error::TooManyLayers {
                    part: name,
                    found: layers.len(),
                });
            }
            check_widths(name, layers, input, output)?;
            for (index, l) in layers.iter().enumerate() {
                if l.in_dim.checked_mul(l.out_dim) != Some(l.weights.len())
                    || l.bias.len() != l.out_dim
                {
                    return Err(Error::Shape(name));
                }
                if l.weights.iter().chain(&l.bias).any(|x| !x.is_finite()) {
                    return Err(Error::NonFinite { part: name });
                }
                let largest = l
                    .weights
                    .iter()
                    .chain(&l.bias)
                    .fold(0.0f32, |m, x| m.max(x.abs()));
                if largest > MAX_PARAMETER {
                    return Err(Error::OutOfRange {
                        part: name,
                        layer: index,
                        value: largest,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Checks that `layers` chain from `input` to `output`, each layer at least one wide.
fn check_widths(
    part: &'static str,
    layers: &[FloatLayer],
    input: usize,
    output: usize,
) -> Result<()> {
    let Some(last) = layers.len().checked_sub(1) else {
        return Err(Error::EmptyMlp { part });
    };
    let mut width = input;
    for (layer, l) in layers.iter().enumerate() {
        // A hidden layer may have any width but zero; the last one gives the MLP's output.
        let out = if layer == last {
            output
        } else {
            l.out_dim.max(1)
        };
        for (side, expected, got) in [("input", width, l.in_dim), ("output", out, l.out_dim)] {
            if expected != got {
                return Err(Error::LayerWidth {
                    part,
                    layer,
                    side,
                    expected,
                    got,
                });
            }
        }
        width = l.out_dim;
    }
    Ok(())
}
