//! The fidelity probe on the MuJoCo backend agrees with the probe's Python script on Python
//! MuJoCo 3.17.0 (`docs/fidelity/python-mujoco-3.17-*.json`, `docs/FIDELITY.md`): the curves that
//! draw no random numbers (joint pulses with the torso welded, the drop from rest) to 1e-6 (RMS,
//! rad or m; the Rust probe reports f32, whose rounding is about 6e-8 here). The statistics over
//! seeds draw from other random streams and are compared in FIDELITY.md, not here.
#![cfg(feature = "mujoco")]

use serde_json::Value;
use sim::fidelity::{ProbeConfig, Robot, probe_mujoco};

fn python(robot: &str) -> Value {
    let path = format!(
        "{}/../docs/fidelity/python-mujoco-3.17-{robot}.json",
        env!("CARGO_MANIFEST_DIR")
    );
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

fn curve(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// RMS(ours - theirs).
fn rms(ours: &[f64], theirs: &[f64]) -> f64 {
    assert_eq!(ours.len(), theirs.len());
    let squares: f64 = ours.iter().zip(theirs).map(|(a, b)| (a - b).powi(2)).sum();
    (squares / ours.len() as f64).sqrt()
}

#[test]
fn the_probes_deterministic_curves_are_python_mujocos() {
    // Two seeds: the statistics are not compared here, only the seed-free curves.
    let config = ProbeConfig {
        seeds: 2,
        steps: 200,
    };
    for robot in [Robot::Cheetah, Robot::Walker, Robot::Ant] {
        let ours = probe_mujoco(robot, &config);
        let theirs = python(robot.name());
        let pulses = theirs["pulse"].as_array().unwrap();
        for (j, pulse) in pulses.iter().enumerate() {
            let e = rms(&curve(&ours["pulse"][j]), &curve(pulse));
            assert!(e < 1e-6, "{}: pulse {j} differs by RMS {e:e}", robot.name());
        }
        let e = rms(
            &curve(&ours["drop"]["curve"]),
            &curve(&theirs["drop"]["curve"]),
        );
        assert!(e < 1e-6, "{}: the drop differs by RMS {e:e}", robot.name());
        let (a, b) = (
            ours["drop"]["penetration"].as_f64().unwrap(),
            theirs["drop"]["penetration"].as_f64().unwrap(),
        );
        assert!(
            (a - b).abs() < 1e-6,
            "{}: drop penetration {a} vs {b}",
            robot.name()
        );
    }
}
