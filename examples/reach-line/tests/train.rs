//! Issue 71, item 2: a family defined outside `sim` trains through the library as the paper's
//! do. reach-line is registered, its scripted expert records demos in `sim`'s format, and the
//! one run driver (`trainer::run::train`) meta-trains Meta-BC and a few SMILe pairs on them
//! from configurations that name the family; Meta-BC's policy then reaches the hidden targets
//! of the test tasks from one demo each.

use std::path::Path;

use sim::{DemoDataset, Family, Split};
use trainer::Algo;
use trainer::eval::{EvalRequest, evaluate_to_dir};
use trainer::run::{TrainRequest, train};

/// The demo files of one test directory: 2 train demos per task, 1 test demo per task.
fn demos(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    reach_line::register().unwrap();
    let (train, test) = (dir.join("train.safetensors"), dir.join("test.safetensors"));
    reach_line::record_demos(Split::Train, 2, 0)
        .unwrap()
        .write(&train)
        .unwrap();
    reach_line::record_demos(Split::Test, 1, 100)
        .unwrap()
        .write(&test)
        .unwrap();
    (train, test)
}

fn run(dir: &Path, algo: Algo, config: &str, demos: &Path) -> std::path::PathBuf {
    let (file, out) = (dir.join(format!("{algo}.toml")), dir.join(algo.name()));
    std::fs::write(&file, config).unwrap();
    let req = TrainRequest {
        demos: demos.to_path_buf(),
        out: out.clone(),
        algo: Some(algo),
        config_file: Some(file),
        ..TrainRequest::default()
    };
    train(&req, &mut |_| {}).unwrap();
    out
}

/// The test tasks' mean metric (closest approach to the target, m) of one trained policy.
fn test_metric(dir: &Path, policy: &Path, contexts: &Path) -> f32 {
    let out = dir.join(format!(
        "eval-{}",
        policy.file_name().unwrap().to_string_lossy()
    ));
    let req = EvalRequest::new(
        vec![policy.to_path_buf()],
        reach_line::REACH_LINE,
        Split::Test,
        contexts.to_path_buf(),
        out,
    );
    let report = evaluate_to_dir(&req, &mut |_| {}).unwrap();
    report.methods[0].mean
}

#[test]
fn the_name_is_known_once_registered_and_refused_to_another_declaration() {
    let family = reach_line::register().unwrap();
    assert_eq!("reach-line".parse::<Family>().unwrap(), family);
    assert!(Family::all().contains(&family));
    assert_eq!(
        reach_line::register().unwrap(),
        family,
        "registering twice is a no-op"
    );
    // Its reset refuses a task value that is not finite, as the built-ins' do.
    let mut env = sim::make_env(family, sim::EnvConfig::default()).unwrap();
    let nan = sim::Task::new(family, f64::NAN);
    assert!(
        matches!(env.reset(&nan, 0), Err(sim::SimError::InvalidTask { .. })),
        "a NaN task"
    );
    // A second declaration under a built-in's name is refused, naming it.
    static CLASH: sim::FamilySpec = sim::FamilySpec {
        name: "cheetah-vel",
        ..reach_line::SPEC
    };
    let err = Family::of(&CLASH).register().unwrap_err();
    assert!(err.to_string().contains("cheetah-vel"), "{err}");
    // The demo format carries the name and reads back as this family.
    let dir = tempfile::tempdir().unwrap();
    let (train, _) = demos(dir.path());
    assert_eq!(DemoDataset::read(&train).unwrap().family, family);
}

#[test]
fn meta_bc_and_smile_train_on_a_family_from_another_crate() {
    trainer::threads::set_compute_threads(1);
    let dir = tempfile::tempdir().unwrap();
    let (train_demos, test_demos) = demos(dir.path());
    let meta_bc = run(
        dir.path(),
        Algo::MetaBc,
        r#"env = "reach-line"
policy_hidden = [32, 32]
lr = 3e-3
tasks_per_batch = 8
per_task = 32
total_steps = 600
eval_every = 200
patience = 0
seed = 0
[context]
enc_hidden = [32]
r_dim = 16
z_dim = 4
"#,
        &train_demos,
    );
    let smile = run(
        dir.path(),
        Algo::Smile,
        r#"env = "reach-line"
disc_hidden = [16]
tasks_per_batch = 4
disc_per_task = 16
sac_per_task = 16
rollouts_per_iter = 2
updates_per_iter = 5
total_updates = 10
eval_every = 5
checkpoint_every = 5
seed = 0
[sac]
hidden = [16]
[context]
enc_hidden = [16]
r_dim = 8
z_dim = 4
head_hidden = [16]
"#,
        &train_demos,
    );
    for out in [&meta_bc, &smile] {
        assert!(out.join("run.json").exists() && out.join("meta_policy.safetensors").exists());
        let policy = trainer::MetaPolicy::load(out).unwrap();
        assert_eq!(policy.family, reach_line::REACH_LINE);
    }
    // Standing still the cart is as far from a target as the target from the origin: 0.50 m
    // on average over the test targets. Meta-BC reads the target from one demo and gets there.
    let targets = reach_line::REACH_LINE.test_tasks();
    let still = targets.iter().map(|t| t.value().abs() as f32).sum::<f32>() / targets.len() as f32;
    let reached = test_metric(dir.path(), &meta_bc, &test_demos);
    eprintln!("reach-line, test targets: Meta-BC {reached:.3} m, standing still {still:.3} m");
    assert!(
        reached < 0.25 * still,
        "Meta-BC's closest approach {reached} m vs {still} m standing still"
    );
}
