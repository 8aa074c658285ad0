//! The MuJoCo backend is Python MuJoCo's robot: the golden trajectories of
//! `golden/make_mujoco_golden.py` (Python `mujoco==3.17.0`, Gymnasium's XMLs, a fixed start and
//! fixed actions, 300 control steps of frame skip 5; the walker also under walker-dyn factors)
//! replayed through `sim::mujoco::MjPlant` agree to 1e-6 in every qpos and qvel entry.
#![cfg(feature = "mujoco")]

use serde::Deserialize;
use sim::mujoco::MjPlant;
use sim::{Robot, WalkerDynamics};

#[derive(Deserialize)]
struct Factors {
    mass: [f32; 7],
    inertia: [f32; 7],
    damping: [f32; 6],
    friction: [f32; 7],
}

#[derive(Deserialize)]
struct Golden {
    robot: String,
    xml_sha256: String,
    mujoco: String,
    walker_factors: Option<Factors>,
    /// The start state and actions as IEEE bits: a decimal parser may round the last place
    /// differently, and the ant amplifies one ulp past 1e-6 within 130 steps.
    qpos0_bits: Vec<u64>,
    qvel0_bits: Vec<u64>,
    action_f32_bits: Vec<Vec<u32>>,
    qpos: Vec<Vec<f64>>,
    qvel: Vec<Vec<f64>>,
}

const TOLERANCE: f64 = 1e-6;

fn replay(file: &str, robot: Robot) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(file);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let golden: Golden = serde_json::from_str(&text).unwrap();
    assert_eq!(golden.robot, robot.name());
    assert_eq!(golden.mujoco, sim::MUJOCO_VERSION);
    let xml = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("mujoco")
            .join(format!("{}.xml", robot.name())),
    )
    .unwrap();
    assert_eq!(
        sim::sha256_hex(&xml),
        golden.xml_sha256,
        "the vendored XML changed since the golden file was made: run make_mujoco_golden.py"
    );

    let mut plant = MjPlant::new(robot).unwrap();
    if let Some(f) = &golden.walker_factors {
        plant.set_dynamics(Some(&WalkerDynamics {
            mass: f.mass,
            inertia: f.inertia,
            damping: f.damping,
            friction: f.friction,
        }));
    }
    let bits = |v: &[u64]| v.iter().map(|&b| f64::from_bits(b)).collect::<Vec<_>>();
    plant
        .set_state(&bits(&golden.qpos0_bits), &bits(&golden.qvel0_bits))
        .unwrap();
    let mut worst = 0.0f64;
    for (step, action) in golden.action_f32_bits.iter().enumerate() {
        // The environments' path: an f32 action, widened to MuJoCo's ctrl.
        let action: Vec<f32> = action.iter().map(|&b| f32::from_bits(b)).collect();
        plant.step_f32(&action);
        for (name, ours, theirs) in [
            ("qpos", plant.qpos(), &golden.qpos[step]),
            ("qvel", plant.qvel(), &golden.qvel[step]),
        ] {
            assert_eq!(ours.len(), theirs.len());
            for (i, (a, b)) in ours.iter().zip(theirs).enumerate() {
                let error = (a - b).abs();
                worst = worst.max(error);
                assert!(
                    error <= TOLERANCE,
                    "{file}: step {step} {name}[{i}] = {a}, Python MuJoCo {b} (|diff| {error:e})"
                );
            }
        }
    }
    eprintln!(
        "{file}: {} steps, worst |diff| {worst:e}",
        golden.action_f32_bits.len()
    );
}

#[test]
fn half_cheetah_follows_python_mujoco() {
    replay("mujoco-half_cheetah.json", Robot::HalfCheetah);
}

#[test]
fn walker2d_follows_python_mujoco() {
    replay("mujoco-walker2d.json", Robot::Walker2d);
}

#[test]
fn walker2d_with_walker_dyn_factors_follows_python_mujoco() {
    replay("mujoco-walker2d-dyn.json", Robot::Walker2d);
}

#[test]
fn ant_follows_python_mujoco() {
    replay("mujoco-ant.json", Robot::Ant);
}
