//! The settings a caller gives over a meta-learner's configuration file, typed.
//!
//! A run's configuration is its algorithm's defaults, under a TOML file, under a list of
//! [`Setting`]s: the command line and a sweep's extension of a cell give one.
//! Each learner writes a setting into its own configuration
//! ([`MetaSettings::set`](crate::MetaSettings::set), an exhaustive `match`: a new setting does
//! not compile until every learner takes or refuses it), and one it has not is refused by name
//! and position ([`Error::NoSuchSetting`](crate::Error::NoSuchSetting)). No configuration key
//! travels as a string between the application and this library.

use sim::Physics;

use crate::data::Sensing;

/// One setting over a configuration file, with its value.
#[derive(Debug, Clone, PartialEq)]
pub enum Setting {
    /// The training budget: SMILe's update pairs (`total_updates`), Meta-BC's gradient steps
    /// (`total_steps`).
    Updates(u64),
    /// SMILe: the compute budget in CPU-seconds (`cpu_budget_s`; 0: none).
    CpuBudget(f64),
    /// The seed (`seed`).
    Seed(u64),
    /// The learner's threads (`learner_threads`).
    LearnerThreads(usize),
    /// Held-out evaluation every this many updates (`eval_every`; 0: never).
    EvalEvery(u64),
    /// Hidden widths of every network the learner trains: SMILe's SAC and discriminator
    /// (`sac.hidden`, `disc_hidden`), Meta-BC's policy (`policy_hidden`).
    Hidden(Vec<usize>),
    /// SMILe: the discriminator's gradient-penalty weight (`gp_weight`).
    GpWeight(f32),
    /// SMILe: SAC's reward scale (`sac.reward_scale`).
    RewardScale(f32),
    /// SMILe + BC: the cloning term's weight on SAC's actor loss (`bc_weight`).
    BcWeight(f32),
    /// The plant (`physics`).
    Physics(Physics),
    /// Train through the device's senses (`[sensing]`): SMILe's rollouts and actor, Meta-BC's
    /// batches and Meta-DAgger's rollouts.
    Sensing(Sensing),
}

impl Setting {
    /// Its name in errors.
    pub fn name(&self) -> &'static str {
        match self {
            Setting::Updates(_) => "updates",
            Setting::CpuBudget(_) => "cpu_budget_s",
            Setting::Seed(_) => "seed",
            Setting::LearnerThreads(_) => "learner_threads",
            Setting::EvalEvery(_) => "eval_every",
            Setting::Hidden(_) => "hidden",
            Setting::GpWeight(_) => "gp_weight",
            Setting::RewardScale(_) => "reward_scale",
            Setting::BcWeight(_) => "bc_weight",
            Setting::Physics(_) => "physics",
            Setting::Sensing(_) => "sensing",
        }
    }

    /// Whether it is part of the training budget: what a resume may change.
    pub fn is_budget(&self) -> bool {
        matches!(self, Setting::Updates(_) | Setting::CpuBudget(_))
    }
}
