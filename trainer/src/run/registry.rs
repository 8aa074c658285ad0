//! Which learner type trains each [`Algo`]: the one `match` a new algorithm adds its arm to,
//! and what the run driver and a sweep plan ask of an algorithm through it (a run, a
//! configuration's check, the extension of a finished cell).

use std::cmp::Ordering;

use sim::Family;

use super::{Run, RunEvent};
use crate::algo::meta_bc::MetaBc;
use crate::algo::smile::Smile;
use crate::algo::{Algo, Learner, MetaInputs, MetaSettings, Setting};
use crate::error::{Error, Result};

/// One meta-learner type's part in the driver and in sweeps: plain functions.
pub(super) struct Meta {
    /// Trains a run with this learner type ([`Run::train`]).
    pub train: fn(&Run<'_>, &mut dyn FnMut(RunEvent)) -> Result<()>,
    check: fn(Algo, &str, Family) -> Result<()>,
    extension: fn(Algo, &str, &str) -> Option<Vec<Setting>>,
}

impl Meta {
    /// The learner type of `algo`: the one map from an algorithm to the type that trains it.
    pub fn of(algo: Algo) -> Self {
        match algo {
            Algo::Smile | Algo::SmileStateOnly => Self::by::<Smile>(),
            Algo::MetaBc | Algo::MetaDagger => Self::by::<MetaBc>(),
        }
    }

    fn by<L>() -> Self
    where
        L: Learner<Inputs = MetaInputs>,
        L::Config: MetaSettings,
    {
        Self {
            train: |run, on| run.train::<L>(on),
            check: check::<L::Config>,
            extension: extension::<L::Config>,
        }
    }
}

impl Algo {
    /// Reads `text` (TOML over the algorithm's defaults) as this algorithm's configuration on
    /// `family`, with what the algorithm itself sets ([`MetaSettings::configure`]), and
    /// validates it: what a sweep plan checks before it runs anything.
    pub fn check_config(self, text: &str, family: Family) -> Result<()> {
        (Meta::of(self).check)(self, text, family)
    }

    /// The settings that extend a run configured by `old` (a configuration's TOML text) to
    /// `new`: `Some` when `new` is `old` but for its budget, no part of the budget lower and
    /// one higher (a CPU-second budget of 0, none, counts as unlimited), else `None`. How a
    /// sweep continues a finished cell whose plan raised its budget.
    pub fn extension(self, old: &str, new: &str) -> Option<Vec<Setting>> {
        (Meta::of(self).extension)(self, old, new)
    }
}

fn check<C: MetaSettings>(algo: Algo, text: &str, family: Family) -> Result<()> {
    let on = format!("{family} (the plan's family)");
    let mut cfg: C = parse(text, None, &on, family)?;
    cfg.configure(algo, family);
    cfg.validate()
}

/// `text`, the configuration file `name`, over `C`'s defaults (`None`: a plan's table, whose
/// line numbers are not the plan's: its errors say what, not where). An `env` other than
/// `family` (the run's, as `on` says for a person) is refused: the family comes from the demos
/// or the plan, and [`MetaSettings::configure`] would overwrite another one silently.
pub(super) fn parse<C: MetaSettings>(
    text: &str,
    name: Option<&str>,
    on: &str,
    family: Family,
) -> Result<C> {
    let table = text.parse::<toml::Table>().unwrap_or_default();
    let env = table.get("env");
    if let Some(env) = env.filter(|e| e.as_str() != Some(family.name())) {
        let name = name.unwrap_or("the configuration");
        return Err(Error::Config(format!(
            "{name} sets env = {env} but the run is on {on}; remove the key, or train on {env} \
             demos"
        )));
    }
    crate::io::from_toml_over_defaults(text).map_err(|e| {
        Error::Config(match name {
            Some(name) => format!("parsing {name}: {e}"),
            None => e.message().to_string(),
        })
    })
}

fn extension<C: MetaSettings>(algo: Algo, old: &str, new: &str) -> Option<Vec<Setting>> {
    if !C::EXTENDS {
        return None;
    }
    let old: C = toml::from_str(old).ok()?;
    let new: C = toml::from_str(new).ok()?;
    let (was, now) = (old.budget(), new.budget());
    let mut same = old.clone();
    same.apply(algo, &now).ok()?;
    // Part by part (one type's budget: the same parts in the same order); a CPU-second budget
    // of 0 (none) is unlimited.
    let unlimited = |c: f64| if c > 0.0 { c } else { f64::INFINITY };
    let order = |(w, n): (&Setting, &Setting)| match (w, n) {
        (Setting::Updates(w), Setting::Updates(n)) => Some(n.cmp(w)),
        (Setting::CpuBudget(w), Setting::CpuBudget(n)) => unlimited(*n).partial_cmp(&unlimited(*w)),
        _ => None,
    };
    let parts: Vec<Ordering> = was.iter().zip(&now).map(order).collect::<Option<_>>()?;
    let raised = parts.iter().all(|o| o.is_ge()) && parts.iter().any(|o| o.is_gt());
    (same == new && raised).then_some(now)
}
