//! Loading and validating a blob: after [`Model::from_bytes`] succeeds, every length, dimension
//! and scale has been checked, so the kernels index without further checks failing.

use crate::error::{Error, Result};
use crate::format::{
    self, Activation, ENVELOPE_LEN, FORMAT_VERSION, Header, LayerRecord, Layers, MAGIC, MAX_LAYERS,
    Payload, Quant,
};

/// A read-only view of `f32` little-endian values stored in the blob.
#[derive(Debug, Clone, Copy)]
pub(crate) struct F32s<'a>(pub &'a [u8]);

impl<'a> F32s<'a> {
    #[inline]
    pub fn get(&self, i: usize) -> f32 {
        let b = &self.0[4 * i..4 * i + 4];
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    #[inline]
    pub fn len(&self) -> usize {
        self.0.len() / 4
    }
    pub fn iter(&self) -> impl Iterator<Item = f32> + 'a {
        self.0
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// One of a blob's three MLPs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mlp {
    /// The per-transition context encoder (runs while the device is taught).
    Encoder,
    /// The head from the summed representation to the latent (once per teaching).
    ZHead,
    /// The conditioned policy (every control tick).
    Policy,
}

/// A validated policy blob, borrowing its weights from the bytes it was loaded from.
///
/// Loading copies no weights: on a microcontroller the bytes can live in flash. The model
/// itself is stateless; run it with a [`Policy`](crate::Policy) and a
/// [`ContextEncoder`](crate::ContextEncoder), which own the (small, fixed) scratch memory.
#[derive(Debug, Clone)]
pub struct Model<'a> {
    pub(crate) payload: Payload<'a>,
}

impl<'a> Model<'a> {
    /// Parses and validates a blob. Any byte string gives either a valid model or an error;
    /// nothing here panics.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self> {
        if bytes.len() < ENVELOPE_LEN {
            return Err(Error::TooShort { len: bytes.len() });
        }
        if bytes[0..4] != MAGIC {
            return Err(Error::BadMagic);
        }
        let version = u16::from_le_bytes([bytes[4], bytes[5]]);
        if (1..FORMAT_VERSION).contains(&version) {
            return Err(Error::OutdatedVersion { found: version });
        }
        if version != FORMAT_VERSION {
            return Err(Error::UnsupportedVersion { found: version });
        }
        let declared = u32::from_le_bytes([bytes[6], bytes[7], bytes[8], bytes[9]]) as usize;
        let payload = &bytes[ENVELOPE_LEN..];
        if declared != payload.len() {
            return Err(Error::LengthMismatch {
                declared,
                actual: payload.len(),
            });
        }
        let declared_crc = u32::from_le_bytes([bytes[10], bytes[11], bytes[12], bytes[13]]);
        let computed = format::crc32(payload);
        if declared_crc != computed {
            return Err(Error::ChecksumMismatch {
                declared: declared_crc,
                computed,
            });
        }
        let (payload, rest): (Payload<'a>, _) =
            postcard::take_from_bytes(payload).map_err(|_| Error::Decode)?;
        if !rest.is_empty() {
            return Err(Error::TrailingBytes);
        }
        validate(&payload)?;
        Ok(Model { payload })
    }

    /// The model's fixed facts: kind, quantization and dimensions.
    pub fn header(&self) -> &Header {
        &self.payload.header
    }

    /// The widest vector any layer reads or writes: the smallest runner capacity `W` that
    /// can run this model.
    pub fn max_width(&self) -> usize {
        let p = &self.payload;
        [&p.encoder, &p.z_head, &p.policy]
            .into_iter()
            .flat_map(|layers| layers.iter())
            .map(|l| (l.in_dim as usize).max(l.out_dim as usize))
            .max()
            .unwrap_or(0)
    }

    /// The quantization of each layer of one of the three MLPs, from its first layer to its
    /// last. None is coarser than [`Header::quant`].
    pub fn layer_quants(&self, mlp: Mlp) -> impl Iterator<Item = Quant> + '_ {
        let p = &self.payload;
        let layers = match mlp {
            Mlp::Encoder => &p.encoder,
            Mlp::ZHead => &p.z_head,
            Mlp::Policy => &p.policy,
        };
        layers.iter().map(|l| l.quant)
    }

    /// Number of weights in the three MLPs together.
    pub fn parameter_count(&self) -> usize {
        let p = &self.payload;
        [&p.encoder, &p.z_head, &p.policy]
            .into_iter()
            .flat_map(|layers| layers.iter())
            .map(|l| (l.in_dim as usize + 1) * l.out_dim as usize)
            .sum()
    }

    pub(crate) fn obs_mean(&self) -> F32s<'a> {
        F32s(self.payload.obs_mean.0)
    }
    pub(crate) fn obs_std(&self) -> F32s<'a> {
        F32s(self.payload.obs_std.0)
    }
    pub(crate) fn act_scale(&self) -> F32s<'a> {
        F32s(self.payload.act_scale.0)
    }
    pub(crate) fn act_offset(&self) -> F32s<'a> {
        F32s(self.payload.act_offset.0)
    }
}

fn validate(p: &Payload<'_>) -> Result<()> {
    let h = &p.header;
    for (part, dim) in [
        ("obs_dim", h.obs_dim),
        ("act_dim", h.act_dim),
        ("r_dim", h.r_dim),
        ("z_dim", h.z_dim),
    ] {
        if dim == 0 {
            return Err(Error::DimMismatch {
                part,
                expected: 1,
                found: 0,
            });
        }
    }
    let obs = h.obs_dim as usize;
    let act = h.act_dim as usize;
    check_vector("obs_mean", p.obs_mean.0, obs, false)?;
    check_vector("obs_std", p.obs_std.0, obs, true)?;
    check_vector("act_scale", p.act_scale.0, act, false)?;
    check_vector("act_offset", p.act_offset.0, act, false)?;
    check_mlp(
        "encoder",
        &p.encoder,
        h.quant,
        h.transition_dim(),
        h.r_dim as usize,
    )?;
    check_mlp(
        "z_head",
        &p.z_head,
        h.quant,
        h.r_dim as usize,
        h.z_dim as usize,
    )?;
    check_mlp("policy", &p.policy, h.quant, obs + h.z_dim as usize, act)?;
    Ok(())
}

fn check_vector(part: &'static str, bytes: &[u8], len: usize, positive: bool) -> Result<()> {
    if bytes.len() != 4 * len {
        return Err(Error::TensorLength {
            part,
            expected: 4 * len,
            found: bytes.len(),
        });
    }
    for v in F32s(bytes).iter() {
        if !v.is_finite() {
            return Err(Error::NonFinite { part });
        }
        if positive && v <= 0.0 {
            return Err(Error::NonPositiveScale { part });
        }
    }
    Ok(())
}

fn check_mlp(
    part: &'static str,
    layers: &Layers<'_>,
    quant: Quant,
    input: usize,
    output: usize,
) -> Result<()> {
    if layers.stored() > MAX_LAYERS {
        return Err(Error::TooManyLayers {
            part,
            found: layers.stored(),
        });
    }
    let Some(last) = layers.last() else {
        return Err(Error::EmptyMlp { part });
    };
    let mut width = input;
    for layer in layers.iter() {
        if layer.in_dim as usize != width {
            return Err(Error::DimMismatch {
                part,
                expected: width,
                found: layer.in_dim as usize,
            });
        }
        if layer.out_dim == 0 {
            return Err(Error::DimMismatch {
                part,
                expected: 1,
                found: 0,
            });
        }
        check_layer(part, layer, quant)?;
        width = layer.out_dim as usize;
    }
    if last.out_dim as usize != output {
        return Err(Error::DimMismatch {
            part,
            expected: output,
            found: last.out_dim as usize,
        });
    }
    // A tanh or ReLU after the last layer would be harmless for the encoder but makes the
    // policy's tanh-mean wrong; only the policy's last activation is fixed.
    if part == "policy" && last.activation != Activation::Identity {
        return Err(Error::PolicyOutputActivation);
    }
    Ok(())
}

fn check_layer(part: &'static str, l: &LayerRecord<'_>, header: Quant) -> Result<()> {
    let quant = l.quant;
    if !quant.at_least(header) {
        return Err(Error::LayerBelowHeader {
            part,
            layer: quant,
            header,
        });
    }
    let (i, o) = (l.in_dim as usize, l.out_dim as usize);
    let expected = i * o * quant.weight_bytes();
    if l.weights.0.len() != expected {
        return Err(Error::TensorLength {
            part,
            expected,
            found: l.weights.0.len(),
        });
    }
    if quant == Quant::F32 {
        check_vector(part, l.weights.0, i * o, false)?;
    }
    check_vector(part, l.bias.0, o, false)?;
    match quant {
        Quant::F32 => {
            if !l.weight_scale.0.is_empty() {
                return Err(Error::TensorLength {
                    part,
                    expected: 0,
                    found: l.weight_scale.0.len(),
                });
            }
        }
        Quant::W8A32 | Quant::W8A8 => check_vector(part, l.weight_scale.0, o, true)?,
    }
    if quant == Quant::W8A8 {
        // One scale per input channel, or a single one for all of them.
        let n = if l.input_scale.0.len() == 4 { 1 } else { i };
        check_vector(part, l.input_scale.0, n, true)?;
    } else if !l.input_scale.0.is_empty() || l.unsigned_input {
        // Canonical form: one encoding per model, so equal models have equal bytes.
        return Err(Error::TensorLength {
            part,
            expected: 0,
            found: l.input_scale.0.len(),
        });
    }
    Ok(())
}

#[cfg(all(test, feature = "alloc"))]
mod tests;
