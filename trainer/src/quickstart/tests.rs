//! The quickstart's choice of expert, demos and horizon per family and budget.

use super::*;

#[test]
fn cheetah_starts_from_the_shipped_expert_at_the_papers_horizon() {
    let cheetah = QuickstartConfig {
        env: Family::CheetahVel,
        ..QuickstartConfig::default()
    };
    let dir = shipped(&cheetah).expect("assets/experts/cheetah-vel is in the repository");
    assert!(dir.ends_with("assets/experts/cheetah-vel"));
    assert_eq!(horizon(&cheetah), None, "the family's 1000 steps");
    check_budget(&cheetah).unwrap();
    // Elsewhere, or at the tiny budget, it trains its own expert on 200-step episodes.
    for other in [
        QuickstartConfig {
            assets: Some(PathBuf::from("/nonexistent")),
            ..cheetah.clone()
        },
        QuickstartConfig {
            budget: Budget::Tiny,
            ..cheetah.clone()
        },
    ] {
        assert_eq!(shipped(&other), None);
        assert_eq!(horizon(&other), Some(200));
    }
    let no_assets = QuickstartConfig {
        assets: Some(PathBuf::from("/nonexistent")),
        ..cheetah
    };
    let err = check_budget(&no_assets).unwrap_err().to_string();
    assert!(err.contains("no shipped one"), "{err}");
    assert_eq!(
        shipped(&QuickstartConfig::default()),
        None,
        "point-goal is scripted"
    );
}

#[test]
fn ant_linclass_starts_from_its_shipped_scripted_expert_and_16_demo_files() {
    let args = QuickstartConfig {
        env: Family::AntLinClass,
        ..QuickstartConfig::default()
    };
    let dir = shipped(&args).expect("assets/experts/ant-linclass is in the repository");
    assert!(dir.ends_with("assets/experts/ant-linclass"));
    let (train, test) = shipped_demos(Family::AntLinClass);
    assert!(dir.join(train).exists() && dir.join(test).exists());
    assert_eq!(context_sizes(Family::AntLinClass), Some((8, 4)));
    assert_eq!(context_sizes(Family::AntGoal), None);
    check_budget(&args).unwrap();
    let out = std::env::temp_dir().join(format!("qs-alc-expert-{}", std::process::id()));
    let (expert, note) = train_expert(&args, &out).unwrap();
    assert_eq!(expert.name(), "scripted-linclass");
    assert!(note.contains("shipped scripted-linclass expert"), "{note}");
    // Without the shipped files the long budget would train SAC on a sparse reward: refused.
    let bare = QuickstartConfig {
        assets: Some(PathBuf::from("/nonexistent")),
        budget: Budget::Long,
        ..args
    };
    let err = check_budget(&bare).unwrap_err().to_string();
    assert!(err.contains("scripted-linclass"), "{err}");
    std::fs::remove_dir_all(&out).ok();
}

/// The quickstart trains SMILe with the configuration behind each family's RESULTS row: the
/// TOML files in docs/configs, read back and compared field by field.
#[test]
fn smile_configs_are_the_documented_ones() {
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/configs");
    for (family, file) in [
        (Family::AntGoal, "ag-smile-rs1.toml"),
        (Family::AntLinClass, "alc-smile.toml"),
    ] {
        let args = QuickstartConfig {
            env: family,
            ..QuickstartConfig::default()
        };
        let mut want: SmileConfig =
            crate::from_toml_over_defaults(&std::fs::read_to_string(docs.join(file)).unwrap())
                .unwrap();
        // What the quickstart sets on top: the family, the seed, two learner threads.
        want.env = family;
        want.learner_threads = 2;
        assert_eq!(smile_config(&args), want, "{family} vs {file}");
    }
}
