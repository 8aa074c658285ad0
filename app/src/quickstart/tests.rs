//! The quickstart's choice of expert, demos and horizon per family and budget.

use super::*;

#[test]
fn cheetah_starts_from_the_shipped_expert_at_the_papers_horizon() {
    let cheetah = QuickstartConfig {
        env: Family::CHEETAH_VEL,
        ..QuickstartConfig::default()
    };
    let dir = Quickstart::resolve(&cheetah)
        .unwrap()
        .shipped
        .expect("assets/experts/cheetah-vel is in the repository");
    assert!(dir.ends_with("assets/experts/cheetah-vel"));
    assert_eq!(
        Quickstart::resolve(&cheetah).unwrap().horizon(),
        None,
        "the family's 1000 steps"
    );
    check_budget(&Quickstart::resolve(&cheetah).unwrap()).unwrap();
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
        let other = Quickstart::resolve(&other).unwrap();
        assert_eq!(other.shipped, None);
        assert_eq!(other.horizon(), Some(200));
        let presets = other.presets().map(|(file, _)| file);
        assert_eq!(
            presets,
            ["cv-smile.toml", "cv-bc-roll.toml"],
            "200-step files"
        );
    }
    let no_assets = QuickstartConfig {
        assets: Some(PathBuf::from("/nonexistent")),
        ..cheetah
    };
    let err = check_budget(&Quickstart::resolve(&no_assets).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("no shipped one"), "{err}");
    assert_eq!(
        Quickstart::resolve(&QuickstartConfig::default())
            .unwrap()
            .shipped,
        None,
        "point-goal is scripted"
    );
}

#[test]
fn ant_linclass_starts_from_its_shipped_scripted_expert_and_16_demo_files() {
    let args = QuickstartConfig {
        env: Family::ANT_LINCLASS,
        ..QuickstartConfig::default()
    };
    let resolved = Quickstart::resolve(&args).unwrap();
    let dir = resolved
        .shipped
        .clone()
        .expect("assets/experts/ant-linclass is in the repository");
    assert!(dir.ends_with("assets/experts/ant-linclass"));
    let (train, test) = recipe(Family::ANT_LINCLASS).unwrap().shipped_demos;
    assert!(dir.join(train).exists() && dir.join(test).exists());
    let cfg = smile_config(&resolved).unwrap();
    assert_eq!((cfg.max_context, cfg.eval_context_size), (8, 4));
    check_budget(&resolved).unwrap();
    let out = std::env::temp_dir().join(format!("qs-alc-expert-{}", std::process::id()));
    let (expert, note) = train_expert(&resolved, &out).unwrap();
    assert_eq!(expert.name(), "scripted-linclass");
    assert!(note.contains("shipped scripted-linclass expert"), "{note}");
    // Without the shipped files the long budget would train SAC on a sparse reward: refused.
    let bare = QuickstartConfig {
        assets: Some(PathBuf::from("/nonexistent")),
        budget: Budget::Long,
        ..args
    };
    let err = check_budget(&Quickstart::resolve(&bare).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("scripted-linclass"), "{err}");
    std::fs::remove_dir_all(&out).ok();
}

/// The quickstart trains both learners with the configuration files behind each family's
/// RESULTS rows (docs/configs), read from disk here and compared field by field with what it
/// compiled in, plus only its own settings (family, seed, SMILe's two learner threads).
#[test]
fn its_configs_are_the_documented_files() {
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/configs");
    let read = |file: &str| std::fs::read_to_string(docs.join(file)).unwrap();
    for (family, smile_file, bc_file) in [
        (Family::POINT_GOAL, "pg-smile-2threads.toml", None),
        (
            Family::CHEETAH_VEL,
            "cv1000-smile.toml",
            Some("cv1000-bc-roll.toml"),
        ),
        (Family::WALKER_DYN, "wd-smile.toml", Some("wd-bc-roll.toml")),
        (
            Family::ANT_GOAL,
            "ag-smile-rs1.toml",
            Some("ag-bc-roll.toml"),
        ),
        (
            Family::ANT_LINCLASS,
            "alc-smile.toml",
            Some("alc-bc-roll.toml"),
        ),
    ] {
        let args = QuickstartConfig {
            env: family,
            seed: 5,
            ..QuickstartConfig::default()
        };
        let q = Quickstart::resolve(&args).unwrap();
        let mut want: SmileConfig = trainer::from_toml_over_defaults(&read(smile_file)).unwrap();
        (want.env, want.seed, want.learner_threads) = (family, 5, 2);
        assert_eq!(smile_config(&q).unwrap(), want, "{family} vs {smile_file}");
        let mut want: MetaBcConfig = match bc_file {
            Some(f) => trainer::from_toml_over_defaults(&read(f)).unwrap(),
            None => MetaBcConfig::default(),
        };
        (want.env, want.seed) = (family, 5);
        assert_eq!(meta_bc_config(&q).unwrap(), want, "{family} vs {bc_file:?}");
    }
    // The tiny budget shrinks what the file says, and nothing else.
    let tiny = QuickstartConfig {
        env: Family::ANT_GOAL,
        budget: Budget::Tiny,
        ..QuickstartConfig::default()
    };
    let cfg = smile_config(&Quickstart::resolve(&tiny).unwrap()).unwrap();
    assert_eq!(
        (cfg.total_updates, cfg.sac.hidden.clone()),
        (200, vec![32, 32])
    );
    assert_eq!(cfg.sac.reward_scale, 1.0, "ag-smile-rs1.toml's scale stays");
    // Point-goal's long budget doubles its file's update pairs; the other families' long
    // budget pays for their own expert, not for more SMILe.
    for (family, factor) in [(Family::POINT_GOAL, 2), (Family::ANT_GOAL, 1)] {
        let [short, long] = [Budget::Short, Budget::Long].map(|budget| {
            let args = QuickstartConfig {
                env: family,
                budget,
                ..QuickstartConfig::default()
            };
            smile_config(&Quickstart::resolve(&args).unwrap())
                .unwrap()
                .total_updates
        });
        assert_eq!(long, factor * short, "{family}");
    }
}

/// Issue 57, item 4: a quickstart over an earlier one removes the earlier results first, so a
/// run killed before writing its own never sits beside them looking complete; other files
/// (the stages' folders, which each stage replaces) are left to their stages.
#[test]
fn an_earlier_quickstarts_results_are_removed_before_a_new_one_starts() {
    let dir = std::env::temp_dir().join(format!("smile-qs-clear-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("device")).unwrap();
    for f in [
        "summary.json",
        "report.md",
        "eval.json",
        "policy.blob",
        "policy.blob.json",
    ] {
        std::fs::write(dir.join(f), "old").unwrap();
    }
    std::fs::write(dir.join("demos-train.safetensors"), "kept").unwrap();
    clear_results(&dir).unwrap();
    for f in RESULT_FILES {
        assert!(!dir.join(f).exists(), "{f} survived");
    }
    assert!(dir.join("demos-train.safetensors").exists());
    clear_results(&dir).unwrap();
    std::fs::remove_dir_all(&dir).ok();
}
