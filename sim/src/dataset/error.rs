//! The one error type of the demo dataset format.

use crate::error::SimError;

use crate::kinds::Physics;

use crate::family::Family;

use super::FORMAT_NAME;

/// Everything that can go wrong reading, writing or transforming a demo dataset.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A shipped file whose bytes are not the ones its folder's checksum list names.
    #[error(transparent)]
    Integrity(#[from] crate::shipped::IntegrityError),
    /// The file is shorter than its header says (e.g. an interrupted copy).
    #[error("truncated demo file: {expected} bytes expected, {got} present")]
    Truncated {
        /// Bytes the header announces.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The bytes are not a valid safetensors file.
    #[error("corrupt demo file: {0}")]
    Corrupt(String),
    /// A valid safetensors file that is not a demo dataset (its `format` key is missing or
    /// names another format).
    #[error("not a {FORMAT_NAME} file: {0}")]
    NotADemoFile(String),
    /// A demo file of a `format_version` this build does not read.
    #[error("demo file has format_version {found}; this build reads version {supported}")]
    UnsupportedVersion {
        /// Version in the file.
        found: u32,
        /// The version this build reads and writes ([`FORMAT_VERSION`](super::FORMAT_VERSION)).
        supported: u32,
    },
    /// A required metadata key is missing or cannot be parsed.
    #[error("metadata key {key:?}: {reason}")]
    BadMetadata {
        /// The key.
        key: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A required tensor is missing or has the wrong dtype or shape.
    #[error("tensor {name:?}: {reason}")]
    BadTensor {
        /// Tensor name.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// Tensors disagree with each other (offsets out of range, non-increasing, ...).
    #[error("inconsistent demo file: {0}")]
    Inconsistent(String),
    /// A stored float (observation, action, reward, next observation, task value or task
    /// parameter) is NaN or infinite: a demo file never carries one, in either direction.
    #[error(
        "tensor {tensor:?} holds the non-finite value {value} in task {task}{}",
        trajectory.map(|j| format!(", trajectory {j}")).unwrap_or_default()
    )]
    NonFinite {
        /// Tensor name (`obs`, `actions`, `rewards`, `next_obs`, `task_values`,
        /// `task_parameters`).
        tensor: &'static str,
        /// Index of the task, in file order.
        task: usize,
        /// Index of the trajectory over the whole file (the `traj_seeds` order); `None` for
        /// the per-task tensors.
        trajectory: Option<usize>,
        /// The offending value.
        value: f64,
    },
    /// The dataset is of another family than the one asked for.
    #[error("demo file is for {found}, expected {expected}")]
    FamilyMismatch {
        /// Family the caller needs.
        expected: Family,
        /// Family in the file.
        found: Family,
    },
    /// The demos were recorded on another physics backend than the run's.
    #[error(
        "the demo file was recorded on the {found} plant, this run simulates {expected}: record \
         demos on {expected}, or run on {found}"
    )]
    PhysicsMismatch {
        /// The run's plant.
        expected: Physics,
        /// The file's plant.
        found: Physics,
    },
    /// A trajectory or transition does not match the dataset's dimensions.
    #[error("{what} has length {got}, expected {expected}")]
    DimensionMismatch {
        /// What was checked.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// Subsampling was asked for with a bad factor or on an already subsampled dataset.
    #[error("cannot subsample: {0}")]
    Subsample(String),
    /// Rolling out the expert failed.
    #[error("recording a demo failed: {0}")]
    Sim(#[from] SimError),
}

impl DatasetError {
    /// [`DatasetError::DimensionMismatch`] for the first `(what, expected, got)` whose lengths
    /// differ.
    pub(crate) fn check_lengths(
        checks: impl IntoIterator<Item = (&'static str, usize, usize)>,
    ) -> Result<(), Self> {
        match checks
            .into_iter()
            .find(|(_, expected, got)| expected != got)
        {
            Some((what, expected, got)) => Err(Self::DimensionMismatch {
                what,
                expected,
                got,
            }),
            None => Ok(()),
        }
    }
}
