//! One interface for the meta-learners: [`Algo`] names them, [`MetaLearner`] is what each one
//! implements, [`Progress`] is what each reports while it trains.
//!
//! `smile train`, the quickstart and `smile sweep` drive every learner through these, so adding
//! an algorithm is its folder under `algo/`, an arm of [`Algo`] (the compiler then lists every
//! `match` that must learn it) and an `impl MetaLearner`.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::Serialize;
use serde::de::DeserializeOwned;
use sim::Family;

pub use crate::algo::fit::Progress;

use crate::algo::expert::ExpertSet;
use crate::algo::meta_bc::{MetaBc, MetaBcConfig};
use crate::algo::smile::{Smile, SmileConfig};
use crate::data::MetaData;
use crate::error::{Error, Result};
use crate::model::MetaPolicy;

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

/// The registry: per algorithm its name, whether it needs an expert, and (in
/// [`Algo::with_learner`]) the learner type that runs it. Adding an algorithm is a variant, a
/// line here and an arm there; the compiler lists nothing else to change.
const REGISTRY: [(Algo, &str, bool); 4] = [
    // (algorithm, name on the command line and in plans, queries an expert while training)
    (Algo::Smile, "smile", false),
    (Algo::SmileStateOnly, "smile-state-only", false),
    (Algo::MetaBc, "meta-bc", false),
    (Algo::MetaDagger, "meta-dagger", true),
];

/// A computation generic over the learner type, run for an [`Algo`] by
/// [`Algo::with_learner`]: how code that serves every algorithm (a run directory, a plan
/// check) reaches the algorithm's [`MetaLearner`] without naming it.
pub trait WithLearner {
    /// What it returns.
    type Output;
    /// Runs it with `L`, the learner of `algo`.
    fn call<L: MetaLearner>(self, algo: Algo) -> Self::Output;
}

impl Algo {
    /// Every algorithm, in the order help texts list them.
    pub const ALL: [Algo; 4] = [REGISTRY[0].0, REGISTRY[1].0, REGISTRY[2].0, REGISTRY[3].0];

    fn entry(self) -> &'static (Algo, &'static str, bool) {
        REGISTRY
            .iter()
            .find(|e| e.0 == self)
            .expect("every algorithm has its registry line")
    }

    /// The name on the command line and in plans and run directories.
    pub fn name(self) -> &'static str {
        self.entry().1
    }

    /// Whether training queries an expert (Meta-DAgger relabels the states it visits).
    pub fn needs_expert(self) -> bool {
        self.entry().2
    }

    /// Runs `f` with the learner type of this algorithm: the one place mapping an algorithm
    /// to the type that trains it.
    pub fn with_learner<F: WithLearner>(self, f: F) -> F::Output {
        match self {
            Algo::Smile | Algo::SmileStateOnly => f.call::<Smile>(self),
            Algo::MetaBc | Algo::MetaDagger => f.call::<MetaBc>(self),
        }
    }

    /// The config key holding this algorithm's training budget ([`MetaLearner::TOTAL_KEY`]).
    pub fn budget_key(self) -> &'static str {
        struct Key;
        impl WithLearner for Key {
            type Output = &'static str;
            fn call<L: MetaLearner>(self, _: Algo) -> &'static str {
                L::TOTAL_KEY
            }
        }
        self.with_learner(Key)
    }

    /// Reads `text` (TOML over the algorithm's defaults) as this algorithm's configuration on
    /// `family`, with what the algorithm itself sets ([`MetaLearner::configure`]), and
    /// validates it: what a sweep plan checks before it runs anything.
    pub fn check_config(self, text: &str, family: Family) -> Result<()> {
        struct Check<'a>(&'a str, Family);
        impl WithLearner for Check<'_> {
            type Output = Result<()>;
            fn call<L: MetaLearner>(self, algo: Algo) -> Result<()> {
                let mut cfg = L::read_config(self.0)?;
                L::configure(&mut cfg, algo, self.1);
                L::validate(&cfg)
            }
        }
        self.with_learner(Check(text, family))
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

    /// The config key holding the training budget (`--updates` sets it).
    const TOTAL_KEY: &'static str;

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

impl MetaLearner for Smile {
    type Config = SmileConfig;
    const TOTAL_KEY: &'static str = "total_updates";
    const STEP_NAME: &'static str = "update pairs";
    const STEP_WORD: &'static str = "update";
    const RESUMABLE: &'static [&'static str] = &["total_updates", "cpu_budget_s"];

    fn configure(cfg: &mut SmileConfig, algo: Algo, family: Family) {
        cfg.env = family;
        cfg.context.state_only = algo == Algo::SmileStateOnly;
    }

    fn validate(cfg: &SmileConfig) -> Result<()> {
        cfg.validate()
    }

    fn holdout_every(cfg: &SmileConfig) -> usize {
        cfg.holdout_every
    }

    fn start(cfg: SmileConfig, data: MetaData, expert: Option<ExpertSet>) -> Result<Self> {
        refuse_expert(cfg.algo_name(), expert.is_some())?;
        Smile::new(cfg, data)
    }

    fn resume_from(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        wanted: &SmileConfig,
    ) -> Result<Self> {
        refuse_expert("smile", expert.is_some())?;
        let mut run = Smile::resume(dir, data, Some(wanted.total_updates))?;
        run.set_cpu_budget(wanted.cpu_budget_s)?;
        Ok(run)
    }

    fn settings(&self) -> &SmileConfig {
        self.config()
    }

    fn total(&self) -> u64 {
        self.config().total_updates
    }

    fn done(&self) -> u64 {
        self.updates()
    }

    fn run(&mut self, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
        crate::algo::smile::train(self, dir, on)
    }

    fn policy(&self) -> MetaPolicy {
        self.meta_policy()
    }
}

impl MetaLearner for MetaBc {
    type Config = MetaBcConfig;
    const TOTAL_KEY: &'static str = "total_steps";
    const STEP_NAME: &'static str = "steps";
    const STEP_WORD: &'static str = "step";
    const RESUMABLE: &'static [&'static str] = &["total_steps"];

    fn configure(cfg: &mut MetaBcConfig, algo: Algo, family: Family) {
        cfg.env = family;
        cfg.dagger = algo == Algo::MetaDagger;
    }

    fn validate(cfg: &MetaBcConfig) -> Result<()> {
        cfg.validate()
    }

    fn holdout_every(cfg: &MetaBcConfig) -> usize {
        cfg.holdout_every
    }

    fn start(cfg: MetaBcConfig, data: MetaData, expert: Option<ExpertSet>) -> Result<Self> {
        MetaBc::new(cfg, data, expert)
    }

    fn resume_from(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        wanted: &MetaBcConfig,
    ) -> Result<Self> {
        MetaBc::resume(dir, data, expert, Some(wanted.total_steps))
    }

    fn settings(&self) -> &MetaBcConfig {
        self.config()
    }

    fn total(&self) -> u64 {
        self.config().total_steps
    }

    fn done(&self) -> u64 {
        self.steps()
    }

    fn run(&mut self, dir: &Path, on: &mut dyn FnMut(Progress)) -> Result<()> {
        crate::algo::meta_bc::train(self, dir, on)
    }

    fn policy(&self) -> MetaPolicy {
        self.meta_policy()
    }
}

fn refuse_expert(algo: &str, given: bool) -> Result<()> {
    if given {
        return Err(Error::Config(format!(
            "{algo} learns from the demos alone and takes no expert (Meta-DAgger does)"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_ones_list_the_choices() {
        for a in Algo::ALL {
            assert_eq!(a.name().parse::<Algo>().unwrap(), a);
            assert_eq!(a.to_string(), a.name());
        }
        let e = "smiles".parse::<Algo>().unwrap_err().to_string();
        assert!(
            e.contains("smile-state-only") && e.contains("meta-dagger"),
            "{e}"
        );
    }

    #[test]
    fn configs_are_checked_against_their_algorithm() {
        let pg = Family::PointGoal;
        Algo::Smile.check_config("gp_weight = 10.0", pg).unwrap();
        // A SMILe key is unknown to Meta-BC, and an invalid value is refused by its own type.
        assert!(Algo::MetaBc.check_config("gp_weight = 10.0", pg).is_err());
        assert!(Algo::Smile.check_config("gp_weight = -1.0", pg).is_err());
        Algo::MetaDagger
            .check_config("total_steps = 10", pg)
            .unwrap();
        // What the algorithm sets is checked too: state-only SMILe has no actions to clone.
        Algo::Smile.check_config("bc_weight = 1.0", pg).unwrap();
        assert!(
            Algo::SmileStateOnly
                .check_config("bc_weight = 1.0", pg)
                .is_err()
        );
    }
}
