//! What the trainer writes and reads: configuration files (over the defaults), atomic
//! checkpoints, a run directory's records (`run_dir`), the metrics log (JSON lines and
//! TensorBoard events), the infer-core blob export with its verification, and the ONNX export.

pub mod checkpoint;
mod config;
pub mod export;
pub mod lock;
mod metrics;
pub mod onnx;
pub mod os_path;
mod policy_file;
pub mod qat;
pub mod run_dir;

pub use config::{MAX_COUNT, MAX_HORIZON, MAX_STEPS};
pub use config::{from_toml_over_defaults, set_key};
pub(crate) use config::{require_positive, require_run};
pub use lock::DirLock;
pub use metrics::{METRICS_FILE, MetricsLog};
