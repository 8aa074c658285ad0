//! Typed settings over a configuration file (`trainer::Setting`): each learner lays them over
//! its own configuration, and refuses by name and position a setting it does not have.

use trainer::meta_bc::MetaBcConfig;
use trainer::smile::SmileConfig;
use trainer::{Algo, Error, MetaSettings, Setting};

#[test]
fn settings_lie_over_the_file_which_lies_over_the_defaults() {
    let mut c: SmileConfig =
        trainer::from_toml_over_defaults("seed = 3\n[sac]\nreward_scale = 2.0\n").unwrap();
    let given = [Setting::Seed(7), Setting::Hidden(vec![64])];
    c.apply(Algo::Smile, &given).unwrap();
    let mut want = SmileConfig::default();
    (want.seed, want.sac.reward_scale) = (7, 2.0);
    (want.sac.hidden, want.disc_hidden) = (vec![64], vec![64]);
    assert_eq!(c, want);
    // Nothing given: the file's configuration, untouched.
    let before = c.clone();
    c.apply(Algo::Smile, &[]).unwrap();
    assert_eq!(c, before);
}

#[test]
fn a_setting_the_algorithm_lacks_is_refused_by_name_and_changes_nothing() {
    let mut c = MetaBcConfig::default();
    let given = [Setting::Updates(5), Setting::BcWeight(1.0)];
    let e = c.apply(Algo::MetaBc, &given).unwrap_err();
    assert!(
        matches!(
            e,
            Error::NoSuchSetting {
                name: "bc_weight",
                at: 1,
                algo: "meta-bc"
            }
        ),
        "{e}"
    );
    // Refused: the budget given before it did not land either.
    assert_eq!(c, MetaBcConfig::default());
    // The budget is Meta-BC's gradient steps.
    c.apply(Algo::MetaBc, &[Setting::Updates(5)]).unwrap();
    assert_eq!(c.total_steps, 5);
}
