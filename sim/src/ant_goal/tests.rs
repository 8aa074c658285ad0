//! ant-goal: determinism, splits, controllability, reward and metric, errors, frames.

use super::*;
use crate::ant::{ACT_DIM, OBS_DIM, obs};
use crate::env::{EpisodeMetric, make_env};
use crate::render::{Role, Shape};
use crate::render::{View, frame_to_svg};
use std::f32::consts::PI;

/// An open-loop pattern: every joint a sine of its own phase.
fn gait(step: usize) -> [f32; ACT_DIM] {
    std::array::from_fn(|j| (0.3 * step as f32 + 1.3 * j as f32).sin())
}

fn trace(task: &Task, seed: u64, steps: usize) -> Vec<u32> {
    let mut env = AntGoalEnv::new(EnvConfig::default()).unwrap();
    let mut out: Vec<f32> = env.reset(task, seed).unwrap().to_vec();
    for step in 0..steps {
        let t = env.step(&gait(step)).unwrap();
        out.extend_from_slice(t.obs);
        out.push(t.reward);
    }
    out.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn same_task_and_seed_give_bit_identical_observations_and_seeds_differ() {
    let task = Family::ANT_GOAL.test_tasks()[3];
    assert_eq!(trace(&task, 7, 50), trace(&task, 7, 50));
    assert_ne!(trace(&task, 7, 50), trace(&task, 8, 50));
}

#[test]
fn splits_are_point_goals_angles_32_train_16_test_disjoint() {
    let train = Family::ANT_GOAL.train_tasks();
    let test = Family::ANT_GOAL.test_tasks();
    assert_eq!((train.len(), test.len()), (32, 16));
    for (k, task) in train.iter().enumerate() {
        assert_eq!(*task, Task::ant_goal(k as f32 * PI / 16.0));
        assert_eq!(task.value(), Family::POINT_GOAL.train_tasks()[k].value());
    }
    for (n, task) in test.iter().enumerate() {
        assert_eq!(
            *task,
            Task::ant_goal(2.0 * n as f32 * PI / 16.0 + PI / 32.0)
        );
        assert!(!train.contains(task));
        assert_eq!(task.goal(), Family::POINT_GOAL.test_tasks()[n].goal());
    }
    // The tolerant lookup and labels work as for point-goal.
    assert_eq!(Family::ANT_GOAL.task_named(0.4909), Ok(test[1]));
    assert_eq!(test[1].label(), "goal_angle=0.4909");
    assert_eq!(test[1].parameter(), test[1].goal().unwrap().to_vec());
    assert_eq!(test[1].family(), Family::ANT_GOAL);
}

#[test]
fn zero_action_stands_and_a_gait_moves_the_torso() {
    let task = Family::ANT_GOAL.train_tasks()[0];
    let mut env = AntGoalEnv::new(EnvConfig::default()).unwrap();
    for seed in 0..3 {
        let start = env.reset(&task, seed).unwrap().to_vec();
        for step in 0..HORIZON {
            let t = env.step(&[0.0; ACT_DIM]).unwrap();
            let z = t.obs[obs::Z];
            let w = t.obs[obs::QUATERNION];
            assert!((0.45..0.7).contains(&z), "seed {seed} step {step}: z {z}");
            assert!(w > 0.95, "seed {seed} step {step}: tilted, w {w}");
        }
        let [x, y] = env.torso_xy();
        let drift = (x - start[obs::XY]).hypot(y - start[obs::XY + 1]);
        assert!(
            drift < 0.3,
            "seed {seed}: drifted {drift} m without actions"
        );
    }
    env.reset(&task, 0).unwrap();
    for step in 0..HORIZON {
        env.step(&gait(step)).unwrap();
    }
    let [x, y] = env.torso_xy();
    assert!(
        x.hypot(y) > 0.5,
        "the gait moved the torso only to ({x}, {y})"
    );
}

#[test]
fn reward_is_minus_distance_minus_action_cost_and_the_metric_is_the_minimum_distance() {
    let task = Family::ANT_GOAL.test_tasks()[5];
    let goal = task.goal().unwrap();
    let mut env = make_env(Family::ANT_GOAL, EnvConfig::default()).unwrap();
    env.reset(&task, 2).unwrap();
    let mut metric = EpisodeMetric::new(Family::ANT_GOAL);
    let mut min_distance = f32::INFINITY;
    for step in 0.. {
        // Out-of-range components are clipped before the cost.
        let mut action = gait(step).map(|a| 1.5 * a);
        action[0] = 3.0;
        let t = env.step(&action).unwrap();
        let (x, y) = (t.obs[obs::XY], t.obs[obs::XY + 1]);
        let distance = (x - goal[0]).hypot(y - goal[1]);
        let effort: f32 = action.iter().map(|a| a.clamp(-1.0, 1.0).powi(2)).sum();
        assert!((t.reward - (-distance - ACTION_COST * effort)).abs() < 1e-5);
        assert!((t.info.metric_sample - distance).abs() < 1e-5);
        assert!(!t.info.terminated);
        metric.record(&t.info);
        min_distance = min_distance.min(t.info.metric_sample);
        if t.done {
            assert!(t.info.truncated);
            assert_eq!(t.info.step, HORIZON);
            break;
        }
    }
    assert_eq!(metric.kind(), crate::family::MetricKind::MinGoalDistance);
    assert_eq!(metric.value(), min_distance);
    assert!(matches!(
        env.step(&[0.0; ACT_DIM]),
        Err(SimError::EpisodeOver { step: HORIZON })
    ));
}

#[test]
fn observation_layout_and_oracle_parameter() {
    let task = Family::ANT_GOAL.test_tasks()[0];
    let mut env = AntGoalEnv::new(EnvConfig::default()).unwrap();
    env.reset(&task, 1).unwrap();
    for step in 0..20 {
        env.step(&gait(step)).unwrap();
    }
    let o = env.observation().to_vec();
    assert_eq!(o.len(), OBS_DIM);
    assert_eq!(Family::ANT_GOAL.obs_dim(), OBS_DIM);
    let q = &o[obs::QUATERNION..obs::QUATERNION + 4];
    assert!((q.iter().map(|c| c * c).sum::<f32>() - 1.0).abs() < 1e-4);
    assert!(q[0] >= 0.0);
    assert_eq!(env.torso_xy(), [o[obs::XY], o[obs::XY + 1]]);
    assert!(o.iter().all(|x| x.is_finite()));
    assert!(
        o[obs::LINEAR_VELOCITY..obs::XY]
            .iter()
            .all(|v| v.abs() <= VELOCITY_CLIP)
    );
    let mut oracle = vec![0.0; env.oracle_obs_dim()];
    env.oracle_observation(&mut oracle).unwrap();
    assert_eq!(&oracle[..OBS_DIM], &o[..]);
    assert_eq!(&oracle[OBS_DIM..], &task.goal().unwrap());
}

#[test]
fn bad_actions_and_tasks_are_typed_errors() {
    let mut env = AntGoalEnv::new(EnvConfig::default()).unwrap();
    let mut action = [0.0; ACT_DIM];
    action[4] = f32::NAN;
    assert!(matches!(
        env.step(&action),
        Err(SimError::NonFiniteAction { index: 4, .. })
    ));
    assert!(matches!(
        env.step(&[0.0; 6]),
        Err(SimError::ActionLength {
            expected: ACT_DIM,
            got: 6,
            ..
        })
    ));
    assert!(matches!(
        env.reset(&Task::point_goal(0.5), 0),
        Err(SimError::TaskFamilyMismatch { .. })
    ));
    assert!(matches!(
        env.reset(&Task::ant_goal(f32::NAN), 0),
        Err(SimError::InvalidTask { .. })
    ));
    assert!(Family::ANT_GOAL.task_from_value(f64::INFINITY).is_err());
}

#[test]
fn frames_are_top_views_with_goal_path_torso_and_twelve_capsules() {
    let mut env = AntGoalEnv::new(EnvConfig::default()).unwrap();
    let task = Family::ANT_GOAL.test_tasks()[2];
    env.reset(&task, 0).unwrap();
    for step in 0..5 {
        env.step(&gait(step)).unwrap();
    }
    let frame = env.frame();
    assert_eq!(frame.view, View::Top);
    let robot = |role: Role| frame.shapes.iter().filter(move |s| shape_role(s) == role);
    assert_eq!(robot(Role::Robot).count(), 1 + 3 * 4);
    assert!(robot(Role::Goal).any(|s| *s
        == Shape::Circle {
            center: task.goal().unwrap(),
            radius: 0.1,
            role: Role::Goal
        }));
    // The ring of goals and one segment per step of the path.
    assert_eq!(robot(Role::Guide).count(), 1 + 5);
    let svg = frame_to_svg(&frame);
    assert!(svg.contains("t = 0.25 s"));
    // Right after a reset the frame shows the reset pose: the torso disc at the torso.
    let start = env.reset(&task, 3).unwrap().to_vec();
    let torso = env.frame().shapes.into_iter().find_map(|s| match s {
        Shape::Circle {
            center,
            role: Role::Robot,
            ..
        } => Some(center),
        _ => None,
    });
    assert_eq!(torso, Some([start[obs::XY], start[obs::XY + 1]]));
}

fn shape_role(shape: &Shape) -> Role {
    match *shape {
        Shape::Circle { role, .. } | Shape::Ring { role, .. } | Shape::Capsule { role, .. } => role,
    }
}
