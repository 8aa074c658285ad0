//! What the trainer writes and reads: configuration files (over the defaults), atomic
//! checkpoints, the metrics log (JSON lines and TensorBoard events), the infer-core blob export
//! with its verification, the ONNX export, and progress bars.

pub mod checkpoint;
mod config;
pub mod export;
pub mod lock;
mod metrics;
pub mod onnx;
pub(crate) mod os_path;
pub mod progress;

pub use config::from_toml_over_defaults;
pub(crate) use config::merge_tables;
pub use lock::DirLock;
pub use metrics::{METRICS_FILE, MetricsLog, TbWriter};
pub use progress::bar;
