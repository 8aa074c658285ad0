//! The two error enums: one for loading a blob, one for running it.

use core::fmt;

/// Why a byte string is not a usable policy blob.
///
/// Returned by [`Model::from_bytes`](crate::Model::from_bytes) and by the constructors of the
/// runners ([`Policy`](crate::Policy), [`ContextEncoder`](crate::ContextEncoder)), which check
/// the blob's widths against their compiled capacity once, before anything runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum BlobError {
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
    /// ([`MAX_LAYERS`](crate::format::MAX_LAYERS)).
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
    /// A layer is wider than the runner's compiled capacity `W`.
    CapacityExceeded {
        /// Width the blob needs.
        needed: usize,
        /// Width this runner was compiled with.
        capacity: usize,
    },
}

impl fmt::Display for BlobError {
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
            Self::CapacityExceeded { needed, capacity } => write!(
                f,
                "blob needs width {needed} but this runner was built for at most {capacity}"
            ),
        }
    }
}

/// Why one inference call could not produce a normal result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum InferError {
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
}

impl fmt::Display for InferError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::WrongLength {
                input,
                expected,
                found,
            } => write!(f, "{input}: length {found}, the model needs {expected}"),
            Self::NonFiniteInput { input } => {
                write!(f, "{input} contains NaN or infinity; safe action used")
            }
            Self::NonFiniteOutput => f.write_str("policy output overflowed; safe action used"),
            Self::EmptyContext => f.write_str("no context transition pushed yet"),
        }
    }
}

impl core::error::Error for BlobError {}
impl core::error::Error for InferError {}
