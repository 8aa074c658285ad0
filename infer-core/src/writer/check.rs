//! What the writer refuses, and the checks that refuse it before anything is indexed: the
//! model's structure (every MLP chains from its input to its output width) and the `w8a8`
//! calibration rows (the model's dimensions, finite). Bad input is an error, never a panic.

use core::fmt;

use super::{Calibration, FloatLayer, FloatModel};
use crate::format::MAX_LAYERS;

/// Why a float model could not be written as a blob.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum WriteError {
    /// A dimension or tensor length is inconsistent.
    Shape(&'static str),
    /// More layers in one MLP than the format allows.
    TooManyLayers {
        /// Which MLP.
        part: &'static str,
    },
    /// A weight or statistic is NaN or infinite.
    NonFinite(&'static str),
    /// `w8a8` needs calibration contexts and observations.
    MissingCalibration,
    /// A dimension does not fit the format's `u16`.
    TooLarge,
    /// An MLP has no layers.
    EmptyMlp {
        /// Which MLP.
        part: &'static str,
    },
    /// A layer's input width is not the width that reaches it (the MLP's input or the
    /// previous layer's output), or an MLP's output is not the model's dimension.
    LayerWidth {
        /// Which MLP.
        part: &'static str,
        /// Index of the layer.
        layer: usize,
        /// `"input"` or `"output"`.
        side: &'static str,
        /// Width the model structure requires.
        expected: usize,
        /// Width the layer has.
        got: usize,
    },
    /// A `w8a8` calibration row does not have the model's dimension.
    CalibrationLength {
        /// `"observation"` or `"context transition"`.
        what: &'static str,
        /// Index of the observation, or of the context holding the transition.
        index: usize,
        /// Length the model needs.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A weight or bias too large for the blob's arithmetic (its scales and sums would
    /// overflow f32): a diverged or corrupted network, not a trained one.
    OutOfRange {
        /// Which MLP.
        part: &'static str,
        /// Index of the layer.
        layer: usize,
        /// The largest magnitude found.
        value: f32,
    },
    /// The finished blob did not load back (a bug in the writer; please report).
    SelfCheck(crate::BlobError),
}

/// Largest weight or bias magnitude a blob takes: trained networks stay orders of magnitude
/// below it, and beyond it a quantization scale or an accumulated sum can overflow f32.
const MAX_PARAMETER: f32 = 1.0e6;

impl fmt::Display for WriteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Shape(what) => write!(f, "inconsistent shape: {what}"),
            Self::TooManyLayers { part } => write!(f, "{part}: more than {MAX_LAYERS} layers"),
            Self::NonFinite(what) => write!(f, "{what}: NaN or infinite value"),
            Self::MissingCalibration => {
                f.write_str("w8a8 needs calibration contexts and observations")
            }
            Self::TooLarge => f.write_str("a dimension exceeds 65535"),
            Self::EmptyMlp { part } => write!(f, "{part}: MLP has no layers"),
            Self::LayerWidth {
                part,
                layer,
                side,
                expected,
                got,
            } => write!(
                f,
                "{part} layer {layer}: {side} width {got}, the model needs {expected}"
            ),
            Self::CalibrationLength {
                what,
                index,
                expected,
                got,
            } => {
                let at = if *what == "observation" {
                    ""
                } else {
                    "in context "
                };
                write!(
                    f,
                    "calibration {what} {at}{index}: length {got}, the model needs {expected}"
                )
            }
            Self::OutOfRange { part, layer, value } => write!(
                f,
                "{part} layer {layer}: a parameter of magnitude {value:e} exceeds the blob's \
                 {MAX_PARAMETER:e} (a diverged or corrupted network: retrain or take an earlier \
                 checkpoint)"
            ),
            Self::SelfCheck(e) => write!(f, "written blob failed to load back: {e}"),
        }
    }
}

impl core::error::Error for WriteError {}

impl Calibration {
    /// Checks that there is calibration data and every row has `model`'s dimension and only
    /// finite values, so nothing downstream indexes past a row.
    pub(super) fn check(&self, model: &FloatModel) -> Result<(), WriteError> {
        if self.contexts.is_empty() || self.observations.is_empty() {
            return Err(WriteError::MissingCalibration);
        }
        let row = |what, index, values: &[f32], expected, non_finite| {
            if values.len() != expected {
                return Err(WriteError::CalibrationLength {
                    what,
                    index,
                    expected,
                    got: values.len(),
                });
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(WriteError::NonFinite(non_finite));
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
    pub(super) fn check(&self) -> Result<(), WriteError> {
        let vectors = [
            ("obs_mean", &self.obs_mean, self.obs_dim),
            ("obs_std", &self.obs_std, self.obs_dim),
            ("act_scale", &self.act_scale, self.act_dim),
            ("act_offset", &self.act_offset, self.act_dim),
        ];
        for (name, v, n) in vectors {
            if v.len() != n {
                return Err(WriteError::Shape(name));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(WriteError::NonFinite(name));
            }
        }
        if self.obs_std.iter().any(|s| *s <= 0.0) {
            return Err(WriteError::Shape("obs_std must be > 0"));
        }
        if [self.obs_dim, self.act_dim, self.r_dim, self.z_dim].contains(&0) {
            return Err(WriteError::Shape(
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
                return Err(WriteError::TooManyLayers { part: name });
            }
            check_widths(name, layers, input, output)?;
            for (index, l) in layers.iter().enumerate() {
                if l.in_dim.checked_mul(l.out_dim) != Some(l.weights.len())
                    || l.bias.len() != l.out_dim
                {
                    return Err(WriteError::Shape(name));
                }
                if l.weights.iter().chain(&l.bias).any(|x| !x.is_finite()) {
                    return Err(WriteError::NonFinite(name));
                }
                let largest = l
                    .weights
                    .iter()
                    .chain(&l.bias)
                    .fold(0.0f32, |m, x| m.max(x.abs()));
                if largest > MAX_PARAMETER {
                    return Err(WriteError::OutOfRange {
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
) -> Result<(), WriteError> {
    let Some(last) = layers.len().checked_sub(1) else {
        return Err(WriteError::EmptyMlp { part });
    };
    let mut width = input;
    for (layer, l) in layers.iter().enumerate() {
        let side = "input";
        if l.in_dim != width {
            let (expected, got) = (width, l.in_dim);
            return Err(WriteError::LayerWidth {
                part,
                layer,
                side,
                expected,
                got,
            });
        }
        // A hidden layer may have any width but zero; the last one gives the MLP's output.
        let expected = if layer == last {
            output
        } else {
            l.out_dim.max(1)
        };
        if l.out_dim != expected {
            let (side, got) = ("output", l.out_dim);
            return Err(WriteError::LayerWidth {
                part,
                layer,
                side,
                expected,
                got,
            });
        }
        width = l.out_dim;
    }
    Ok(())
}
