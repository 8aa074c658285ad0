//! Typed settings over a configuration file (`trainer::Overrides`): each learner lays them
//! over its own configuration, and refuses by name a setting it does not have.

use trainer::meta_bc::MetaBcConfig;
use trainer::smile::SmileConfig;
use trainer::{Algo, Error, MetaSettings, Overrides};

#[test]
fn settings_lie_over_the_file_which_lies_over_the_defaults() {
    let mut c: SmileConfig =
        trainer::from_toml_over_defaults("seed = 3\n[sac]\nreward_scale = 2.0\n").unwrap();
    let o = Overrides {
        seed: Some(7),
        hidden: Some(vec![64]),
        ..Overrides::default()
    };
    c.apply(Algo::Smile, &o).unwrap();
    let mut want = SmileConfig::default();
    (want.seed, want.sac.reward_scale) = (7, 2.0);
    (want.sac.hidden, want.disc_hidden) = (vec![64], vec![64]);
    assert_eq!(c, want);
    // Nothing given: the file's configuration, untouched.
    let before = c.clone();
    c.apply(Algo::Smile, &Overrides::default()).unwrap();
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
    let e = c.apply(Algo::MetaBc, &o).unwrap_err();
    assert!(
        matches!(
            e,
            Error::NoSuchSetting {
                setting: trainer::Setting::BcWeight,
                algo: "meta-bc"
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
    c.apply(Algo::MetaBc, &o).unwrap();
    assert_eq!(c.total_steps, 5);
}
