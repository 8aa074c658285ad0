//! Learning side of SMILe: SAC experts, demos, SMILe, Meta-BC, Meta-DAgger, evaluation with
//! the paper's metrics, checkpoints and export of an infer-core policy blob.
//!
//! The modules follow the data flow:
//!
//! ```text
//! model (networks) -> algo (SAC, experts, SMILe, Meta-BC) -> data (demos, split, rollouts,
//! replay) -> eval (protocols, metrics) -> io (checkpoints, run records, metrics log, blob
//! export) -> CLI
//! ```
//!
//! * `model`: [`Mlp`], [`TanhGaussianPolicy`], [`ContextEncoder`], [`Discriminator`] and
//!   [`MetaPolicy`], each a type with `new` and `forward`, on one fused dense layer.
//! * `optim`: [`Adam`], one fused in-place pass per parameter.
//! * `algo`: one file per algorithm, its loss next to its equation: [`sac`], [`expert`],
//!   [`smile`], [`meta_bc`] (Meta-BC and Meta-DAgger). Each implements one interface,
//!   [`Learner`], and trains through one loop, [`fit`], reporting [`Progress`]; the
//!   meta-learners are named by [`Algo`], their configurations set through [`MetaSettings`].
//!   A new algorithm is its file(s), one [`Algo`] variant and one arm in the run driver's
//!   map from an algorithm to its learner type (ARCHITECTURE.md, "An algorithm").
//! * `data`: demos ([`record_demos`]), the meta-train / held-out split ([`MetaData`]),
//!   rollouts ([`run_episode`]) and replay buffers.
//! * [`eval`]: the paper's evaluation protocols per family (JSON, markdown, SVG plot), the
//!   walker-dyn normalised metric, expert evaluation.
//! * `io`: [`checkpoint`]s, a run directory's records (`run.json`, `config.toml`), the metrics
//!   log, the blob [`export`], the [`onnx`] export.
//! * [`run`]: a run directory started or resumed ([`run::train`]): configuration (a file
//!   under typed [`Setting`]s), demos, expert, records and lock around a [`Learner`]; what
//!   `smile train`, sweep cells and the quickstart call. [`run::train_expert`] does the same
//!   for a SAC expert, through the same tail.
//! * [`threads`]: the compute thread layout.
//!
//! This crate is the library: what learns and what it writes. The application over it (the
//! `smile` command line, the quickstart, sweeps, reports, benchmarks) is the `smile-app` crate
//! (`app/`), which uses only this public API.
#![warn(missing_docs)]

mod algo;
mod data;
mod error;
mod io;
mod model;
mod optim;

pub mod eval;
pub mod run;
pub mod threads;

// Algorithms: each module holds its configuration and its run type, a `Learner` trained by
// `fit`; the meta-learners' configurations are `MetaSettings`, named by `Algo`.
pub use algo::{
    Algo, Cadence, Evaluation, Fields, Learner, MetaInputs, MetaSettings, Progress, Score, Setting,
    Unit, expert, fit, meta_bc, sac, smile,
};

/// Errors and the result alias.
pub use error::{Error, Input, Result};

/// Networks: MLPs, the SAC policy, the context encoder, the discriminator, the meta-policy.
pub use model::{
    ContextBatch, ContextConfig, ContextEncoder, ContextSpec, DiscInput, DiscStats, Discriminator,
    FrozenMlp, META_POLICY_FILE, MetaPolicy, Mlp, ObsNorm, PolicySample, TanhGaussianPolicy,
    TrainingMark,
};

/// The optimiser.
pub use optim::{Adam, AdamConfig};

/// Demos: deterministic expert rollouts in `sim`'s dataset format.
pub use algo::expert::{DemoSpec, record as record_demos, record_with as record_demos_with};

/// A trained meta-policy distilled to act through the device's senses (issue 73).
pub use algo::distill::{DistillConfig, DistillReport, distill_through_sensing};
/// Demos, the meta-train split, rollouts and replay.
pub use data::{
    ActFn, ActionNoise, Batch, BatchVecs, Episode, HeldOut, MetaData, ReplayBuffer, Step,
    TaskReplay, better, quick_eval, read_demos, read_demos_of, run_episode,
};
/// Training through the device's senses: a learner's `[sensing]` section and the rollout that
/// reads the plant as firmware-sim's loop does.
pub use data::{Sensing, sensed_episode};

/// Checkpoints, blob export and ONNX export keep their namespaces (`checkpoint::load`,
/// `export::verify`, `onnx::export`).
pub use io::{checkpoint, onnx};

/// Blob export ([`io::export`](crate::export)) and its verification (which evaluates the blob)
/// under one name.
pub mod export {
    pub use crate::eval::blob::*;
    pub use crate::io::export::*;
    pub use crate::io::qat::*;
}

/// Serde for paths whose names need not be UTF-8 (`#[serde(with = "trainer::os_path")]`).
pub use io::os_path;

/// One writer per output directory.
pub use io::{DirLock, lock};

/// The bounds every count, budget and episode length is checked against, from a flag, a
/// configuration or a plan alike.
pub use io::{MAX_COUNT, MAX_HORIZON, MAX_STEPS};

/// The metrics log (JSON lines + TensorBoard events).
pub use io::{METRICS_FILE, MetricsLog, from_toml_over_defaults, set_key as set_config_key};
