//! The settings a caller gives over a configuration file, by name: what an error about one
//! says (kept below the error type and the learners, which both name them).

/// One field of [`Overrides`](crate::Overrides), as an error names it: the caller says which of its own inputs
/// (a flag, a sweep's extension) gave it, with an exhaustive `match` (not `non_exhaustive` on
/// purpose: a new setting must be given a flag where one is named), and no configuration key
/// travels as a string.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Setting {
    /// [`crate::Overrides::updates`].
    Updates,
    /// [`crate::Overrides::cpu_budget_s`].
    CpuBudget,
    /// [`crate::Overrides::seed`].
    Seed,
    /// [`crate::Overrides::learner_threads`].
    LearnerThreads,
    /// [`crate::Overrides::eval_every`].
    EvalEvery,
    /// [`crate::Overrides::hidden`].
    Hidden,
    /// [`crate::Overrides::gp_weight`].
    GpWeight,
    /// [`crate::Overrides::reward_scale`].
    RewardScale,
    /// [`crate::Overrides::bc_weight`].
    BcWeight,
    /// [`crate::Overrides::physics`].
    Physics,
    /// [`crate::Overrides::sensing`].
    Sensing,
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // The field's name in `Overrides`.
        let name = match self {
            Setting::Updates => "updates",
            Setting::CpuBudget => "cpu_budget_s",
            Setting::Seed => "seed",
            Setting::LearnerThreads => "learner_threads",
            Setting::EvalEvery => "eval_every",
            Setting::Hidden => "hidden",
            Setting::GpWeight => "gp_weight",
            Setting::RewardScale => "reward_scale",
            Setting::BcWeight => "bc_weight",
            Setting::Physics => "physics",
            Setting::Sensing => "sensing",
        };
        f.write_str(name)
    }
}
