//! ant-linclass: splits, the pair drawn per episode, the scripted choice, the metric and
//! no-op rate, determinism, errors, frames.

use super::*;
use crate::ant::ACT_DIM;
use crate::env::{EpisodeMetric, make_env};
use crate::family::{MetricKind, StepInfo};
use crate::render::{View, frame_to_svg};

fn gait(step: usize) -> [f32; ACT_DIM] {
    std::array::from_fn(|j| (0.3 * step as f32 + 1.3 * j as f32).sin())
}

#[test]
fn splits_are_64_train_and_32_test_hyperplanes_disjoint_with_unit_normals() {
    let train = Family::ANT_LINCLASS.train_tasks();
    let test = Family::ANT_LINCLASS.test_tasks();
    assert_eq!((train.len(), test.len()), (64, 32));
    assert_eq!(train[5], Task::ant_linclass(5));
    assert_eq!(test[2], Task::ant_linclass(10_002));
    let normals: Vec<[f32; POINT_DIM]> = train
        .iter()
        .chain(&test)
        .map(|t| t.linclass_normal().unwrap())
        .collect();
    for (i, w) in normals.iter().enumerate() {
        assert!((w.iter().map(|x| x * x).sum::<f32>() - 1.0).abs() < 1e-5);
        // No two tasks share a hyperplane.
        for v in &normals[..i] {
            assert!(dot(w, v).abs() < 0.9999, "task {i} repeats a hyperplane");
        }
    }
    assert!(test.iter().all(|t| !train.contains(t)));
    assert_eq!(test[2].parameter(), test[2].linclass_normal().unwrap());
    assert_eq!(test[2].label(), "hyperplane_seed=10002");
    assert_eq!(Family::ANT_LINCLASS.task_named(10_002.0), Ok(test[2]));
    assert!(Family::ANT_LINCLASS.task_from_value(2.5).is_err());
    assert!(Family::ANT_LINCLASS.task_from_value(-1.0).is_err());
    assert_eq!(Family::ANT_LINCLASS.value_tolerance(), 0.0);
    assert_eq!("ant-linclass".parse::<Family>(), Ok(Family::ANT_LINCLASS));
}

#[test]
fn each_episode_shows_one_point_per_side_in_random_order_constant_over_the_episode() {
    let task = Family::ANT_LINCLASS.test_tasks()[0];
    let w = task.linclass_normal().unwrap();
    let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
    let mut first_positive = 0;
    for seed in 0..200 {
        let o = env.reset(&task, seed).unwrap().to_vec();
        let (first, second) = (
            &o[FIRST_POINT..SECOND_POINT],
            &o[SECOND_POINT..SECOND_POINT + POINT_DIM],
        );
        assert!(first.iter().chain(second).all(|x| x.abs() <= 1.0));
        let (a, b) = (dot(&w, first), dot(&w, second));
        assert!(a * b < 0.0, "seed {seed}: both points on one side");
        let correct = if a > 0.0 { TARGETS[0] } else { TARGETS[1] };
        assert_eq!(env.correct_target(), correct);
        first_positive += usize::from(a > 0.0);
    }
    // Both orders occur, about equally often (binomial(200, 0.5): 100 +- 7).
    assert!((70..130).contains(&first_positive), "{first_positive}");
    env.reset(&task, 9).unwrap();
    let points = env.observation()[FIRST_POINT..].to_vec();
    for step in 0..10 {
        let t = env.step(&gait(step)).unwrap();
        assert_eq!(&t.obs[FIRST_POINT..], &points[..]);
    }
}

#[test]
fn same_task_and_seed_give_bit_identical_episodes() {
    let trace = |seed: u64| {
        let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
        let mut out = env
            .reset(&Family::ANT_LINCLASS.train_tasks()[3], seed)
            .unwrap()
            .to_vec();
        for step in 0..30 {
            let t = env.step(&gait(step)).unwrap();
            out.extend_from_slice(t.obs);
            out.push(t.reward);
        }
        out.iter().map(|x| x.to_bits()).collect::<Vec<u32>>()
    };
    assert_eq!(trace(4), trace(4));
    assert_ne!(trace(4), trace(5));
}

#[test]
fn the_scripted_target_is_the_episodes_correct_target_and_feeds_an_ant_goal_expert() {
    let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
    let mut oracle = vec![0.0; env.oracle_obs_dim()];
    let mut goal_input = vec![0.0; Family::ANT_GOAL.oracle_obs_dim()];
    for (i, task) in Family::ANT_LINCLASS.test_tasks().iter().enumerate() {
        env.reset(task, i as u64).unwrap();
        env.oracle_observation(&mut oracle).unwrap();
        assert_eq!(&oracle[OBS_DIM..], &task.linclass_normal().unwrap());
        assert_eq!(scripted_target(&oracle), Ok(env.correct_target()));
        goal_expert_input(&oracle, AIM_SCALE, &mut goal_input).unwrap();
        let ant = crate::ant::OBS_DIM;
        assert_eq!(&goal_input[..ant], &env.observation()[..ant]);
        assert_eq!(
            &goal_input[ant..],
            &env.correct_target().map(|t| t * AIM_SCALE)
        );
    }
    assert!(matches!(
        scripted_target(&oracle[1..]),
        Err(SimError::BufferLength { .. })
    ));
    assert!(matches!(
        goal_expert_input(&oracle, AIM_SCALE, &mut goal_input[1..]),
        Err(SimError::BufferLength { .. })
    ));
}

#[test]
fn standing_still_decides_nothing_earns_nothing_and_is_a_no_op() {
    let task = Family::ANT_LINCLASS.test_tasks()[1];
    let mut env = make_env(Family::ANT_LINCLASS, EnvConfig::default()).unwrap();
    assert_eq!(env.horizon(), HORIZON);
    env.reset(&task, 0).unwrap();
    let mut metric = EpisodeMetric::new(Family::ANT_LINCLASS);
    assert_eq!(metric.kind(), MetricKind::ClassificationSuccess);
    loop {
        let t = env.step(&[0.0; ACT_DIM]).unwrap();
        assert_eq!((t.reward, t.info.metric_sample), (0.0, 0.0));
        assert!(!t.info.terminated);
        metric.record(&t.info);
        if t.done {
            assert_eq!(t.info.step, HORIZON);
            break;
        }
    }
    assert_eq!((metric.value(), metric.no_op()), (0.0, Some(true)));
}

#[test]
fn the_metric_reads_the_latched_decision() {
    let run = |samples: &[f32]| {
        let mut m = EpisodeMetric::new(Family::ANT_LINCLASS);
        for &s in samples {
            m.record(&StepInfo {
                metric_sample: s,
                ..StepInfo::default()
            });
        }
        (m.value(), m.no_op())
    };
    assert_eq!(run(&[0.0, 0.0, 1.0, 1.0]), (1.0, Some(false)));
    assert_eq!(run(&[0.0, -1.0, -1.0]), (0.0, Some(false)));
    assert_eq!(run(&[0.0, 0.0]), (0.0, Some(true)));
    assert!(run(&[]).0.is_nan());
    assert_eq!(run(&[]).1, None, "no decision can be judged before a step");
    // Fresh accumulators compare equal (no NaN inside).
    assert_eq!(
        EpisodeMetric::new(Family::ANT_LINCLASS),
        EpisodeMetric::new(Family::ANT_LINCLASS)
    );
    assert_eq!(EpisodeMetric::new(Family::ANT_GOAL).no_op(), None);
    for d in [Decision::Undecided, Decision::Correct, Decision::Wrong] {
        assert_eq!(Decision::from_sample(d.sample()), d);
    }
}

#[test]
fn bad_actions_and_tasks_are_typed_errors() {
    let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
    assert!(matches!(
        env.step(&[0.0; 3]),
        Err(SimError::ActionLength { got: 3, .. })
    ));
    assert!(matches!(
        env.step(&[f32::NAN; ACT_DIM]),
        Err(SimError::NonFiniteAction { index: 0, .. })
    ));
    assert!(matches!(
        env.reset(&Task::ant_goal(0.5), 0),
        Err(SimError::TaskFamilyMismatch { .. })
    ));
}

#[test]
fn frames_show_both_targets_the_correct_one_filled() {
    let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
    env.reset(&Family::ANT_LINCLASS.test_tasks()[0], 1).unwrap();
    for step in 0..3 {
        env.step(&gait(step)).unwrap();
    }
    let frame = env.frame();
    assert_eq!(frame.view, View::Top);
    assert!(frame.shapes.contains(&Shape::Circle {
        center: env.correct_target(),
        radius: DECISION_RADIUS,
        role: Role::Goal
    }));
    assert_eq!(
        frame
            .shapes
            .iter()
            .filter(|s| matches!(s, Shape::Ring { .. }))
            .count(),
        1
    );
    assert!(frame_to_svg(&frame).contains("<svg"));
}

#[test]
fn tasks_draw_their_own_points_for_the_same_reset_seed() {
    // Demos of different tasks recorded with the same reset seeds must not share their points.
    let mut env = AntLinClassEnv::new(EnvConfig::default()).unwrap();
    let tasks = Family::ANT_LINCLASS.train_tasks();
    let mut firsts: Vec<Vec<u32>> = tasks
        .iter()
        .map(|t| {
            env.reset(t, 0).unwrap()[FIRST_POINT..SECOND_POINT]
                .iter()
                .map(|x| x.to_bits())
                .collect()
        })
        .collect();
    firsts.sort();
    firsts.dedup();
    assert_eq!(firsts.len(), tasks.len(), "two tasks share a first point");
}
