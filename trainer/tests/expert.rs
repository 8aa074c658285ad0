//! Expert runs: resume == uninterrupted, corrupt checkpoints, divergence, demo round trip.

use std::path::{Path, PathBuf};

use sim::ant_linclass::AIM_SCALE;
use sim::{EnvConfig, Family, Split};
use trainer::checkpoint;
use trainer::expert::{self, Expert, ExpertConfig, ExpertTrainer};
use trainer::sac::SacConfig;
use trainer::{DemoSpec, record_demos as record};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("smile-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn tiny(total: u64) -> ExpertConfig {
    ExpertConfig {
        total_steps: total,
        learning_starts: 30,
        horizon: Some(20),
        checkpoint_every: 60,
        eval_every: 40,
        buffer_capacity: 1000,
        sac: SacConfig {
            hidden: vec![16, 16],
            batch_size: 16,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// A new expert run of `cfg`, trained to its budget in `dir`.
fn trained(cfg: ExpertConfig, dir: &Path) -> ExpertTrainer {
    let mut run = ExpertTrainer::new(cfg).unwrap();
    trainer::fit(&mut run, dir, &mut |_| {}).unwrap();
    run
}

#[test]
fn resumed_run_equals_uninterrupted_run() {
    trainer::threads::set_compute_threads(1);
    let (a, b) = (tmp("full"), tmp("split"));
    let full = trained(tiny(120), &a);

    let first = trained(tiny(60), &b);
    drop(first); // "killed" after its checkpoint at step 60
    let mut resumed = ExpertTrainer::resume(&b, Some(120)).unwrap();
    assert_eq!(resumed.env_steps(), 60);
    trainer::fit(&mut resumed, &b, &mut |_| {}).unwrap();

    let (ca, cb) = (checkpoint::load(&a).unwrap(), checkpoint::load(&b).unwrap());
    for key in ["sac_counters", "env_steps", "episodes", "rng"] {
        assert_eq!(ca.meta[key], cb.meta[key], "{key}");
    }
    let (names, _) = full.sac.state_tensors().unwrap();
    assert!(names.len() > 20);
    for (name, _) in names
        .iter()
        .chain(&[("replay.obs".to_string(), names[0].1.clone())])
    {
        let [x, y] = [&ca, &cb].map(|c| c.get(name).unwrap().flatten_all().unwrap());
        let (x, y) = (x.to_vec1::<f32>().unwrap(), y.to_vec1::<f32>().unwrap());
        assert_eq!(x, y, "{name} differs after resume");
    }
    std::fs::remove_dir_all(&a).ok();
    std::fs::remove_dir_all(&b).ok();
}

#[test]
fn keep_best_ships_the_better_of_the_best_evaluation_and_the_final_weights() {
    trainer::threads::set_compute_threads(1);
    let d = tmp("keep-best");
    let cfg = ExpertConfig {
        keep_best: true,
        ..tiny(200)
    };
    let run = trained(cfg.clone(), &d);
    let best = run.best_eval().expect("evaluations ran every 40 steps");
    assert!(best.env_steps >= 40 && best.env_steps <= 200);
    let best_file = d.join(expert::BEST_POLICY_FILE);
    assert!(best_file.exists());
    // The shipped weights evaluate at least as well as the best periodic evaluation (point-goal:
    // lower min-distance is better), on the same tasks and episodes.
    let eval = |p: &std::path::Path| {
        let ex = Expert::load(p).unwrap();
        let env = EnvConfig {
            horizon: cfg.horizon,
            ..EnvConfig::default()
        };
        expert::evaluate(&ex, &Family::POINT_GOAL.test_tasks(), 1, env)
            .unwrap()
            .mean
    };
    let (shipped, best_again) = (eval(&d), eval(&best_file));
    assert_eq!(
        best_again, best.metric,
        "the best file holds the best weights"
    );
    assert!(shipped <= best.metric, "{shipped} > best {}", best.metric);
    // The best evaluation survives a resume.
    let resumed = ExpertTrainer::resume(&d, Some(240)).unwrap();
    assert_eq!(resumed.best_eval(), Some(best));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn warm_start_begins_from_the_source_run_and_resumes_without_it() {
    trainer::threads::set_compute_threads(1);
    let (src, dst) = (tmp("warm-src"), tmp("warm-dst"));
    let source = trained(tiny(60), &src);
    let actor = |run: &ExpertTrainer| {
        let (tensors, _) = run.sac.state_tensors().unwrap();
        tensors
            .iter()
            .filter(|(n, _)| n.starts_with("actor") || n.starts_with("q1"))
            .map(|(_, t)| t.flatten_all().unwrap().to_vec1::<f32>().unwrap())
            .collect::<Vec<_>>()
    };
    let warm_cfg = ExpertConfig {
        init_from: Some(src.clone()),
        task_index: Some(3),
        ..tiny(40)
    };
    let mut warm = ExpertTrainer::new(warm_cfg.clone()).unwrap();
    assert_eq!(
        actor(&warm),
        actor(&source),
        "starts from the source's weights"
    );
    assert_eq!(
        warm.env_steps(),
        0,
        "a new run: its own counters and buffer"
    );
    assert_ne!(
        actor(&ExpertTrainer::new(tiny(40)).unwrap()),
        actor(&source)
    );
    trainer::fit(&mut warm, &dst, &mut |_| {}).unwrap();
    // The warm start lives in the run's own checkpoint: resuming needs no source.
    std::fs::remove_dir_all(&src).unwrap();
    let resumed = ExpertTrainer::resume(&dst, Some(80)).unwrap();
    assert_eq!(actor(&resumed), actor(&warm));
    // A source of another width is refused by name.
    let wide = ExpertConfig {
        sac: SacConfig {
            hidden: vec![8, 8],
            batch_size: 16,
            ..Default::default()
        },
        init_from: Some(dst.clone()),
        ..tiny(40)
    };
    let e = ExpertTrainer::new(wide).err().unwrap().to_string();
    assert!(e.contains("hidden [16, 16]") && e.contains("[8, 8]"), "{e}");
    // So is a source trained on another physics backend (checked before the plant is built,
    // so this holds in a build without MuJoCo too).
    let other_plant = ExpertConfig {
        physics: sim::Physics::Mujoco,
        init_from: Some(dst.clone()),
        ..tiny(40)
    };
    let e = ExpertTrainer::new(other_plant).err().unwrap().to_string();
    assert!(
        e.contains("trained on rapier cannot start one on mujoco"),
        "{e}"
    );
    std::fs::remove_dir_all(&dst).ok();
}

#[test]
fn corrupt_or_foreign_checkpoint_is_a_clear_error() {
    trainer::threads::set_compute_threads(1);
    let d = tmp("corrupt");
    trained(tiny(40), &d);
    // A policy file is not a training checkpoint, and vice versa.
    let e = ExpertTrainer::resume(&d.join(trainer::checkpoint::POLICY_FILE), None)
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("not an expert training checkpoint"),
        "{e}"
    );
    let e = Expert::load(&d.join(checkpoint::CHECKPOINT_FILE)).unwrap_err();
    assert!(e.to_string().contains("not an expert policy file"), "{e}");
    // Truncated checkpoint.
    let p = d.join(checkpoint::CHECKPOINT_FILE);
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = ExpertTrainer::resume(&d, None).err().unwrap().to_string();
    assert!(
        e.contains("checkpoint") && e.contains("checkpoint.safetensors"),
        "{e}"
    );
    // Missing directory.
    assert!(ExpertTrainer::resume(&d.join("nope"), None).is_err());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn non_finite_loss_names_the_update() {
    trainer::threads::set_compute_threads(1);
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let cfg = SacConfig {
        hidden: vec![8],
        ..Default::default()
    };
    let mut sac = trainer::sac::Sac::new(3, 1, cfg, &mut rng).unwrap();
    let mut rb = trainer::ReplayBuffer::new(3, 1, 10).unwrap();
    rb.push(&[0.0; 3], &[0.0], f32::NAN, &[0.0; 3], false, None)
        .unwrap();
    let b = rb.sample(4, &mut rng).unwrap();
    match sac.update(&b, &mut rng) {
        Err(trainer::Error::NonFinite { what, update, .. }) => {
            assert_eq!((what, update), ("losses/qf_loss", 1));
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
}

#[test]
fn demos_round_trip_and_are_deterministic() {
    let d = tmp("demos");
    std::fs::create_dir_all(&d).unwrap();
    expert::export_scripted_pd(&d).unwrap();
    let ex = Expert::load(&d).unwrap();
    assert_eq!(ex.name(), "scripted-pd");
    let spec = DemoSpec {
        tasks: Family::POINT_GOAL.test_tasks()[..2].to_vec(),
        split: Split::Test,
        per_task: 2,
        subsample: 5,
        seed: 3,
        distinct_starts: false,
        env: EnvConfig {
            horizon: Some(30),
            ..Default::default()
        },
    };
    let ds = record(&ex, &spec).unwrap();
    assert_eq!(ds.trajectory_count(), 4);
    assert_eq!(ds.subsample_factor, 5);
    assert_eq!(ds.transition_count(), 4 * 6);
    let f = d.join("demos.safetensors");
    ds.write(&f).unwrap();
    assert_eq!(sim::DemoDataset::read(&f).unwrap(), ds);
    assert_eq!(record(&ex, &spec).unwrap(), ds);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn distinct_starts_give_every_task_its_own_reset_seeds() {
    let d = tmp("demos-starts");
    std::fs::create_dir_all(&d).unwrap();
    expert::export_scripted_pd(&d).unwrap();
    let ex = Expert::load(&d).unwrap();
    let spec = |distinct_starts| DemoSpec {
        tasks: Family::POINT_GOAL.test_tasks()[..3].to_vec(),
        split: Split::Test,
        per_task: 2,
        subsample: 1,
        seed: 10,
        distinct_starts,
        env: EnvConfig {
            horizon: Some(5),
            ..Default::default()
        },
    };
    let seeds = |ds: &sim::DemoDataset| -> Vec<Vec<u64>> {
        ds.tasks
            .iter()
            .map(|t| t.trajectories.iter().map(|tr| tr.seed).collect())
            .collect()
    };
    let shared = record(&ex, &spec(false)).unwrap();
    assert_eq!(seeds(&shared), vec![vec![10, 11]; 3]);
    let distinct = record(&ex, &spec(true)).unwrap();
    assert_eq!(seeds(&distinct), [[10, 11], [12, 13], [14, 15]]);
    // The first task's demos are the shared file's; the next ones start elsewhere (point-goal's
    // start is drawn from the reset seed).
    assert_eq!(distinct.tasks[0], shared.tasks[0]);
    let start = |ds: &sim::DemoDataset| ds.tasks[1].trajectories[0].obs[..2].to_vec();
    assert_ne!(start(&distinct), start(&shared));
    assert_eq!(
        start(&shared),
        shared.tasks[0].trajectories[0].obs[..2].to_vec()
    );
    // Seeds that would wrap past 2^64 (onto ones another demo used) are refused, not wrapped.
    let near_end = |distinct_starts| DemoSpec {
        seed: u64::MAX - 4,
        ..spec(distinct_starts)
    };
    assert!(record(&ex, &near_end(false)).is_ok());
    let e = record(&ex, &near_end(true)).unwrap_err().to_string();
    assert!(e.contains("smaller seed"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn an_ant_goal_expert_trains_evaluates_and_records_demos_of_the_3d_family() {
    trainer::threads::set_compute_threads(1);
    let cfg = ExpertConfig {
        env: Family::ANT_GOAL,
        ..tiny(60)
    };
    let d = tmp("ant-goal");
    trained(cfg.clone(), &d);
    let ex = Expert::load(&d).unwrap();
    assert_eq!(ex.family(), Family::ANT_GOAL);
    let env = EnvConfig {
        horizon: cfg.horizon,
        ..EnvConfig::default()
    };
    let tasks = Family::ANT_GOAL.test_tasks()[..2].to_vec();
    let eval = expert::evaluate(&ex, &tasks, 1, env).unwrap();
    // Min distance to a goal 2 m away after 20 steps of an untrained policy.
    assert!(eval.mean.is_finite() && eval.mean > 0.5, "{}", eval.mean);
    let spec = DemoSpec {
        tasks,
        split: Split::Test,
        per_task: 1,
        subsample: 1,
        seed: 0,
        distinct_starts: false,
        env,
    };
    let ds = record(&ex, &spec).unwrap();
    assert_eq!(ds.family, Family::ANT_GOAL);
    assert_eq!((ds.obs_dim, ds.act_dim), (29, 8));
    assert_eq!(ds.transition_count(), 2 * 20);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn the_scripted_linclass_expert_drives_the_shipped_ant_goal_expert_to_the_correct_target() {
    trainer::threads::set_compute_threads(1);
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts");
    let d = tmp("linclass");
    expert::export_scripted_linclass(&assets.join("ant-goal"), AIM_SCALE, &d).unwrap();
    let ex = Expert::load(&d).unwrap();
    assert_eq!(
        (ex.family(), ex.name()),
        (Family::ANT_LINCLASS, "scripted-linclass")
    );
    let tasks = Family::ANT_LINCLASS.test_tasks()[..4].to_vec();
    let eval = expert::evaluate(&ex, &tasks, 2, EnvConfig::default()).unwrap();
    // Measured 0.78 over 32 tasks x 10 episodes (20 distinct walks), 0.88 over 320 distinct
    // walks (docs/results/linclass-walk-end); on these shared seeds a failure is a no-op (last
    // sample 0), never the wrong target (last sample -1), so the mean last sample equals the
    // success.
    assert!(eval.mean >= 0.5, "{eval:?}");
    assert_eq!(eval.final_sample_mean, eval.mean);
    // The shipped copy is the same expert.
    let shipped = Expert::load(&assets.join("ant-linclass")).unwrap();
    assert_eq!(
        expert::evaluate(&shipped, &tasks, 2, EnvConfig::default()).unwrap(),
        eval
    );
    // Only an ant-goal SAC expert can be driven.
    let err = expert::export_scripted_linclass(
        &assets.join("ant-linclass"),
        AIM_SCALE,
        &tmp("linclass-bad"),
    )
    .unwrap_err();
    assert!(err.to_string().contains("ant-goal SAC expert"), "{err}");
    // The aim is stored and read back: another aim acts differently, a bad one is refused.
    let far = tmp("linclass-far");
    expert::export_scripted_linclass(&assets.join("ant-goal"), 2.0, &far).unwrap();
    let far_expert = Expert::load(&far).unwrap();
    let task = tasks[0];
    let mut env = sim::make_env(Family::ANT_LINCLASS, EnvConfig::default()).unwrap();
    env.reset(&task, 0).unwrap();
    let mut oracle = vec![0.0; Family::ANT_LINCLASS.oracle_obs_dim()];
    env.oracle_observation(&mut oracle).unwrap();
    let (mut near_action, mut far_action) = ([0.0f32; 8], [0.0f32; 8]);
    ex.act(&oracle, &mut near_action).unwrap();
    far_expert.act(&oracle, &mut far_action).unwrap();
    assert_ne!(near_action, far_action);
    for bad in [0.0, -1.0, f32::NAN] {
        let err = expert::export_scripted_linclass(&assets.join("ant-goal"), bad, &tmp("lc-bad"))
            .unwrap_err();
        assert!(err.to_string().contains("aim scale"), "{err}");
    }
    std::fs::remove_dir_all(&far).ok();
    std::fs::remove_dir_all(&d).ok();
}

/// An evaluation from distinct starts resets task i's episode k with seed `1_000_000 + i *
/// episodes + k`: the first task's episodes are the plain evaluation's, the others' are not.
#[test]
fn an_evaluation_from_distinct_starts_reseeds_every_task_but_the_first() {
    trainer::threads::set_compute_threads(1);
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts");
    let ex = Expert::load(&assets.join("ant-goal")).unwrap();
    let tasks = Family::ANT_GOAL.test_tasks()[..3].to_vec();
    let env = EnvConfig::new(Some(20), sim::Physics::Rapier);
    let shared = expert::evaluate(&ex, &tasks, 2, env).unwrap();
    let distinct = expert::evaluate_distinct(&ex, &tasks, 2, env).unwrap();
    assert_eq!(distinct.per_task[0], shared.per_task[0]);
    for i in 1..3 {
        assert_ne!(distinct.per_task[i], shared.per_task[i], "task {i}");
    }
    // Task 1's two episodes are the plain evaluation's episodes 2 and 3 of that task.
    let four = expert::evaluate(&ex, &tasks[1..2], 4, env).unwrap();
    let (first_two, all) = (shared.per_task[1], four.per_task[0]);
    assert!(
        (2.0 * all - first_two - distinct.per_task[1]).abs() < 1e-5,
        "{all} {first_two} {}",
        distinct.per_task[1]
    );
}

/// A resume of an expert run killed before its first checkpoint starts it over with its
/// recorded `config.toml`, as a meta-learner's does: the same policy as the uninterrupted run,
/// the dead run's files cleared. A finished run whose checkpoint is gone is refused, its files
/// kept.
#[test]
fn a_resume_without_a_checkpoint_starts_the_recorded_run_over() {
    use trainer::run::{ExpertRequest, RunEvent, train_expert};
    trainer::threads::set_compute_threads(1);
    let d = tmp("restart");
    let request = |config| ExpertRequest {
        out: d.clone(),
        config,
        total_steps: None,
    };
    train_expert(&request(Some(tiny(60))), &mut |_| {}).unwrap();
    let read = |name: &str| std::fs::read(d.join(name)).unwrap();
    let policy = read(checkpoint::POLICY_FILE);
    // What a run killed before its first checkpoint leaves: its config, log and events, and
    // perhaps a policy kept by an early evaluation and a compute count.
    let gone = [
        checkpoint::CHECKPOINT_FILE,
        "checkpoint.json",
        checkpoint::POLICY_FILE,
    ];
    for f in gone {
        std::fs::remove_file(d.join(f)).unwrap();
    }
    let leftovers = [checkpoint::BEST_POLICY_FILE, "compute.json"];
    for f in leftovers {
        std::fs::write(d.join(f), b"left by the killed run").unwrap();
    }
    let events = || std::fs::read_dir(d.join("tb")).unwrap().count();
    assert_eq!(events(), 1);

    let (mut notes, mut started) = (Vec::new(), None);
    train_expert(&request(None), &mut |e| match e {
        RunEvent::Note(n) => notes.push(n),
        RunEvent::Started { done, resumed, .. } => started = Some((done, resumed)),
        _ => {}
    })
    .unwrap();
    let restarted = notes.iter().any(|n| n.contains("no checkpoint yet"));
    assert!(restarted, "{notes:?}");
    assert_eq!(started, Some((0, false)), "a new start, from step 0");
    assert_eq!(read(checkpoint::POLICY_FILE), policy, "the same run");
    assert_eq!(events(), 1, "the dead run's event file is gone");
    assert!(leftovers.iter().all(|f| !d.join(f).exists()));

    // Finished, then its checkpoint lost: nothing to continue, and nothing is removed.
    std::fs::remove_file(d.join(checkpoint::CHECKPOINT_FILE)).unwrap();
    let log = read(trainer::METRICS_FILE);
    let refusal = || {
        train_expert(&request(None), &mut |_| {})
            .unwrap_err()
            .to_string()
    };
    let e = refusal();
    assert!(
        e.contains("holds a finished run") && e.contains("is kept"),
        "{e}"
    );
    assert_eq!(read(checkpoint::POLICY_FILE), policy);
    assert_eq!(read(trainer::METRICS_FILE), log);

    // A meta-learner's run (it records run.json) is not an expert's to resume: named, kept.
    std::fs::write(d.join(trainer::run::RUN_FILE), r#"{"algo": "meta-bc"}"#).unwrap();
    let e = refusal();
    assert!(
        e.contains("holds a meta-bc run") && e.contains("not an expert's"),
        "{e}"
    );
    assert_eq!(read(trainer::METRICS_FILE), log);
    std::fs::remove_dir_all(&d).ok();
}
