//! Settings a caller gives over a meta-learner's configuration file, typed.
//!
//! A run's configuration is its algorithm's defaults, under a TOML file, under these: each
//! `Some` replaces the file's value, each `None` keeps it. The command line, a sweep's
//! extension of a cell and the quickstart fill an [`Overrides`]; each learner applies it to its
//! own configuration through its [`Slots`] ([`MetaSettings::apply`](crate::MetaSettings::apply)),
//! and a setting it has no slot for is refused by name
//! ([`Error::NoSuchSetting`](crate::Error::NoSuchSetting)). No configuration key travels as a
//! string between the application and this library.

use sim::Physics;

use crate::error::{Error, Result};
use crate::setting::Setting;

/// Typed settings over a configuration file; `None` keeps the file's value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// The training budget: SMILe's update pairs (`total_updates`), Meta-BC's gradient steps
    /// (`total_steps`).
    pub updates: Option<u64>,
    /// SMILe: the compute budget in CPU-seconds (`cpu_budget_s`; 0: none).
    pub cpu_budget_s: Option<f64>,
    /// The seed (`seed`).
    pub seed: Option<u64>,
    /// The learner's threads (`learner_threads`).
    pub learner_threads: Option<usize>,
    /// Held-out evaluation every this many updates (`eval_every`; 0: never).
    pub eval_every: Option<u64>,
    /// Hidden widths of every network the learner trains: SMILe's SAC and discriminator
    /// (`sac.hidden`, `disc_hidden`), Meta-BC's policy (`policy_hidden`).
    pub hidden: Option<Vec<usize>>,
    /// SMILe: the discriminator's gradient-penalty weight (`gp_weight`).
    pub gp_weight: Option<f32>,
    /// SMILe: SAC's reward scale (`sac.reward_scale`).
    pub reward_scale: Option<f32>,
    /// SMILe + BC: the cloning term's weight on SAC's actor loss (`bc_weight`).
    pub bc_weight: Option<f32>,
    /// The plant (`physics`).
    pub physics: Option<Physics>,
    /// Train through the device's senses (`[sensing]`): SMILe's rollouts and actor, Meta-BC's
    /// batches and Meta-DAgger's rollouts.
    pub sensing: Option<crate::data::Sensing>,
}

/// Where each setting of [`Overrides`] lands in one learner's configuration: a field to
/// write, or `None` where the learner has no such setting (given one, it is refused by name).
pub struct Slots<'a> {
    /// The training budget's count.
    pub updates: &'a mut u64,
    /// The compute budget in CPU-seconds.
    pub cpu_budget_s: Option<&'a mut f64>,
    /// The seed.
    pub seed: &'a mut u64,
    /// The learner's threads.
    pub learner_threads: &'a mut usize,
    /// The held-out evaluation's period.
    pub eval_every: &'a mut u64,
    /// Every network's hidden widths.
    pub hidden: Vec<&'a mut Vec<usize>>,
    /// The gradient-penalty weight.
    pub gp_weight: Option<&'a mut f32>,
    /// SAC's reward scale.
    pub reward_scale: Option<&'a mut f32>,
    /// SMILe + BC's cloning weight.
    pub bc_weight: Option<&'a mut f32>,
    /// The plant.
    pub physics: &'a mut Physics,
    /// The device's senses.
    pub sensing: &'a mut Option<crate::data::Sensing>,
}

impl Overrides {
    /// Lays these settings over a configuration through its `slots`; a setting given to a
    /// learner without its slot is refused by name (for `algo`), and then nothing changes.
    pub(crate) fn apply_to(&self, slots: Slots<'_>, algo: &'static str) -> Result<()> {
        // Every field named: a setting added to `Overrides` does not compile until it has a slot.
        let Overrides {
            updates,
            cpu_budget_s,
            seed,
            learner_threads,
            eval_every,
            hidden,
            gp_weight,
            reward_scale,
            bc_weight,
            physics,
            sensing,
        } = self;
        // The optional slots first: a refusal changes nothing.
        let cpu = optional(slots.cpu_budget_s, cpu_budget_s, Setting::CpuBudget, algo)?;
        let gp = optional(slots.gp_weight, gp_weight, Setting::GpWeight, algo)?;
        let rs = optional(slots.reward_scale, reward_scale, Setting::RewardScale, algo)?;
        let bc = optional(slots.bc_weight, bc_weight, Setting::BcWeight, algo)?;
        set(cpu, cpu_budget_s);
        set(Some(slots.updates), updates);
        set(Some(slots.seed), seed);
        set(Some(slots.learner_threads), learner_threads);
        set(Some(slots.eval_every), eval_every);
        for h in slots.hidden {
            set(Some(h), hidden);
        }
        set(gp, gp_weight);
        set(rs, reward_scale);
        set(bc, bc_weight);
        set(Some(slots.physics), physics);
        if sensing.is_some() {
            *slots.sensing = *sensing;
        }
        Ok(())
    }

    /// The settings given (`Some`) other than the budget: what a resume may not change.
    pub(crate) fn given_beyond_budget(&self) -> Vec<Setting> {
        const BEYOND_BUDGET: [Setting; 9] = [
            Setting::Seed,
            Setting::LearnerThreads,
            Setting::EvalEvery,
            Setting::Hidden,
            Setting::GpWeight,
            Setting::RewardScale,
            Setting::BcWeight,
            Setting::Physics,
            Setting::Sensing,
        ];
        let given = |s: &Setting| self.only(*s) != Overrides::default();
        BEYOND_BUDGET.into_iter().filter(given).collect()
    }

    /// This setting alone, as given here.
    pub(crate) fn only(&self, s: Setting) -> Overrides {
        let (mut o, x) = (Overrides::default(), self.clone());
        match s {
            Setting::Updates => o.updates = x.updates,
            Setting::CpuBudget => o.cpu_budget_s = x.cpu_budget_s,
            Setting::Seed => o.seed = x.seed,
            Setting::LearnerThreads => o.learner_threads = x.learner_threads,
            Setting::EvalEvery => o.eval_every = x.eval_every,
            Setting::Hidden => o.hidden = x.hidden,
            Setting::GpWeight => o.gp_weight = x.gp_weight,
            Setting::RewardScale => o.reward_scale = x.reward_scale,
            Setting::BcWeight => o.bc_weight = x.bc_weight,
            Setting::Physics => o.physics = x.physics,
            Setting::Sensing => o.sensing = x.sensing,
        }
        o
    }
}

/// The slot for `value`: none when no value is given; a value given to a learner without
/// the slot is refused ([`Error::NoSuchSetting`]).
fn optional<'a, T>(
    slot: Option<&'a mut T>,
    value: &Option<T>,
    setting: Setting,
    algo: &'static str,
) -> Result<Option<&'a mut T>> {
    match (slot, value) {
        (_, None) => Ok(None),
        (None, Some(_)) => Err(Error::NoSuchSetting { setting, algo }),
        (slot, Some(_)) => Ok(slot),
    }
}

/// Writes `value` into `slot` when both are there.
fn set<T: Clone>(slot: Option<&mut T>, value: &Option<T>) {
    if let (Some(slot), Some(v)) = (slot, value) {
        *slot = v.clone();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every setting but the budget is named when given, and the budget is not. A new field
    /// of `Overrides` does not compile here until it is given below; its setting must then be
    /// added to `BEYOND_BUDGET` and the count here by hand (`only`'s match holds the rest).
    #[test]
    fn every_setting_beyond_the_budget_is_named_when_given() {
        let all = Overrides {
            updates: Some(1),
            cpu_budget_s: Some(1.0),
            seed: Some(1),
            learner_threads: Some(1),
            eval_every: Some(1),
            hidden: Some(vec![1]),
            gp_weight: Some(1.0),
            reward_scale: Some(1.0),
            bc_weight: Some(1.0),
            physics: Some(Physics::Rapier),
            sensing: Some(crate::data::Sensing::default()),
        };
        let named = all.given_beyond_budget();
        assert_eq!(named.len(), 9, "{named:?}");
        assert!(!named.contains(&Setting::Updates) && !named.contains(&Setting::CpuBudget));
        assert!(Overrides::default().given_beyond_budget().is_empty());
    }
}
