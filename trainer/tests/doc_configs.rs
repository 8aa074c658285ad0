//! The configuration files that docs/RESULTS.md trains with still parse and validate.

use trainer::meta_bc::{MetaBcConfig, Selection};
use trainer::smile::SmileConfig;

fn read(name: &str) -> String {
    let path = format!("{}/../docs/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
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
