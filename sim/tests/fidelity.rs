//! Holds the Rapier robots within the band of MuJoCo's own figures (`docs/FIDELITY.md`): the
//! probe runs on 30 seeds here, as `docs/scripts/fidelity_mujoco.py` did for the committed
//! `docs/fidelity/mujoco-*.json`. A change that calms a plant, stiffens its joints or changes
//! its contacts fails here.
//!
//! Held: the figures inside the band today, less those that MuJoCo itself does not repeat
//! within 25% with another random stream (found by running the MuJoCo probe against itself),
//! and one-sided liveliness guards on the divergence rates where Rapier is livelier than
//! MuJoCo (a plant may become as calm as MuJoCo's, not calmer).

use std::path::Path;

use serde_json::Value;
use sim::fidelity::{ProbeConfig, Robot, probe};

fn mujoco(robot: Robot) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../docs/fidelity")
        .join(format!("mujoco-{}.json", robot.name()));
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (the committed MuJoCo figures)", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn at<'a>(doc: &'a Value, path: &str) -> &'a Value {
    path.split('/')
        .fold(doc, |v, key| match key.parse::<usize>() {
            Ok(i) if v.is_array() => &v[i],
            _ => &v[key],
        })
}

fn number(doc: &Value, path: &str) -> f64 {
    at(doc, path)
        .as_f64()
        .unwrap_or_else(|| panic!("{path} is not a number in {doc}"))
}

/// The absolute floor of a scalar figure's band (as `docs/scripts/fidelity_table.py`).
fn floor(path: &str) -> f64 {
    let key = path.rsplit('/').next().unwrap_or(path);
    match key {
        k if k.contains("speed") => 0.05,
        "flips" | "falls" => 1.0,
        "rate" => 0.2,
        k if k.starts_with("steps") || k == "fall_step" => 5.0,
        k if k.contains("penetration") => 0.005,
        "limit_overshoot" | "pitch_rms" | "track_rms" => 0.02,
        _ => 0.0,
    }
}

/// A figure of the band: a curve (RMS / swing <= 0.10), a scalar (within 25% or its floor),
/// or a one-sided liveliness guard (at least 75% of MuJoCo's rate).
#[derive(Clone, Copy)]
enum Check<'a> {
    Curve(&'a str),
    Scalar(&'a str),
    AtLeast(&'a str),
}

use Check::{AtLeast, Scalar};

/// Holds `checks`, and with `pulses` every joint's pulse curve.
fn hold(robot: Robot, pulses: bool, checks: &[Check]) {
    let reference = mujoco(robot);
    let ours = probe(robot, &ProbeConfig::default());
    let mut failures = Vec::new();
    let joints = if pulses {
        at(&reference, "pulse").as_array().map_or(0, Vec::len)
    } else {
        0
    };
    let curves: Vec<String> = (0..joints).map(|j| format!("pulse/{j}")).collect();
    let curve_checks = curves.iter().map(|path| Check::Curve(path.as_str()));
    for check in curve_checks.chain(checks.iter().copied()) {
        match check {
            Check::Curve(path) => {
                let (m, r) = (at(&reference, path), at(&ours, path));
                let m: Vec<f64> = m
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter_map(Value::as_f64)
                    .collect();
                let r: Vec<f64> = r
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter_map(Value::as_f64)
                    .collect();
                assert_eq!(m.len(), r.len(), "{path}: curve lengths");
                let swing = m.iter().copied().fold(f64::MIN, f64::max)
                    - m.iter().copied().fold(f64::MAX, f64::min);
                let rms = (m.iter().zip(&r).map(|(a, b)| (a - b).powi(2)).sum::<f64>()
                    / m.len() as f64)
                    .sqrt();
                if rms / swing > 0.10 {
                    failures.push(format!("{path}: RMS / swing {:.3} > 0.10", rms / swing));
                }
            }
            Check::Scalar(path) => {
                let (m, r) = (number(&reference, path), number(&ours, path));
                let band = (0.25 * m.abs()).max(floor(path));
                if (r - m).abs() > band {
                    failures.push(format!(
                        "{path}: rapier {r:.4}, mujoco {m:.4}, band {band:.4}"
                    ));
                }
            }
            Check::AtLeast(path) => {
                let (m, r) = (number(&reference, path), number(&ours, path));
                if r < 0.75 * m {
                    failures.push(format!("{path}: rapier {r:.4} < 0.75 x mujoco {m:.4}"));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} outside MuJoCo's band:\n{}",
        robot.name(),
        failures.join("\n")
    );
}

#[test]
fn the_cheetah_responds_like_mujocos() {
    hold(
        Robot::Cheetah,
        true,
        &[
            Scalar("drop/min"),
            Scalar("drop/final"),
            Scalar("drop/penetration"),
            Scalar("divergence/random/steps_0_1"),
            Scalar("open_loop/limit_overshoot"),
            Scalar("closed_loop/0/speed"),
            Scalar("closed_loop/0/track_rms"),
            Scalar("closed_loop/0.1/speed"),
            Scalar("closed_loop/0.1/track_rms"),
            Scalar("closed_loop/0.3/track_rms"),
            AtLeast("divergence/random/rate"),
            AtLeast("divergence/trot/rate"),
        ],
    );
}

#[test]
fn the_walker_responds_like_mujocos() {
    hold(
        Robot::Walker,
        true,
        &[
            Scalar("drop/min"),
            Scalar("drop/final"),
            Scalar("open_loop/falls"),
            Scalar("open_loop/fall_step"),
            Scalar("divergence/random/rate"),
            Scalar("closed_loop/0/speed"),
            Scalar("closed_loop/0/pitch_rms"),
            Scalar("closed_loop/0/track_rms"),
            Scalar("closed_loop/0.1/speed"),
            Scalar("closed_loop/0.1/pitch_rms"),
            Scalar("closed_loop/0.1/track_rms"),
            Scalar("closed_loop/0.3/pitch_rms"),
            AtLeast("divergence/zero/rate"),
            AtLeast("divergence/trot/rate"),
        ],
    );
}

#[test]
fn the_ant_responds_like_mujocos() {
    hold(
        Robot::Ant,
        false,
        &[
            Scalar("divergence/trot/steps_0_1"),
            Scalar("divergence/trot/rate"),
            Scalar("divergence/random/steps_0_1"),
            Scalar("divergence/random/steps_1"),
            Scalar("divergence/random/rate"),
            Scalar("open_loop/flips"),
            Scalar("open_loop/limit_overshoot"),
            Scalar("drop/min"),
            Scalar("drop/final"),
            Scalar("closed_loop/0/speed"),
            Scalar("closed_loop/0.1/speed"),
        ],
    );
}

#[test]
fn the_probe_is_deterministic() {
    let config = ProbeConfig {
        seeds: 2,
        steps: 40,
    };
    assert_eq!(
        probe(Robot::Cheetah, &config),
        probe(Robot::Cheetah, &config)
    );
}
