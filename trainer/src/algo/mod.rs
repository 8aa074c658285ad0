//! The learning algorithms, one file each, their losses next to the equations they implement.
//!
//! * [`sac`]: soft actor-critic (SAC v2), the RL learner of the experts and of SMILe.
//! * [`expert`]: oracle SAC experts per family (and the scripted PD expert of point-goal).
//! * [`smile`]: SMILe, state-action and state-only (Algorithm 1 of the paper).
//! * [`meta_bc`]: the baselines Meta-BC and Meta-DAgger.
//! * [`distill`]: a trained meta-policy distilled to act through the device's senses.
//! * [`learner`]: [`Learner`], the one interface SMILe, Meta-BC and the SAC expert implement,
//!   [`MetaSettings`] their configurations', and [`Algo`], the meta-learners' names.
//! * `setting`: [`Setting`], the typed settings a caller lays over a configuration file.
//! * `fit`: [`fit`], the one loop every learner trains through (metrics, evaluation and
//!   keeping the best, checkpoints, stopping, the final policies).

pub mod distill;
pub mod expert;
mod fit;
pub mod learner;
pub mod meta_bc;
pub mod sac;
mod setting;
pub mod smile;

pub use fit::fit;
pub use learner::{
    Algo, Cadence, Evaluation, Fields, Learner, MetaInputs, MetaSettings, Progress, Score, Unit,
};
pub use setting::Setting;
