//! The learning algorithms, one file each, their losses next to the equations they implement.
//!
//! * [`sac`]: soft actor-critic (SAC v2), the RL learner of the experts and of SMILe.
//! * [`expert`]: oracle SAC experts per family (and the scripted PD expert of point-goal).
//! * [`smile`]: SMILe, state-action and state-only (Algorithm 1 of the paper).
//! * [`meta_bc`]: the baselines Meta-BC and Meta-DAgger.
//! * [`learner`]: [`Algo`] and [`MetaLearner`], the one interface SMILe and Meta-BC implement
//!   and `smile train`, the quickstart and the sweep drive.
//! * `settings`: [`Overrides`], the typed settings a caller lays over a configuration file.
//! * `fit`: the one fit loop they train through (metrics, evaluation and keeping the best,
//!   checkpoints, stopping, the final policies), each learner its `Fit` hooks.

pub mod expert;
mod fit;
pub mod learner;
pub mod meta_bc;
mod registry;
mod settings;
pub(crate) use registry::other_env;
pub mod sac;
pub mod smile;

pub use learner::{Algo, MetaLearner, Progress, WithLearner};
pub use settings::Overrides;
