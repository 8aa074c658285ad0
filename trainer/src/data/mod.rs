//! Data that flows into the learners: demos recorded by an expert, the meta-train /
//! held-out split with task and context sampling, rollouts, and replay buffers.

mod demos;
mod replay;
mod rollout;
mod split;

pub use demos::{DemoSpec, record, record_with};
pub use replay::{Batch, BatchVecs, ReplayBuffer, TaskReplay};
pub use rollout::{ActFn, Episode, Step, better, quick_eval, run_episode};
pub use split::{ContextDraw, MetaData, distinct_tasks, sample_context};
