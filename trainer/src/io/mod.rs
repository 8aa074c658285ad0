//! What the trainer writes and reads: atomic checkpoints, the metrics log (JSON lines and
//! TensorBoard events), the infer-core blob export with its verification, and progress bars.

pub mod checkpoint;
pub mod export;
mod metrics;
pub mod progress;

pub use metrics::{METRICS_FILE, MetricsLog, TbWriter, sac_fields};
pub use progress::bar;
