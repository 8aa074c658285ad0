//! One interface for the meta-learners: [`Algo`] names them, [`MetaLearner`] is what each one
//! implements, [`Progress`] is what each reports while it trains.
//!
//! `smile train`, the quickstart and `smile sweep` drive every learner through these. Adding
//! an algorithm is its folder under `algo/` (its update step and models, its `Fit` hooks for
//! the shared loop and its `impl MetaLearner`, as `smile/fit.rs`) and its entry in the one
//! list here ([`with_algorithms`]), which writes [`Algo`] and, in `registry.rs` (which imports
//! the learner type), [`Algo::with_learner`].

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::Serialize;
use serde::de::DeserializeOwned;
use sim::Family;

pub use crate::algo::fit::Progress;

use crate::algo::expert::ExpertSet;
use crate::algo::settings::Overrides;
use crate::data::MetaData;
use crate::error::{Error, Result};
use crate::model::MetaPolicy;

/// The one list of meta-learners, in the order help texts list them: per algorithm what it is
/// (its [`Algo`] variant's doc), its variant, its name on the command line and in plans and
/// run directories, the learner type that runs it and whether it queries an expert while
/// training. This module writes [`Algo`] and its registry from it; `registry.rs` writes
/// [`Algo::with_learner`], the map to the learner types (which it imports). Adding an
/// algorithm is its folder (its `mod` line in `algo/mod.rs`), its entry here and the import of
/// its learner type in `registry.rs`.
macro_rules! with_algorithms {
    ($then:ident) => {
        $then! {
            /// SMILe on (s, a, s') contexts and an [s, a, z] discriminator.
            Smile = "smile", learner Smile, expert false;
            /// SMILe on (s, s') contexts and an [s, s', z] discriminator.
            SmileStateOnly = "smile-state-only", learner Smile, expert false;
            /// Meta-BC: encoder and policy regressing the demos' actions.
            MetaBc = "meta-bc", learner MetaBc, expert false;
            /// Meta-DAgger: Meta-BC plus online relabelling by an expert.
            MetaDagger = "meta-dagger", learner MetaBc, expert true;
        }
    };
}
pub(crate) use with_algorithms;

/// Writes [`Algo`], [`Algo::ALL`], [`Algo::name`] and [`Algo::needs_expert`] from the list.
macro_rules! declare_algorithms {
    ($(
        $(#[$doc:meta])* $variant:ident = $name:literal,
        learner $learner:ident, expert $expert:literal;
    )+) => {
        /// The meta-learners, by the name `smile train --algo` and sweep plans take.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Algo {
            $($(#[$doc])* $variant,)+
        }

        impl Algo {
            /// Every algorithm, in the list's order (the order help texts list them).
            pub const ALL: [Algo; [$(Algo::$variant),+].len()] = [$(Algo::$variant),+];

            /// The name on the command line and in plans and run directories.
            pub fn name(self) -> &'static str {
                match self {
                    $(Algo::$variant => $name,)+
                }
            }

            /// Whether training queries an expert (Meta-DAgger relabels the states it visits).
            pub fn needs_expert(self) -> bool {
                match self {
                    $(Algo::$variant => $expert,)+
                }
            }
        }
    };
}

with_algorithms!(declare_algorithms);

/// A computation generic over the learner type, run for an [`Algo`] by
/// [`Algo::with_learner`]: how code that serves every algorithm (a run directory, a plan
/// check) reaches the algorithm's [`MetaLearner`] without naming it.
pub trait WithLearner {
    /// What it returns.
    type Output;
    /// Runs it with `L`, the learner of `algo`.
    fn call<L: MetaLearner>(self, algo: Algo) -> Self::Output;
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
                let names: Vec<&str> = Algo::ALL.iter().map(|a| a.name()).collect();
                Error::Config(format!(
                    "unknown algo {s:?}; expected one of {}",
                    names.join(", ")
                ))
            })
    }
}

/// A meta-learner: built from its configuration and the meta-train demos, or resumed from a
/// run directory; trained there; yielding a [`MetaPolicy`].
pub trait MetaLearner: Sized {
    /// Its hyper-parameters (a TOML file's type; `Default` is the documented defaults).
    type Config: Clone + fmt::Debug + PartialEq + Default + Serialize + DeserializeOwned;

    /// What the units of that budget are called in progress bars ("update pairs").
    const STEP_NAME: &'static str;

    /// One unit, in messages ("resuming from update 2000").
    const STEP_WORD: &'static str;

    /// The config keys a resumed run may change (the budget among them); every other key must
    /// stay what the run started with.
    const RESUMABLE: &'static [&'static str];

    /// Sets the parts of `cfg` that the algorithm and family decide (its `env`, SMILe's
    /// state-only switch, Meta-BC's DAgger switch).
    fn configure(cfg: &mut Self::Config, algo: Algo, family: Family);

    /// Lays the settings `o` gives over `cfg`; a setting the algorithm does not have is
    /// refused by name ([`Error::NoSuchSetting`]).
    fn apply(cfg: &mut Self::Config, algo: Algo, o: &Overrides) -> Result<()>;

    /// `cfg`'s training budget as settings (its updates, and the CPU-seconds where the
    /// algorithm has that budget): what a finished run resumes with to train on to a larger
    /// one. `None` when a larger budget is a new run instead.
    fn budget(cfg: &Self::Config) -> Option<Overrides>;

    /// Checks every value of `cfg`.
    fn validate(cfg: &Self::Config) -> Result<()>;

    /// Every how many meta-train tasks one is held out for validation (the data split the run
    /// needs, [`MetaData::from_dataset`]).
    fn holdout_every(cfg: &Self::Config) -> usize;

    /// [`Self::Config`] from TOML text over the defaults (not yet validated: the algorithm's
    /// own settings, [`Self::configure`], come first).
    fn read_config(text: &str) -> Result<Self::Config> {
        crate::io::from_toml_over_defaults::<Self::Config>(text)
            .map_err(|e| Error::Config(e.message().to_string()))
    }

    /// A fresh run; `expert` only where [`Algo::needs_expert`].
    fn start(cfg: Self::Config, data: MetaData, expert: Option<ExpertSet>) -> Result<Self>;

    /// The run checkpointed in `dir`, taking the [`Self::RESUMABLE`] keys from `wanted` (a
    /// larger budget, say) and everything else from the checkpoint.
    fn resume_from(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        wanted: &Self::Config,
    ) -> Result<Self>;

    /// The configuration it runs with.
    fn settings(&self) -> &Self::Config;

    /// The budget (update pairs or gradient steps).
    fn total(&self) -> u64;

    /// Updates done.
    fn done(&self) -> u64;

    /// Trains in `dir` to the budget or the learner's own stopping rule, keeping the best
    /// held-out policy in `dir/meta_policy.safetensors` and the last in `dir/last/`.
    fn run(&mut self, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()>;

    /// The current policy.
    fn policy(&self) -> MetaPolicy;
}
