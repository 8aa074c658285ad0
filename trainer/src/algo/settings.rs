//! Settings a caller gives over a meta-learner's configuration file, typed.
//!
//! A run's configuration is its algorithm's defaults, under a TOML file, under these: each
//! `Some` replaces the file's value, each `None` keeps it. The command line, a sweep's
//! extension of a cell and the quickstart fill an [`Overrides`]; each learner applies it to its
//! own configuration ([`MetaLearner::apply`](crate::MetaLearner::apply)) and refuses a setting
//! it does not have by name ([`Error::NoSuchSetting`]). No configuration key travels as a
//! string between the application and this library.

use sim::Physics;

use crate::algo::learner::Algo;
use crate::error::{Error, Result};

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
}

impl Overrides {
    /// Writes `value` into `field` when it is given.
    pub(crate) fn set<T: Clone>(field: &mut T, value: &Option<T>) {
        if let Some(v) = value {
            *field = v.clone();
        }
    }

    /// Refuses the settings in `given` (`(config key, whether given)`) that `algo` does not
    /// have, naming the first.
    pub(crate) fn refuse(algo: Algo, given: &[(&'static str, bool)]) -> Result<()> {
        match given.iter().find(|(_, g)| *g) {
            Some((key, _)) => Err(Error::NoSuchSetting { key, algo }),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::learner::MetaLearner;
    use crate::algo::meta_bc::{MetaBc, MetaBcConfig};
    use crate::algo::smile::{Smile, SmileConfig};

    #[test]
    fn settings_lie_over_the_file_which_lies_over_the_defaults() {
        let mut c: SmileConfig =
            crate::io::from_toml_over_defaults("seed = 3\n[sac]\nreward_scale = 2.0\n").unwrap();
        let o = Overrides {
            seed: Some(7),
            hidden: Some(vec![64]),
            ..Overrides::default()
        };
        Smile::apply(&mut c, Algo::Smile, &o).unwrap();
        let mut want = SmileConfig::default();
        (want.seed, want.sac.reward_scale) = (7, 2.0);
        (want.sac.hidden, want.disc_hidden) = (vec![64], vec![64]);
        assert_eq!(c, want);
        // Nothing given: the file's configuration, untouched.
        let before = c.clone();
        Smile::apply(&mut c, Algo::Smile, &Overrides::default()).unwrap();
        assert_eq!(c, before);
    }

    #[test]
    fn a_setting_the_algorithm_lacks_is_refused_by_name_and_changes_nothing() {
        let mut c = MetaBcConfig::default();
        let o = Overrides {
            updates: Some(5),
            bc_weight: Some(1.0),
            ..Overrides::default()
        };
        let e = MetaBc::apply(&mut c, Algo::MetaBc, &o).unwrap_err();
        assert!(
            matches!(
                e,
                Error::NoSuchSetting {
                    key: "bc_weight",
                    algo: Algo::MetaBc
                }
            ),
            "{e}"
        );
        assert_eq!(c, MetaBcConfig::default());
        // The budget is Meta-BC's gradient steps.
        let o = Overrides {
            updates: Some(5),
            ..Overrides::default()
        };
        MetaBc::apply(&mut c, Algo::MetaBc, &o).unwrap();
        assert_eq!(c.total_steps, 5);
    }
}
