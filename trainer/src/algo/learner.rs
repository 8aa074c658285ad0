//! The one interface of a learner, [`Learner`], which SMILe, Meta-BC (Meta-DAgger its option)
//! and the SAC expert implement and [`fit`](crate::fit) trains, as in burn: the loop owns the
//! log, the cadence, keeping the best, the budget and the end; a learner supplies its unit of
//! work, evaluation, state and files. [`MetaSettings`] is a meta-learner's configuration as the
//! run driver and sweeps set it, [`Algo`] the meta-learners by name. Adding one: ARCHITECTURE.md,
//! "An algorithm".

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::Serialize;
use serde::de::DeserializeOwned;
use sim::Family;

pub use crate::algo::fit::{Cadence, Evaluation, Fields, Progress, Score};

use crate::algo::expert::set::ExpertSet;
use crate::algo::setting::Setting;
use crate::data::MetaData;
use crate::error::{Error, Result};
use crate::io::MetricsLog;

/// The meta-learners, by the name `smile train --algo` and sweep plans take.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Algo {
    /// SMILe on (s, a, s') contexts and an [s, a, z] discriminator.
    Smile,
    /// SMILe on (s, s') contexts and an [s, s', z] discriminator.
    SmileStateOnly,
    /// Meta-BC: encoder and policy regressing the demos' actions.
    MetaBc,
    /// Meta-DAgger: Meta-BC plus online relabelling by an expert.
    MetaDagger,
}

impl Algo {
    /// Every algorithm, in the order help texts list them.
    pub const ALL: [Algo; 4] = [
        Algo::Smile,
        Algo::SmileStateOnly,
        Algo::MetaBc,
        Algo::MetaDagger,
    ];

    /// The name on the command line and in plans and run directories.
    pub fn name(self) -> &'static str {
        match self {
            Algo::Smile => "smile",
            Algo::SmileStateOnly => "smile-state-only",
            Algo::MetaBc => "meta-bc",
            Algo::MetaDagger => "meta-dagger",
        }
    }

    /// Whether training queries an expert (Meta-DAgger relabels the states it visits).
    pub fn needs_expert(self) -> bool {
        self == Algo::MetaDagger
    }
}

impl fmt::Display for Algo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algo {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        Algo::ALL
            .into_iter()
            .find(|a| a.name() == s)
            .ok_or_else(|| {
                let names = Algo::ALL.map(Algo::name).join(", ");
                Error::Config(format!("unknown algo {s:?}; expected one of {names}"))
            })
    }
}

/// What a learner's budget counts, for progress bars and messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unit {
    /// The budget's units ("update pairs").
    pub plural: &'static str,
    /// One unit, in messages ("resuming from update 2000").
    pub word: &'static str,
}

/// What a meta-learner learns from besides its configuration: the meta-train demos (split) and,
/// for Meta-DAgger, the expert that relabels its rollouts.
pub struct MetaInputs {
    /// The meta-train tasks and their held-out part.
    pub data: MetaData,
    /// Meta-DAgger's relabelling expert; `None` for the learners of demos alone (they refuse
    /// one).
    pub expert: Option<ExpertSet>,
}

/// A learner: started from its configuration and inputs, or resumed from a run directory, and
/// trained there by [`fit`](crate::fit) through the hooks below.
///
/// ```text
/// begin                      (warm start, the untrained policy's evaluation)
/// while !finished (the learner's budget or stopping rule, or the compute budget):
///     advance                (SAC: one episode; SMILe: one iteration of Algorithm 1;
///                             Meta-BC: one step)
///     cpu_seconds_mut        (the run's CPU-seconds, counted and logged: charts/cpu_s)
///     log the metrics        (with the units per second, charts/sps)
///     if an evaluation is due: evaluate; save_kept if best; log; report
///                            (finished now: the learner's stopping rule ended it here)
///     if a checkpoint is due: save_checkpoint; report
/// finish                     (the final policy files)
/// ```
pub trait Learner: Sized {
    /// Its hyper-parameters (a TOML file's type; `Default` is the documented defaults).
    type Config: Clone + fmt::Debug + PartialEq + Serialize + DeserializeOwned;

    /// What it learns from besides its configuration ([`MetaInputs`]; `()` for a SAC expert).
    type Inputs;

    /// What its budget counts.
    const UNIT: Unit;

    /// A fresh run.
    fn start(cfg: Self::Config, inputs: Self::Inputs) -> Result<Self>;

    /// The run checkpointed in `dir`, taking its budget from `wanted` (a larger one, say) and
    /// everything else from the checkpoint.
    fn resume(dir: &Path, inputs: Self::Inputs, wanted: &Self::Config) -> Result<Self>;

    /// The configuration it runs with.
    fn config(&self) -> &Self::Config;

    /// Units of work done.
    fn done(&self) -> u64;

    /// Its budget, and when evaluations and checkpoints are due.
    fn cadence(&self) -> Cadence;

    /// Before the loop: a warm start, the untrained policy's evaluation.
    fn begin(&mut self, _log: &mut MetricsLog) -> Result<()> {
        Ok(())
    }

    /// Whether training is over: the budget is done (or the learner's stopping rule ended it).
    fn finished(&self) -> bool {
        self.done() >= self.cadence().total
    }

    /// Where the learner keeps the run's CPU-seconds for its checkpoint: the loop starts from
    /// it (the earlier processes' count), updates it after each unit of work and logs it
    /// (`charts/cpu_s`); `None` for a learner that keeps no count.
    fn cpu_seconds_mut(&mut self) -> Option<&mut f64> {
        None
    }

    /// One unit of work; returns the metrics to log at [`Learner::done`] (none: no line).
    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields>;

    /// The held-out evaluation; `None` when there is nothing to evaluate on.
    fn evaluate(&mut self) -> Result<Option<Evaluation>>;

    /// Writes the checkpoint to `dir`.
    fn save_checkpoint(&self, dir: &Path) -> Result<()>;

    /// Writes the current policy as the one kept so far (an evaluation judged it best).
    fn save_kept(&self, dir: &Path) -> Result<()>;

    /// After the loop: the final policy files.
    fn finish(&mut self, dir: &Path, log: &mut MetricsLog) -> Result<()>;
}

/// A meta-learner's configuration as the run driver and sweeps set it: what the algorithm and
/// family decide, the caller's typed settings, the budget.
pub trait MetaSettings: Clone + PartialEq + Default + Serialize + DeserializeOwned {
    /// Sets what the algorithm and family decide (its `env`, SMILe's state-only switch,
    /// Meta-BC's DAgger switch).
    fn configure(&mut self, algo: Algo, family: Family);

    /// Writes `setting` into this configuration; `false`, changing nothing, where the
    /// algorithm has no such setting. An exhaustive `match`: a new [`Setting`] does not compile
    /// until every learner takes or refuses it.
    fn set(&mut self, setting: Setting) -> bool;

    /// Lays `settings` over this configuration, in order; one the algorithm has not is refused
    /// by name and position ([`Error::NoSuchSetting`]) and then nothing changes.
    fn apply(&mut self, algo: Algo, settings: &[Setting]) -> Result<()> {
        let mut cfg = self.clone();
        for (at, s) in settings.iter().enumerate() {
            if !cfg.set(s.clone()) {
                let (name, algo) = (s.name(), algo.name());
                return Err(Error::NoSuchSetting { name, at, algo });
            }
        }
        *self = cfg;
        Ok(())
    }

    /// The training budget as settings, the same parts in the same order for every
    /// configuration of a type (its updates, and the CPU-seconds where the algorithm has that
    /// budget): what a resume may change, and what a sweep extends a finished cell
    /// with where [`MetaSettings::EXTENDS`].
    fn budget(&self) -> Vec<Setting>;

    /// Whether a finished run continues to a larger budget (SMILe), or a larger budget is a
    /// new run (Meta-BC: its policy is the one early stopping picked; more steps are another
    /// selection).
    const EXTENDS: bool;

    /// Checks every value.
    fn validate(&self) -> Result<()>;

    /// Every how many meta-train tasks one is held out for validation (the data split the run
    /// needs, [`MetaData::from_dataset`]).
    fn holdout_every(&self) -> usize;
}
