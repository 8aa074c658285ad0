#![no_std]
#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod error;
pub mod estimator;
pub mod format;
mod kernels;
mod model;
mod runner;
#[cfg(feature = "alloc")]
mod writer;

pub use error::{BlobError, InferError};
pub use estimator::{Channel, Estimator, EstimatorConfig, EstimatorError, StepReport};
pub use format::{Activation, Header, ModelKind, Quant};
pub use model::Model;
pub use runner::{ContextEncoder, Policy};
#[cfg(feature = "alloc")]
pub use writer::{
    Calibration, Dims, FloatLayer, FloatModel, WriteError, write_blob, write_blob_with,
};
