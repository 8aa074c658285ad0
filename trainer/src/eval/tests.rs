//! The normalised metric (pure function and report plumbing).

use super::request::REPORT_FILES;
use super::*;

#[test]
fn normalised_score_matches_a_hand_computed_value() {
    // Task 0: (30 - 10) / (50 - 10) = 0.5; task 1: (0 - 20) / (40 - 20) = -1;
    // task 2: (25 - 5) / (15 - 5) = 2. Mean (0.5 - 1 + 2) / 3 = 0.5.
    let n = normalised_score(&[30.0, 0.0, 25.0], &[10.0, 20.0, 5.0], &[50.0, 40.0, 15.0]).unwrap();
    assert_eq!(n.per_task, vec![Some(0.5), Some(-1.0), Some(2.0)]);
    assert_eq!((n.tasks_used, n.tasks_skipped), (3, 0));
    assert!((n.score.unwrap() - 0.5).abs() < 1e-6, "{n:?}");
}

#[test]
fn tasks_where_the_expert_is_not_better_than_the_base_are_skipped() {
    // Task 1: expert < base; task 2: expert == base (would divide by zero); task 3: NaN base.
    let n = normalised_score(
        &[6.0, 100.0, 100.0, 100.0, 3.0],
        &[2.0, 50.0, 7.0, f32::NAN, 1.0],
        &[10.0, 40.0, 7.0, 9.0, 2.0],
    )
    .unwrap();
    assert_eq!(n.per_task, vec![Some(0.5), None, None, None, Some(2.0)]);
    assert_eq!((n.tasks_used, n.tasks_skipped), (2, 3));
    assert!((n.score.unwrap() - 1.25).abs() < 1e-6);
    // Every task skipped: no score rather than NaN (which JSON cannot hold).
    let none = normalised_score(&[1.0], &[5.0], &[4.0]).unwrap();
    assert_eq!(
        (none.score, none.tasks_used, none.tasks_skipped),
        (None, 0, 1)
    );
    assert!(matches!(
        normalised_score(&[1.0, 2.0], &[0.0], &[1.0, 2.0]),
        Err(Error::Shape(_))
    ));
}

fn task(value: f64, metric: f32) -> TaskResult {
    TaskResult {
        task: format!("dynamics_seed={value}"),
        value,
        metric,
        by_context_size: vec![metric],
        no_op_rate: None,
    }
}

#[test]
fn reports_with_references_score_every_method_and_old_reports_still_parse() {
    let method = MethodResult {
        name: "m".into(),
        tasks: vec![task(0.0, 30.0), task(1.0, 0.0)],
        mean: 15.0,
        std_over_tasks: 15.0,
        episode_mean: 15.0,
        episode_std: 15.0,
        by_context_size: vec![15.0],
        no_op_rate: None,
        no_op_by_context_size: None,
        normalised: None,
    };
    let plain = EvalReport::new(
        Family::WALKER_DYN,
        Split::Test,
        Protocol::for_family(Family::WALKER_DYN),
        vec![method],
    );
    let old_json = serde_json::to_string(&plain).unwrap();
    assert!(!old_json.contains("normalised") && !old_json.contains("reference"));
    let reference = ReferenceReturns {
        base: "b".into(),
        expert: "e".into(),
        base_returns: vec![10.0, 5.0],
        expert_returns: vec![50.0, 1.0],
        task_values: vec![0.0, 1.0],
        base_steps: vec![300.0, 1000.0],
        expert_steps: vec![1000.0, 20.0],
    };
    let report = plain.clone().with_reference(reference.clone()).unwrap();
    let n = report.methods[0].normalised.as_ref().unwrap();
    assert_eq!((n.score, n.tasks_used, n.tasks_skipped), (Some(0.5), 1, 1));
    let md = report.markdown();
    assert!(
        md.contains("base: b") && md.contains("**0.500** (1 tasks, 1 skipped)"),
        "{md}"
    );
    let back: EvalReport = serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
    assert_eq!(back, report);
    // Files written before the metric existed parse, without it.
    assert_eq!(
        serde_json::from_str::<EvalReport>(&old_json).unwrap(),
        plain
    );
    let short = ReferenceReturns {
        base_returns: vec![1.0],
        ..reference.clone()
    };
    assert!(plain.clone().with_reference(short).is_err());
    // References of other tasks are refused.
    let other = ReferenceReturns {
        task_values: vec![0.0, 2.0],
        ..reference
    };
    assert!(plain.with_reference(other).is_err());
}

#[test]
fn ant_goal_is_evaluated_with_the_papers_figure_2_protocol_and_metric() {
    let p = Protocol::for_family(Family::ANT_GOAL);
    assert_eq!((p.context_sizes, p.draws, p.rollouts), (vec![1], 3, 10));
    assert_eq!(
        metric_name(Family::ANT_GOAL.metric_kind()),
        "min distance to goal"
    );
}

/// Stands still whatever the context: never reaches a target.
struct StandStill;

impl ConditionedActor for StandStill {
    fn latent(&mut self, context: &[&Trajectory]) -> Result<Vec<f32>> {
        Ok(vec![context.len() as f32])
    }
    fn act(&mut self, _obs: &[f32], _z: &[f32], action: &mut [f32]) -> Result<()> {
        action.fill(0.0);
        Ok(())
    }
}

#[test]
fn classification_evaluations_report_success_and_the_no_op_rate_per_context_size() {
    let contexts = DemoDataset::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/experts/ant-linclass/demos-test-16x-sub5.safetensors"),
    )
    .unwrap();
    let protocol = Protocol {
        context_sizes: vec![1, 8],
        draws: 1,
        rollouts: 1,
        horizon: Some(4),
        action_noise: 0.0,
        run_through_falls: false,
        physics: Default::default(),
    };
    let family = Family::ANT_LINCLASS;
    let m = evaluate(
        &mut StandStill,
        "still",
        family,
        Split::Test,
        &contexts,
        &protocol,
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(m.tasks.len(), 32);
    assert_eq!((m.mean, m.no_op_rate), (0.0, Some(1.0)));
    assert_eq!(m.no_op_by_context_size, Some(vec![1.0, 1.0]));
    assert!(m.tasks.iter().all(|t| t.no_op_rate == Some(1.0)));
    let report = EvalReport::new(family, Split::Test, protocol, vec![m]);
    assert!(!report.lower_is_better);
    assert_eq!(report.metric, "success rate");
    let md = report.markdown();
    assert!(
        md.contains("| **no-op rate** (no decision) | 1.000 |"),
        "{md}"
    );
    assert!(
        md.contains("| no-op rate, 8 context demos | 1.000 |"),
        "{md}"
    );
    // The JSON carries it for `smile report`.
    let json = serde_json::to_string(&report).unwrap();
    assert!(json.contains("no_op_rate"));
    let p = Protocol::for_family(Family::ANT_LINCLASS);
    assert_eq!(p.context_sizes, vec![1, 2, 4, 8]);
}

#[test]
fn action_noise_perturbs_every_episode_reproducibly_and_zero_changes_nothing() {
    let contexts = DemoDataset::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/experts/point-goal/demos-test-4x-sub20.safetensors"),
    )
    .unwrap();
    let run = |sigma: f32| {
        let protocol = Protocol {
            context_sizes: vec![1],
            draws: 1,
            rollouts: 2,
            horizon: Some(20),
            action_noise: sigma,
            run_through_falls: false,
            physics: Default::default(),
        };
        evaluate(
            &mut StandStill,
            "still",
            Family::POINT_GOAL,
            Split::Test,
            &contexts,
            &protocol,
            &mut |_, _| {},
        )
        .unwrap()
    };
    let (still, noisy) = (run(0.0), run(0.5));
    // A point that never moves keeps its start distance; noise moves it, the same way twice.
    assert_ne!(still.mean, noisy.mean);
    assert_eq!(noisy, run(0.5));
    assert_eq!(still, run(0.0));
    // The protocol without the field (an older eval.json) reads as no noise.
    let old: Protocol =
        serde_json::from_str(r#"{"context_sizes": [1], "draws": 1, "rollouts": 1}"#).unwrap();
    assert_eq!(old.action_noise, 0.0);
}

/// The SMILe authors' walker evaluation (`terminal = False`) runs every episode to the horizon
/// with the alive bonus after a fall; this project's protocol ends an episode at the fall. A
/// walker given no torque falls within the first second.
#[test]
fn the_authors_walker_protocol_runs_through_falls() {
    let contexts = DemoDataset::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/experts/walker-dyn/demos-test-4x-sub20.safetensors"),
    )
    .unwrap();
    let run = |run_through_falls: bool| {
        let protocol = Protocol {
            horizon: Some(300),
            run_through_falls,
            physics: Default::default(),
            ..Protocol::for_family(Family::WALKER_DYN)
        };
        evaluate(
            &mut StandStill,
            "still",
            Family::WALKER_DYN,
            Split::Test,
            &contexts,
            &protocol,
            &mut |_, _| {},
        )
        .unwrap()
    };
    let (falls_end, authors) = (run(false), run(true));
    // 300 steps of alive bonus 1, give or take the fall's velocity.
    assert!(
        authors.mean > 250.0 && falls_end.mean < 0.5 * authors.mean,
        "mean return: falls end {:.1}, authors' {:.1}",
        falls_end.mean,
        authors.mean
    );
    let old: Protocol =
        serde_json::from_str(r#"{"context_sizes": [1], "draws": 1, "rollouts": 1}"#).unwrap();
    assert!(
        !old.run_through_falls,
        "an older eval.json is this project's protocol"
    );
    // A family whose episodes have no falls refuses the protocol before any rollout (its
    // spec says so: `falls_end_episodes`).
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts/point-goal");
    let mut req = super::request::EvalRequest::new(
        vec![assets.join("no-policy-needed")],
        Family::POINT_GOAL,
        Split::Test,
        assets.join("demos-test-4x-sub20.safetensors"),
        std::env::temp_dir().join("never-written"),
    );
    req.run_through_falls = true;
    let err = super::request::evaluate_to_dir(&req, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("no falls to run through"), "{err}");
}

/// A one-method walker report whose mean is `mean`.
fn report_with_mean(mean: f32) -> EvalReport {
    let method = MethodResult {
        name: "m".into(),
        tasks: vec![task(0.0, mean)],
        mean,
        std_over_tasks: 0.0,
        episode_mean: mean,
        episode_std: 0.0,
        by_context_size: vec![mean],
        no_op_rate: None,
        no_op_by_context_size: None,
        normalised: None,
    };
    let family = Family::WALKER_DYN;
    EvalReport::new(
        family,
        Split::Test,
        Protocol::for_family(family),
        vec![method],
    )
}

#[test]
fn an_evaluation_that_fails_to_write_leaves_the_older_one_whole() {
    let dir = std::env::temp_dir().join(format!("smile-eval-write-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.as_path();
    write_report(&report_with_mean(1.0), out).unwrap();
    let read = |f: &str| std::fs::read(out.join(f)).unwrap();
    let old: Vec<Vec<u8>> = REPORT_FILES.iter().map(|f| read(f)).collect();
    // The picture cannot be written (a directory where its staged file goes), as a full disk
    // would fail it: the new markdown is already written by then.
    std::fs::create_dir(out.join(".eval.svg.staged")).unwrap();
    assert!(write_report(&report_with_mean(2.0), out).is_err());
    let now: Vec<Vec<u8>> = REPORT_FILES.iter().map(|f| read(f)).collect();
    assert_eq!(now, old, "the older evaluation's files are untouched");
    assert!(
        !out.join(".eval.md.staged").exists(),
        "nothing staged is left"
    );
    // Once it can write, the new evaluation replaces all three.
    std::fs::remove_dir(out.join(".eval.svg.staged")).unwrap();
    write_report(&report_with_mean(2.0), out).unwrap();
    let back: EvalReport = serde_json::from_slice(&read("eval.json")).unwrap();
    assert_eq!(back.methods[0].mean, 2.0);
    for (f, was) in REPORT_FILES.iter().zip(&old) {
        assert_ne!(&read(f), was, "{f} is the new evaluation's");
    }
    let names: Vec<String> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.ends_with(".staged")), "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
