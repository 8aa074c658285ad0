//! Learning side of SMILe: SAC, SMILe, Meta-BC, Meta-DAgger, evaluation and blob export.
//!
//! Module map (one algorithm per file, losses next to their equations):
//! * [`fused`]: the fused dense layer (`CustomOp3`) the MLPs are built from.
//! * [`nn`]: MLPs on candle-core, target networks in their own storage, fused in-place Adam.
//! * [`policy`]: the tanh-squashed Gaussian policy with reparameterisation.
//! * [`replay`]: flat preallocated ring replay buffers (one per task for meta-learning).
//! * [`sac`]: soft actor-critic (SAC v2: twin Q, Polyak targets, learned temperature) and its
//!   hyper-parameters.
//! * [`context`]: the permutation-invariant context encoder and observation normalisation
//!   every meta-learner shares.
//! * [`meta_policy`]: encoder + conditioned policy, saved and loaded as one file, and its
//!   conversion to infer-core's blob structure.
//! * [`meta_data`]: meta-train demos split into training / held-out train tasks (refuses
//!   meta-test data), context sampling, rollouts.
//! * [`smile`]: SMILe (state-action and state-only): discriminator, encoder, SAC on its reward;
//!   [`disc`]: its discriminator losses (BCE with logits, gradient penalty).
//! * [`meta_bc`]: Meta-BC and Meta-DAgger (validation-based early stopping).
//! * [`eval`]: the paper's evaluation protocols per family (JSON, markdown, SVG plot);
//!   [`eval_norm`]: walker-dyn's normalised metric's base and expert returns.
//! * [`export`]: infer-core blob export with parity and metric verification.
//! * [`quickstart`]: the whole pipeline in one call (`smile quickstart`).
//! * [`progress`]: the shared progress-bar style.
//! * [`checkpoint`]: atomic safetensors checkpoints with JSON metadata.
//! * [`demos`]: deterministic expert demonstrations in sim's dataset format.
//! * [`expert`]: oracle SAC experts (training loop, export, loading) and the scripted PD expert;
//!   [`expert_eval`]: their evaluation on a split.
//! * [`bench`](mod@bench): timing of the learner's update steps (`smile bench`).
//! * [`metrics`]: the JSON-lines metrics log.
//! * [`threads`]: the compute thread layout (candle's matmul thread count).
#![warn(missing_docs)]

pub mod bench;
pub mod checkpoint;
pub mod context;
pub mod demos;
pub mod disc;
pub mod eval;
pub mod eval_norm;
pub mod expert;
pub mod expert_eval;
pub mod export;
pub mod fused;
pub mod meta_bc;
pub mod meta_data;
pub mod meta_policy;
pub mod metrics;
pub mod nn;
pub mod policy;
pub mod progress;
pub mod quickstart;
pub mod replay;
pub mod sac;
pub mod smile;
pub mod threads;

/// Errors of the trainer library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A tensor operation failed inside candle.
    #[error("tensor op: {0}")]
    Candle(#[from] candle_core::Error),
    /// A configuration value is invalid.
    #[error("invalid config: {0}")]
    Config(String),
    /// Tensor shapes or dimensions disagree (e.g. a checkpoint for another network size).
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A loss or statistic became NaN or infinite.
    #[error("non-finite {what} ({value}) at update {update}")]
    NonFinite {
        /// Which quantity diverged, e.g. `losses/qf`.
        what: &'static str,
        /// Its value.
        value: f32,
        /// The update counter at which it happened (1-based).
        update: u64,
    },
    /// A replay buffer cannot serve the request (e.g. sampling from an empty buffer).
    #[error("replay buffer: {0}")]
    Replay(String),
    /// A checkpoint could not be written or read (missing, truncated, corrupt, mismatched).
    #[error("checkpoint {}: {reason}", path.display())]
    Checkpoint {
        /// The file or directory concerned.
        path: std::path::PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// An environment or dataset error from `sim`.
    #[error("sim: {0}")]
    Sim(String),
    /// The simulated device (firmware-sim) refused the blob or failed to run it.
    #[error("device: {0}")]
    Device(String),
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: std::path::PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Result alias of the trainer library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
