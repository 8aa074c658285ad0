//! Which learner type trains each [`Algo`]: the one `match` a new algorithm adds its arm to,
//! and what the run driver and a sweep plan ask of an algorithm through it (a run, a
//! configuration's check, the extension of a finished cell).

use std::cmp::Ordering;

use sim::Family;

use super::{Run, RunEvent};
use crate::algo::meta_bc::MetaBc;
use crate::algo::smile::Smile;
use crate::algo::{Algo, Learner, MetaInputs, MetaSettings, Setting, Unit};
use crate::error::{Error, Result};

/// One meta-learner type's part in the driver and in sweeps: plain functions and its unit.
pub(super) struct Meta {
    /// Trains a run with this learner type ([`Run::train`]).
    pub train: fn(&Run<'_>, &mut dyn FnMut(RunEvent)) -> Result<()>,
    /// What its budget counts.
    pub unit: Unit,
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
            unit: L::UNIT,
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
    let table = text.parse::<toml::Table>().unwrap_or_default();
    if let Some(env) = other_env(&table, family) {
        return Err(Error::Config(format!(
            "env = {env} contradicts the plan's family {family}"
        )));
    }
    let mut cfg: C = crate::io::from_toml_over_defaults(text)
        .map_err(|e| Error::Config(e.message().to_string()))?;
    cfg.configure(algo, family);
    cfg.validate()
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

/// The `env` a configuration table names when it is not `family`: the family comes from the
/// demos (or the plan), and [`MetaSettings::configure`] would overwrite another one silently.
pub(super) fn other_env(table: &toml::Table, family: Family) -> Option<&toml::Value> {
    table
        .get("env")
        .filter(|env| env.as_str() != Some(family.name()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_lists_every_algorithm_once() {
        // Exhaustive: a new variant does not compile until it has a place here (the next
        // number, and `LAST` moves to it); then this test fails until `Algo::ALL` lists it.
        let place = |a: Algo| match a {
            Algo::Smile => 0,
            Algo::SmileStateOnly => 1,
            Algo::MetaBc => 2,
            Algo::MetaDagger => 3,
        };
        let mut seen: Vec<usize> = Algo::ALL.iter().map(|&a| place(a)).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..Algo::ALL.len()).collect::<Vec<_>>());
        const LAST: Algo = Algo::MetaDagger;
        assert_eq!(Algo::ALL.len(), 1 + place(LAST));
    }

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
    fn a_raised_budget_extends_a_smile_run_and_nothing_else_does() {
        let full = |extra: &str| {
            let mut t = toml::Table::try_from(crate::algo::smile::SmileConfig::default()).unwrap();
            for (k, v) in extra.parse::<toml::Table>().unwrap() {
                t.insert(k, v);
            }
            t.to_string()
        };
        let e = |old: &str, new: &str| Algo::Smile.extension(&full(old), &full(new));
        let raised = e("total_updates = 10", "total_updates = 20").unwrap();
        assert_eq!(raised[0], Setting::Updates(20));
        // 0 CPU-seconds is no budget: unlimited, so 10 -> 0 raises it.
        let cpu = |u: u64, c: f64| format!("total_updates = {u}\ncpu_budget_s = {c:?}");
        assert!(e(&cpu(10, 10.0), &cpu(10, 0.0)).is_some());
        assert!(e(&cpu(10, 10.0), &cpu(10, 20.0)).is_some());
        // One part up and one down, nothing up, or another setting changed: a new run.
        assert!(e(&cpu(10, 20.0), &cpu(20, 10.0)).is_none());
        assert!(e(&cpu(10, 0.0), &cpu(20, 10.0)).is_none());
        assert!(e("total_updates = 10", "total_updates = 10").is_none());
        assert!(e("total_updates = 20", "total_updates = 10").is_none());
        assert!(e("total_updates = 10", "total_updates = 20\nseed = 3").is_none());
        // Meta-BC's larger budget is another early-stopping selection, a new run.
        let bc = |steps: u64| {
            let mut t =
                toml::Table::try_from(crate::algo::meta_bc::MetaBcConfig::default()).unwrap();
            t.insert("total_steps".into(), toml::Value::Integer(steps as i64));
            t.to_string()
        };
        assert!(Algo::MetaBc.extension(&bc(10), &bc(20)).is_none());
    }

    #[test]
    fn configs_are_checked_against_their_algorithm() {
        let pg = Family::POINT_GOAL;
        Algo::Smile.check_config("gp_weight = 10.0", pg).unwrap();
        // Counts a flag refuses are refused from a file too (issue 57, item 7), and so is a
        // family the plan does not run.
        for bad in ["total_updates = 0", "horizon = 0", "rollouts_per_iter = 0"] {
            let e = Algo::Smile.check_config(bad, pg).unwrap_err().to_string();
            assert!(e.contains(bad.split(' ').next().unwrap()), "{e}");
        }
        assert!(Algo::MetaBc.check_config("total_steps = 0", pg).is_err());
        assert!(
            Algo::MetaBc
                .check_config("env = \"cheetah-vel\"", pg)
                .is_err()
        );
        Algo::MetaBc
            .check_config("env = \"point-goal\"", pg)
            .unwrap();
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
