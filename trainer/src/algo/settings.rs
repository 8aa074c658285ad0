//! Settings a caller gives over a meta-learner's configuration file, typed.
//!
//! A run's configuration is its algorithm's defaults, under a TOML file, under these: each
//! `Some` replaces the file's value, each `None` keeps it. The command line, a sweep's
//! extension of a cell and the quickstart fill an [`Overrides`]; each learner applies it to its
//! own configuration ([`MetaLearner::apply`](crate::MetaLearner::apply)) and refuses a setting
//! it does not have by name ([`Error::NoSuchSetting`](crate::Error::NoSuchSetting)). No configuration key travels as a
//! string between the application and this library.

use sim::Physics;

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

impl Overrides {
    /// The settings given (`Some`) other than the budget: what a resume may not change.
    pub(crate) fn given_beyond_budget(&self) -> Box<[Setting]> {
        let Overrides {
            updates: _,
            cpu_budget_s: _,
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
        [
            (seed.is_some(), Setting::Seed),
            (learner_threads.is_some(), Setting::LearnerThreads),
            (eval_every.is_some(), Setting::EvalEvery),
            (hidden.is_some(), Setting::Hidden),
            (gp_weight.is_some(), Setting::GpWeight),
            (reward_scale.is_some(), Setting::RewardScale),
            (bc_weight.is_some(), Setting::BcWeight),
            (physics.is_some(), Setting::Physics),
            (sensing.is_some(), Setting::Sensing),
        ]
        .into_iter()
        .filter_map(|(given, s)| given.then_some(s))
        .collect()
    }

    /// Writes `value` into `field` when it is given.
    pub(crate) fn set<T: Clone>(field: &mut T, value: &Option<T>) {
        if let Some(v) = value {
            *field = v.clone();
        }
    }

    /// Refuses `setting` when it is given (`value` is `Some`): `algo` has no such setting.
    pub(crate) fn refuse<T>(
        setting: Setting,
        value: &Option<T>,
        algo: &'static str,
    ) -> crate::error::Result<()> {
        match value {
            Some(_) => Err(crate::error::Error::NoSuchSetting { setting, algo }),
            None => Ok(()),
        }
    }
}
