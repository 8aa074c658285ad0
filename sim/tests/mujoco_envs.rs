//! The task families on the MuJoCo backend: the same families, tasks, rewards and observation
//! layouts as on Rapier, with Gymnasium's robots underneath.
#![cfg(feature = "mujoco")]

use sim::{EnvConfig, Family, Physics, SimError, Task, make_env};

fn mujoco(horizon: usize) -> EnvConfig {
    EnvConfig {
        horizon: Some(horizon),
        physics: Physics::Mujoco,
        ..EnvConfig::default()
    }
}

/// The fidelity probe's trot: back leg joints lead the front leg by half a period.
fn trot(step: usize, dt: f32) -> [f32; 6] {
    let phase = 2.0 * std::f32::consts::PI * step as f32 * dt;
    let pi = std::f32::consts::PI;
    [0.0, -0.5, -1.0, pi, pi - 0.5, pi - 1.0].map(|offset| 0.6 * (phase + offset).sin())
}

fn trace(family: Family, task: Task, seed: u64, steps: usize) -> Vec<u32> {
    let mut env = make_env(family, mujoco(steps)).unwrap();
    let act_dim = env.act_dim();
    let mut out: Vec<u32> = env
        .reset(&task, seed)
        .unwrap()
        .iter()
        .map(|x| x.to_bits())
        .collect();
    for step in 0..steps {
        let action: Vec<f32> = (0..act_dim)
            .map(|j| 0.5 * ((step + j) as f32 * 0.3).sin())
            .collect();
        let t = env.step(&action).unwrap();
        out.extend(t.obs.iter().map(|x| x.to_bits()));
        out.push(t.reward.to_bits());
        if t.done {
            break;
        }
    }
    out
}

#[test]
fn every_legged_family_runs_on_mujoco_with_the_rapier_layout_and_is_deterministic() {
    for family in [
        Family::CHEETAH_VEL,
        Family::WALKER_DYN,
        Family::ANT_GOAL,
        Family::ANT_LINCLASS,
    ] {
        let rapier = make_env(family, EnvConfig::default()).unwrap();
        let env = make_env(family, mujoco(20)).unwrap();
        assert_eq!(env.physics(), Physics::Mujoco);
        assert_eq!(rapier.physics(), Physics::Rapier);
        assert_eq!(
            (env.obs_dim(), env.act_dim()),
            (rapier.obs_dim(), rapier.act_dim())
        );
        assert_eq!(env.observation().len(), env.obs_dim());
        assert!(!env.frame().shapes.is_empty(), "{family}: nothing to draw");
        let task = family.test_tasks()[0];
        assert_eq!(
            trace(family, task, 3, 20),
            trace(family, task, 3, 20),
            "{family}"
        );
        assert_ne!(
            trace(family, task, 3, 20),
            trace(family, task, 4, 20),
            "{family}"
        );
    }
}

#[test]
fn point_goal_has_no_mujoco_robot_and_says_so() {
    let err = make_env(Family::POINT_GOAL, mujoco(5)).err().unwrap();
    assert!(matches!(
        err,
        SimError::PhysicsUnavailable {
            physics: Physics::Mujoco,
            ..
        }
    ));
    assert!(err.to_string().contains("run it on Rapier"), "{err}");
}

#[test]
fn the_trot_moves_mujocos_cheetah_forward_and_its_metric_is_the_velocity_error() {
    // Section 9 of the reference: on Gymnasium's cheetah this trot moves at +0.51 m/s.
    let mut env = make_env(Family::CHEETAH_VEL, mujoco(200)).unwrap();
    let dt = env.control_dt();
    assert!((dt - 0.05).abs() < 1e-6, "control dt {dt}");
    let mut velocity = 0.0;
    env.reset(&Task::cheetah_vel(0.5), 1).unwrap();
    for step in 0..200 {
        let t = env.step(&trot(step, dt)).unwrap();
        velocity += t.info.forward_velocity / 200.0;
        let error = (t.info.forward_velocity - 0.5).abs();
        assert!((t.info.metric_sample - error).abs() < 1e-6);
    }
    assert!(
        (0.2..0.9).contains(&velocity),
        "mean forward velocity {velocity}"
    );
}

#[test]
fn a_passive_walker_falls_and_the_episode_ends_there() {
    let mut env = make_env(Family::WALKER_DYN, mujoco(1000)).unwrap();
    let obs = env.reset(&Family::WALKER_DYN.train_tasks()[0], 0).unwrap();
    assert!(
        (obs[0] - 1.25).abs() < 0.02,
        "walker starts at height {}",
        obs[0]
    );
    let mut steps = 0;
    loop {
        steps += 1;
        let t = env.step(&[0.0; 6]).unwrap();
        if t.done {
            assert!(t.info.terminated, "ran to the horizon without falling");
            break;
        }
    }
    assert!(steps < 300, "a passive walker stood {steps} steps");
}

#[test]
fn walker_dyn_tasks_change_mujocos_dynamics() {
    let tasks = Family::WALKER_DYN.train_tasks();
    let a = trace(Family::WALKER_DYN, tasks[0], 1, 30);
    let b = trace(Family::WALKER_DYN, tasks[1], 1, 30);
    assert_ne!(a, b, "two dynamics gave the same trajectory");
    // Back to the first dynamics on the same environment: the model is restored, not drifted.
    let mut env = make_env(Family::WALKER_DYN, mujoco(30)).unwrap();
    let run = |env: &mut Box<dyn sim::Environment>, task: &Task| {
        env.reset(task, 1).unwrap();
        (0..10)
            .map(|_| env.step(&[0.2; 6]).unwrap().obs[0])
            .collect::<Vec<_>>()
    };
    let first = run(&mut env, &tasks[0]);
    run(&mut env, &tasks[1]);
    assert_eq!(first, run(&mut env, &tasks[0]));
}

#[test]
fn mujoco_leaves_no_log_file_behind() {
    let _ = make_env(Family::CHEETAH_VEL, mujoco(5)).unwrap();
    assert!(!std::path::Path::new("MUJOCO_LOG.TXT").exists());
}
