//! Data that flows into the learners: the meta-train /
//! held-out split with task and context sampling, rollouts, and replay buffers.

mod demos;
mod early;
mod replay;
mod rollout;
mod sensing;
mod split;

pub use demos::{read_demos, read_demos_of};
pub use early::EarlyWeight;
pub use replay::{Batch, BatchVecs, ReplayBuffer, TaskReplay};
pub use rollout::{ActFn, ActionNoise, Episode, HeldOut, Step, better, quick_eval, run_episode};
pub use sensing::{Sensing, sensed_episode};
pub use split::{ContextDraw, MetaData, distinct_tasks, sample_context};
