//! Typed settings over a configuration file (`trainer::Setting`): each learner lays them over
//! its own configuration, and refuses by name and position a setting it does not have; the
//! algorithms' names, a plan's configuration check and a sweep's extension of a finished cell.

use sim::Family;
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
        let mut t = toml::Table::try_from(SmileConfig::default()).unwrap();
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
        let mut t = toml::Table::try_from(MetaBcConfig::default()).unwrap();
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
    // A plan's table is generated: its errors say what is wrong, not at which line of it.
    let e = Algo::Smile.check_config("total_updates = \"x\"", pg);
    let e = e.unwrap_err().to_string();
    assert!(e.contains("invalid type") && !e.contains("line"), "{e}");
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
