#![no_std]
#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod error;
mod estimator;
mod format;
mod kernels;
mod model;
mod runner;
#[cfg(feature = "alloc")]
mod writer;

pub use error::{Error, Result};
pub use estimator::{Channel, Estimator, EstimatorConfig, StepReport};
pub use format::{
    Activation, ENVELOPE_LEN, FORMAT_VERSION, Header, MAGIC, MAX_LAYERS, ModelKind, Quant, crc32,
};
pub use model::{Mlp, Model};
pub use runner::{ContextEncoder, Policy};
#[cfg(feature = "alloc")]
pub use writer::{
    Calibration, Dims, FloatLayer, FloatModel, WriteOptions, write_blob, write_blob_with,
};
