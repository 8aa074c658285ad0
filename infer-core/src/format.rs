//! Blob format v3: the one definition of the bytes a trained policy travels in.
//!
//! ```text
//! offset  size  field
//! 0       4     magic  b"SMLB"
//! 4       2     format version, u16 little-endian (= 3)
//! 6       4     payload length in bytes, u32 little-endian
//! 10      4     CRC-32 (IEEE) of the payload, u32 little-endian
//! 14      n     payload: postcard encoding of `Payload`
//! ```
//!
//! Every tensor in the payload is a postcard byte string (varint length + raw bytes), so a
//! loaded [`Model`](crate::Model) borrows its weights from the blob in place: `f32` values are
//! little-endian and read with `f32::from_le_bytes` (no alignment needed), `i8` weights are
//! the bytes themselves. Weight matrices are row-major `[out][in]`.
//!
//! Version 2: a `w8a8` layer quantizes each input channel with its own scale (folded into the
//! stored weights, so the integer dot product is unchanged), and a layer whose input follows a
//! ReLU quantizes it as unsigned 8-bit (0..=255), twice the resolution of a signed byte for a
//! non-negative value.
//!
//! Version 3 (v1 and v2 blobs are refused with
//! [`Error::OutdatedVersion`](crate::Error::OutdatedVersion)): every layer record names its own
//! [`Quant`], so a `w8a8` blob may keep chosen layers (the first and last of each MLP, where
//! int8 activations cost the most) at a higher precision. The header's `quant` is the blob's
//! lowest precision, and no layer is stored coarser than it.

use serde::{Deserialize, Serialize};

/// The four bytes every blob starts with.
pub const MAGIC: [u8; 4] = *b"SMLB";
/// The blob format version this crate reads and writes.
pub const FORMAT_VERSION: u16 = 3;
/// Bytes before the payload: magic, version, length, checksum.
pub const ENVELOPE_LEN: usize = 14;
/// Most layers one MLP of a blob may have.
pub const MAX_LAYERS: usize = 4;

/// What the context encoder reads per transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ModelKind {
    /// Transitions are `(s, a, s')`: the encoder input is `[norm(s), a, norm(s')]`.
    StateAction,
    /// Transitions are `(s, s')`: the encoder input is `[norm(s), norm(s')]`.
    StateOnly,
}

/// How weights and activations are stored and computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Quant {
    /// `f32` weights and activations: the reference.
    F32,
    /// `i8` weights, symmetric per output channel with an `f32` scale; `f32` activations.
    W8A32,
    /// `i8` weights and 8-bit activations, `i32` accumulation; one calibrated `f32` scale
    /// per input channel, unsigned activations after a ReLU.
    W8A8,
}

impl Quant {
    /// Rank by precision: `F32` 2, `W8A32` 1, `W8A8` 0.
    const fn rank(self) -> u8 {
        match self {
            Quant::F32 => 2,
            Quant::W8A32 => 1,
            Quant::W8A8 => 0,
        }
    }

    /// Whether a layer stored as `self` is at least as precise as `other`.
    pub const fn at_least(self, other: Quant) -> bool {
        self.rank() >= other.rank()
    }

    /// The finer of `self` and `other`.
    pub const fn max_precision(self, other: Quant) -> Quant {
        if self.at_least(other) { self } else { other }
    }

    /// Bytes per stored weight.
    pub const fn weight_bytes(self) -> usize {
        match self {
            Quant::F32 => 4,
            Quant::W8A32 | Quant::W8A8 => 1,
        }
    }
}

/// The non-linearity after a layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Activation {
    /// No non-linearity.
    Identity,
    /// `max(x, 0)`.
    Relu,
    /// `tanh(x)`.
    Tanh,
}

impl Activation {
    #[inline]
    pub(crate) fn apply(self, x: f32) -> f32 {
        match self {
            Activation::Identity => x,
            Activation::Relu => x.max(0.0),
            Activation::Tanh => libm::tanhf(x),
        }
    }
}

/// The fixed-size facts about a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// What the encoder reads per transition.
    pub kind: ModelKind,
    /// Weight and activation storage: the blob's lowest precision (each layer names its own,
    /// never coarser).
    pub quant: Quant,
    /// Observation dimension.
    pub obs_dim: u16,
    /// Action dimension.
    pub act_dim: u16,
    /// Per-transition representation dimension (encoder output).
    pub r_dim: u16,
    /// Latent task variable dimension.
    pub z_dim: u16,
}

impl Header {
    /// Width of one encoder input row: `2 obs + act` (state-action) or `2 obs` (state-only).
    pub const fn transition_dim(&self) -> usize {
        let base = 2 * self.obs_dim as usize;
        match self.kind {
            ModelKind::StateAction => base + self.act_dim as usize,
            ModelKind::StateOnly => base,
        }
    }
}

/// A byte string serialised as postcard bytes and borrowed back in place.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Bytes<'a>(pub &'a [u8]);

impl Serialize for Bytes<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(self.0)
    }
}

impl<'de: 'a, 'a> Deserialize<'de> for Bytes<'a> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Bytes<'de>;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("borrowed bytes")
            }
            fn visit_borrowed_bytes<E: serde::de::Error>(
                self,
                v: &'de [u8],
            ) -> Result<Self::Value, E> {
                Ok(Bytes(v))
            }
        }
        d.deserialize_bytes(Visitor)
    }
}

/// One dense layer as stored: `y = act(W x + b)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(crate) struct LayerRecord<'a> {
    pub in_dim: u16,
    pub out_dim: u16,
    pub activation: Activation,
    /// How this layer's weights and input are stored and computed.
    pub quant: Quant,
    /// `[out][in]` weights: `f32` LE (F32) or `i8` (W8A32, W8A8).
    #[serde(borrow)]
    pub weights: Bytes<'a>,
    /// `[out]` biases, `f32` LE.
    #[serde(borrow)]
    pub bias: Bytes<'a>,
    /// `[out]` per-channel weight scales, `f32` LE; empty for F32. For W8A8 they include the
    /// input scales: `y_o = act(ws_o * sum_i w_oi q_i + b_o)`.
    #[serde(borrow)]
    pub weight_scale: Bytes<'a>,
    /// `[in]` input activation scales, `f32` LE (W8A8 only; empty otherwise): input `i` is
    /// quantized as `q_i = round(x_i / s_i)`; a single value is the scale of every input.
    #[serde(borrow)]
    pub input_scale: Bytes<'a>,
    /// W8A8: the input is non-negative (it follows a ReLU) and quantized to `0..=255` instead
    /// of `-127..=127`. Always false otherwise.
    pub unsigned_input: bool,
}

/// The layers of one MLP: at most [`MAX_LAYERS`] are kept. A stored list that is longer is
/// still read to its end (each extra record is decoded and dropped, without a heap), and
/// [`Layers::stored`] lets the validator refuse it by name
/// ([`Error::TooManyLayers`](crate::Error::TooManyLayers)) instead of as a decode error.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Layers<'a> {
    kept: heapless::Vec<LayerRecord<'a>, MAX_LAYERS>,
    /// Records in the blob's list (more than `kept.len()` when over the limit).
    stored: usize,
}

impl<'a> Layers<'a> {
    /// Appends a layer; gives it back when [`MAX_LAYERS`] are already kept.
    #[cfg(feature = "alloc")]
    pub fn push(&mut self, layer: LayerRecord<'a>) -> Result<(), LayerRecord<'a>> {
        self.kept.push(layer)?;
        self.stored += 1;
        Ok(())
    }

    /// Number of layers the blob stores, including any beyond [`MAX_LAYERS`].
    pub fn stored(&self) -> usize {
        self.stored
    }
}

impl<'a> core::ops::Deref for Layers<'a> {
    type Target = [LayerRecord<'a>];
    fn deref(&self) -> &Self::Target {
        &self.kept
    }
}

impl<'a> core::ops::DerefMut for Layers<'a> {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.kept
    }
}

impl Serialize for Layers<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // The same bytes as the plain list: a length, then the records.
        self.kept.serialize(s)
    }
}

impl<'de: 'a, 'a> Deserialize<'de> for Layers<'a> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Layers<'de>;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("a list of layers")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                let mut layers = Layers::default();
                while let Some(layer) = seq.next_element::<LayerRecord<'de>>()? {
                    // Each record takes payload bytes, so the count stays below their number.
                    layers.stored = layers.stored.saturating_add(1);
                    // Beyond MAX_LAYERS the record is dropped; `stored` keeps the count.
                    let _ = layers.kept.push(layer);
                }
                Ok(layers)
            }
        }
        d.deserialize_seq(Visitor)
    }
}

/// Everything after the envelope.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Payload<'a> {
    pub header: Header,
    #[serde(borrow)]
    pub obs_mean: Bytes<'a>,
    #[serde(borrow)]
    pub obs_std: Bytes<'a>,
    #[serde(borrow)]
    pub act_scale: Bytes<'a>,
    #[serde(borrow)]
    pub act_offset: Bytes<'a>,
    /// Per-transition MLP: transition -> r.
    #[serde(borrow)]
    pub encoder: Layers<'a>,
    /// Head: sum over trajectories of the per-trajectory mean r -> posterior mean of z.
    #[serde(borrow)]
    pub z_head: Layers<'a>,
    /// Policy: `[norm(obs), z]` -> pre-tanh action mean.
    #[serde(borrow)]
    pub policy: Layers<'a>,
}

/// CRC-32 (IEEE 802.3, reflected, as zlib's `crc32`), table built at compile time.
pub fn crc32(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            table[i] = c;
            i += 1;
        }
        table
    };
    let mut crc = !0u32;
    for &b in bytes {
        crc = TABLE[((crc ^ b as u32) & 0xFF) as usize] ^ (crc >> 8);
    }
    !crc
}

#[cfg(test)]
mod tests {
    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(super::crc32(b"123456789"), 0xCBF4_3926);
    }
}
