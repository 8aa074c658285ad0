//! infer-core's one error type: loading a blob, running it, the estimator and the writer all
//! return [`Error`], so a caller matches one enum and `?` works across them.

use core::fmt;

/// `Result` with infer-core's [`Error`].
pub type Result<T> = core::result::Result<T, Error>;

/// Everything that can go wrong in infer-core, by where it happens:
///
/// - **loading** ([`Model::from_bytes`](crate::Model::from_bytes), and the runners'
///   constructors, which check the blob's widths against their compiled capacity once): the
///   byte string is not a usable policy blob;
/// - **running** ([`Policy::act`](crate::Policy::act),
///   [`ContextEncoder`](crate::ContextEncoder)): one inference call could not give a normal
///   result;
/// - **estimating** ([`Estimator`](crate::Estimator)): a configuration the estimator cannot
///   take, or no estimate yet;
/// - **writing** (`write_blob`, feature `alloc`): a float model or calibration that cannot
///   become a blob.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// Fewer bytes than the fixed envelope header.
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// The first four bytes are not the blob magic `SMLB`.
    BadMagic,
    /// A format version this build does not read.
    UnsupportedVersion {
        /// Version found in the envelope.
        found: u16,
    },
    /// An older format version that this build no longer reads: re-export the policy.
    OutdatedVersion {
        /// Version found in the envelope.
        found: u16,
    },
    /// The envelope's payload length disagrees with the bytes given (truncated or extended).
    LengthMismatch {
        /// Payload length declared in the envelope.
        declared: usize,
        /// Payload bytes actually present.
        actual: usize,
    },
    /// The payload's CRC-32 does not match the envelope: the blob is corrupt.
    ChecksumMismatch {
        /// CRC-32 declared in the envelope.
        declared: u32,
        /// CRC-32 computed over the payload.
        computed: u32,
    },
    /// The payload does not decode as the blob format.
    Decode,
    /// The payload decodes but leaves bytes unread.
    TrailingBytes,
    /// A dimension is zero, or two connected dimensions disagree.
    DimMismatch {
        /// Which part of the model: `"encoder"`, `"z_head"`, `"policy"`, `"obs_norm"`...
        part: &'static str,
        /// Dimension the model structure requires.
        expected: usize,
        /// Dimension found in the blob.
        found: usize,
    },
    /// An MLP has no layers.
    EmptyMlp {
        /// Which MLP.
        part: &'static str,
    },
    /// An MLP has more layers than the format allows
    /// ([`MAX_LAYERS`](crate::MAX_LAYERS)).
    TooManyLayers {
        /// Which MLP.
        part: &'static str,
        /// Layers stored in the blob.
        found: usize,
    },
    /// A tensor's byte length does not match its declared shape.
    TensorLength {
        /// Which part of the model.
        part: &'static str,
        /// Bytes the shape requires.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
    /// A weight, bias, normalisation value or scale is NaN or infinite.
    NonFinite {
        /// Which part of the model.
        part: &'static str,
    },
    /// A quantization scale or a normalisation std is not strictly positive.
    NonPositiveScale {
        /// Which part of the model.
        part: &'static str,
    },
    /// The policy's last layer has a non-linearity; the action is `tanh` of its raw output.
    PolicyOutputActivation,
    /// A layer is stored coarser than the header's quantization, the blob's lowest precision.
    LayerBelowHeader {
        /// Which MLP.
        part: &'static str,
        /// The layer's quantization.
        layer: crate::format::Quant,
        /// The header's quantization.
        header: crate::format::Quant,
    },
    /// A layer is wider than the runner's compiled capacity `W`.
    CapacityExceeded {
        /// Width the blob needs.
        needed: usize,
        /// Width this runner was compiled with.
        capacity: usize,
    },

    // Running a loaded blob.
    /// An input slice has the wrong length.
    WrongLength {
        /// Which input: `"obs"`, `"z"`, `"action"`, `"next_obs"`.
        input: &'static str,
        /// Length the model needs.
        expected: usize,
        /// Length given.
        found: usize,
    },
    /// An input contains NaN or infinity. For [`Policy::act`](crate::Policy::act) the safe
    /// action (the centre of the action range) has been written to the output.
    NonFiniteInput {
        /// Which input.
        input: &'static str,
    },
    /// The computation overflowed to a non-finite value; the safe action has been written.
    NonFiniteOutput,
    /// [`ContextEncoder::latent`](crate::ContextEncoder::latent) was called before any
    /// transition was pushed.
    EmptyContext,

    // The estimator.
    /// More channels than the estimator's capacity `N`, or none.
    ChannelCount {
        /// Channels given.
        found: usize,
        /// The capacity `N`.
        capacity: usize,
    },
    /// A rate names an entry that is not a position or angle, or has a non-finite scale.
    BadRate {
        /// Index of the rate channel.
        index: usize,
        /// The index it names.
        of: usize,
    },
    /// An estimator configuration value is out of its range.
    BadConfig {
        /// Which field of [`EstimatorConfig`](crate::EstimatorConfig).
        field: &'static str,
    },
    /// The channel at this observation index has had no valid reading yet: there is no
    /// estimate to give the policy.
    NotReady {
        /// Observation index.
        index: usize,
    },

    // Writing a blob (feature `alloc`). A blob that fails to load back after writing (a
    // writer bug) returns the loader's error.
    /// A dimension or tensor length of the float model is inconsistent.
    Shape(&'static str),
    /// `w8a8` needs calibration contexts and observations.
    MissingCalibration,
    /// A dimension does not fit the format's `u16`.
    TooLarge,
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
    /// A higher precision asked for some layers (the edges, or the context encoder and z
    /// head) is coarser than the blob's own.
    FinerBelowQuant {
        /// The quantization asked for those layers.
        asked: crate::format::Quant,
        /// The blob's quantization.
        quant: crate::format::Quant,
    },
}

/// Largest weight or bias magnitude a blob takes: trained networks stay orders of magnitude
/// below it, and beyond it a quantization scale or an accumulated sum can overflow f32.
pub(crate) const MAX_PARAMETER: f32 = 1.0e6;

impl fmt::Display for Error {
    // Over 100 lines on purpose: one arm per variant of the crate's one error enum, each
    // message beside the others so their wording stays alike.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::TooShort { len } => write!(
                f,
                "blob too short: {len} bytes, need at least {}",
                crate::format::ENVELOPE_LEN
            ),
            Self::BadMagic => f.write_str("not a SMILe policy blob (bad magic)"),
            Self::UnsupportedVersion { found } => write!(
                f,
                "unsupported blob format version {found} (this build reads {})",
                crate::format::FORMAT_VERSION
            ),
            Self::OutdatedVersion { found } => write!(
                f,
                "blob format v{found} is no longer read (this build reads v{}): re-export the \
                 policy with `smile export`",
                crate::format::FORMAT_VERSION
            ),
            Self::LengthMismatch { declared, actual } => write!(
                f,
                "blob payload is {actual} bytes but the header declares {declared} (truncated or extended)"
            ),
            Self::ChecksumMismatch { declared, computed } => write!(
                f,
                "blob checksum mismatch (declared {declared:#010x}, computed {computed:#010x}): corrupt blob"
            ),
            Self::Decode => write!(
                f,
                "blob payload does not decode as format v{}",
                crate::format::FORMAT_VERSION
            ),
            Self::TrailingBytes => f.write_str("blob payload has trailing bytes after the model"),
            Self::DimMismatch {
                part,
                expected,
                found,
            } => write!(f, "{part}: dimension {found} where {expected} is required"),
            Self::EmptyMlp { part } => write!(f, "{part}: MLP has no layers"),
            Self::TooManyLayers { part, found } => write!(
                f,
                "{part}: {found} layers, the format allows at most {}",
                crate::format::MAX_LAYERS
            ),
            Self::TensorLength {
                part,
                expected,
                found,
            } => write!(
                f,
                "{part}: tensor has {found} bytes, its shape needs {expected}"
            ),
            Self::NonFinite { part } => write!(f, "{part}: contains NaN or infinite values"),
            Self::NonPositiveScale { part } => {
                write!(f, "{part}: scale or std is not strictly positive")
            }
            Self::PolicyOutputActivation => f.write_str(
                "policy: last layer must have identity activation (tanh is applied to its output)",
            ),
            Self::LayerBelowHeader {
                part,
                layer,
                header,
            } => write!(
                f,
                "{part}: a layer is stored as {layer:?}, coarser than the blob's {header:?}"
            ),
            Self::CapacityExceeded { needed, capacity } => write!(
                f,
                "blob needs width {needed} but this runner was built for at most {capacity}"
            ),
            Self::WrongLength {
                input,
                expected,
                found,
            } => write!(f, "{input}: length {found}, {expected} needed"),
            Self::NonFiniteInput { input } => {
                write!(f, "{input} contains NaN or infinity; safe action used")
            }
            Self::NonFiniteOutput => f.write_str("policy output overflowed; safe action used"),
            Self::EmptyContext => f.write_str("no context transition pushed yet"),
            Self::ChannelCount { found, capacity } => write!(
                f,
                "{found} observation channels; the estimator takes 1 to {capacity}"
            ),
            Self::BadRate { index, of } => write!(
                f,
                "channel {index} is a rate of channel {of}, which is not a position or angle (or its scale is not finite)"
            ),
            Self::BadConfig { field } => write!(f, "estimator config: {field} out of range"),
            Self::NotReady { index } => write!(
                f,
                "no valid reading of observation entry {index} yet: no estimate"
            ),
            Self::Shape(what) => write!(f, "inconsistent shape: {what}"),
            Self::MissingCalibration => {
                f.write_str("w8a8 needs calibration contexts and observations")
            }
            Self::TooLarge => f.write_str("a dimension exceeds 65535"),
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
                let at = if what == "observation" {
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
            Self::FinerBelowQuant { asked, quant } => write!(
                f,
                "layers as {asked:?} would be coarser than the blob's {quant:?}: the edges and \
                 the context encoder take a higher precision, not a lower one"
            ),
        }
    }
}

impl core::error::Error for Error {}
