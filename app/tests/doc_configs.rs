//! The configuration files that docs/RESULTS.md trains with still parse and validate.

use trainer::meta_bc::{MetaBcConfig, Selection};
use trainer::smile::SmileConfig;

fn read(name: &str) -> String {
    let path = format!("{}/../docs/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The narrow-width twins of the authors' presets (one per family) differ from them in the
/// widths alone (issue 32's width comparison is a one-factor one, and the grid runs the
/// winner), and in how often they evaluate.
#[test]
fn the_narrow_authors_presets_differ_only_in_width() {
    for (wide, narrow, sac, actor) in [
        (
            "authors-cv-smile.toml",
            "authors-cv-smile-narrow.toml",
            [128, 128],
            None,
        ),
        (
            "authors-wd-smile.toml",
            "authors-wd-smile-narrow.toml",
            [128, 128],
            None,
        ),
        (
            "authors-ag-smile.toml",
            "authors-ag-smile-narrow.toml",
            [256, 256],
            Some(vec![256, 256]),
        ),
        (
            "authors-alc-smile.toml",
            "authors-alc-smile-narrow.toml",
            [256, 256],
            Some(vec![256, 256]),
        ),
    ] {
        let wide: SmileConfig = toml::from_str(&read(wide)).unwrap();
        let mut narrow: SmileConfig = toml::from_str(&read(narrow)).unwrap();
        narrow.validate().unwrap();
        assert_eq!(narrow.disc_hidden, vec![128, 128]);
        assert_eq!(narrow.sac.hidden, sac.to_vec());
        assert_eq!(narrow.sac.actor_hidden, actor);
        assert_eq!((narrow.context.r_dim, narrow.context.z_dim), (32, 16));
        narrow.disc_hidden = wide.disc_hidden.clone();
        narrow.sac.hidden = wide.sac.hidden.clone();
        narrow.sac.actor_hidden = wide.sac.actor_hidden.clone();
        narrow.context = wide.context.clone();
        narrow.total_updates = wide.total_updates;
        narrow.eval_every = wide.eval_every;
        narrow.checkpoint_every = wide.checkpoint_every;
        assert_eq!(narrow, wide);
    }
}

#[test]
fn results_configs_parse_and_validate() {
    let smile: SmileConfig = toml::from_str(&read("cv-smile.toml")).unwrap();
    smile.validate().unwrap();
    assert_eq!((smile.total_updates, smile.horizon), (60_000, Some(200)));
    let smile: SmileConfig = toml::from_str(&read("cv1000-smile.toml")).unwrap();
    smile.validate().unwrap();
    assert_eq!((smile.total_updates, smile.horizon), (40_000, Some(1000)));
    for (name, select_by, horizon) in [
        ("cv-bc.toml", Selection::Mse, 200),
        ("cv-bc-roll.toml", Selection::Rollouts, 200),
        ("cv1000-bc.toml", Selection::Mse, 1000),
        ("cv1000-bc-roll.toml", Selection::Rollouts, 1000),
    ] {
        let bc: MetaBcConfig = toml::from_str(&read(name)).unwrap();
        bc.validate().unwrap();
        assert_eq!(
            (bc.select_by, bc.horizon),
            (select_by, Some(horizon)),
            "{name}"
        );
        assert_eq!(bc.context.enc_hidden, vec![128, 128], "{name}");
    }
}

/// The authors' presets (issue 32; docs/PRESETS.md): one per family, each with the values of
/// their spec that the table there lists.
#[test]
fn the_authors_presets_hold_their_recipe() {
    for (name, reward_scale, actor, max_context) in [
        ("authors-cv-smile.toml", 24.0, None, 4),
        ("authors-wd-smile.toml", 24.0, None, 4),
        ("authors-ag-smile.toml", 4.0, Some(vec![512; 3]), 4),
        ("authors-alc-smile.toml", 4.0, Some(vec![512; 3]), 8),
    ] {
        let c: SmileConfig = toml::from_str(&read(name)).unwrap();
        c.validate().unwrap();
        assert_eq!(c.disc_hidden, vec![512; 3], "{name}");
        assert_eq!((c.gp_weight, c.logit_clamp), (10.0, 10.0), "{name}");
        assert_eq!(
            (
                c.context.enc_hidden.clone(),
                c.context.r_dim,
                c.context.z_dim
            ),
            (vec![256, 256], 64, 64),
            "{name}"
        );
        assert_eq!(c.sac.hidden, vec![256; 3], "{name}");
        assert_eq!(c.sac.actor_hidden, actor, "{name}");
        assert!(!c.sac.learn_alpha && c.sac.init_alpha == 1.0, "{name}");
        assert_eq!(
            (c.sac.reward_scale, c.sac.policy_reg),
            (reward_scale, 1e-3),
            "{name}"
        );
        assert_eq!(
            (c.tasks_per_batch, c.sac_per_task, c.disc_per_task),
            (8, 128, 128),
            "{name}"
        );
        assert_eq!(
            (c.rollouts_per_iter, c.updates_per_iter, c.replay_per_task),
            (5, 100, 50_000),
            "{name}"
        );
        assert_eq!(c.max_context, max_context, "{name}");
        // The actor takes its own widths where the preset gives them; the critics keep theirs.
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
        let sac = trainer::sac::Sac::new(10, 2, c.sac.clone(), &mut rng).unwrap();
        let want = actor.unwrap_or(vec![256; 3]);
        assert_eq!(sac.actor.net().widths()[1..4], want[..], "{name}");
        assert_eq!(sac.q1.widths()[1..4], [256; 3], "{name}");
    }
}

/// The sensing preset (issue 73) is the device table's sensor column: noise 0.01, a 12-bit ADC
/// over +-10, and it checks.
#[test]
fn the_sensing_preset_is_the_device_tables_sensor_column() {
    #[derive(serde::Deserialize)]
    struct Preset {
        sensing: trainer::Sensing,
    }
    let p: Preset = toml::from_str(&read("sensing-noise01-adc12.toml")).unwrap();
    let s = p.sensing;
    assert_eq!(
        (s.noise_std, s.adc_bits, s.adc_range),
        (0.01, Some(12), 10.0)
    );
    s.check().unwrap();
    // The first robust Meta-BC's config carries the same sensor in its own section.
    let bc: MetaBcConfig = toml::from_str(&read("cv1000-bc-sensing.toml")).unwrap();
    assert_eq!(bc.sensing.unwrap().model(), s.model());
}

/// The position-sensing preset is the device table's "positions + estimator" column: ideal
/// readings of the measured entries, the estimator's range +-10, the family's tuning.
#[test]
fn the_position_sensing_preset_is_the_device_tables_position_column() {
    #[derive(serde::Deserialize)]
    struct Preset {
        sensing: trainer::Sensing,
    }
    let p: Preset = toml::from_str(&read("sensing-positions.toml")).unwrap();
    let s = p.sensing;
    s.check().unwrap();
    assert!(s.positions && s.model().is_ideal());
    assert_eq!((s.adc_range, s.accel_std, s.meas_std), (10.0, None, None));
}

/// ant-linclass' first-steps preset (issue 70 item 3) is the table's rollout-stopped Meta-BC
/// with the weight added and nothing else changed: the ablation in docs/RESULTS.md compares
/// the two.
#[test]
fn the_first_steps_preset_is_the_rollout_stopped_recipe_plus_the_weight() {
    let roll: MetaBcConfig = toml::from_str(&read("alc-bc-roll.toml")).unwrap();
    let mut early: MetaBcConfig = toml::from_str(&read("alc-bc-early.toml")).unwrap();
    early.validate().unwrap();
    assert_eq!(
        early.early,
        Some(trainer::meta_bc::EarlyWeight {
            steps: 6,
            weight: 16
        })
    );
    early.early = None;
    assert_eq!(early, roll);
}
