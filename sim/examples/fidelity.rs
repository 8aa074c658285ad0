//! The Rapier side of the plant-fidelity probe (`docs/FIDELITY.md`):
//! `cargo run --release -p sim --example fidelity -- --family cheetah --json OUT [--seeds 30]`;
//! with `--features mujoco` and `--physics mujoco`, the same probe on the MuJoCo backend.
//! Compare with the MuJoCo twin: `python3 docs/scripts/fidelity_table.py MUJOCO.json OUT`.

use std::process::ExitCode;

use sim::fidelity::{ProbeConfig, Robot, probe};

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let (mut robot, mut out, mut config) = (None, None, ProbeConfig::default());
    let mut physics = sim::Physics::Rapier;
    while let Some(flag) = args.next() {
        let value = args.next();
        let parsed = match (flag.as_str(), value) {
            ("--family", Some(v)) => v.parse().map(|r| robot = Some(r)),
            ("--physics", Some(v)) => v
                .parse()
                .map(|p| physics = p)
                .map_err(|e: sim::SimError| e.to_string()),
            ("--json", Some(v)) => {
                out = Some(v);
                Ok(())
            }
            ("--seeds", Some(v)) => v
                .parse()
                .map(|n| config.seeds = n)
                .map_err(|e| format!("--seeds: {e}")),
            (flag, _) => Err(format!("unknown flag or missing value: {flag}")),
        };
        if let Err(message) = parsed {
            eprintln!("error: {message}");
            return ExitCode::from(2);
        }
    }
    let Some(robot): Option<Robot> = robot else {
        eprintln!("usage: fidelity --family cheetah|walker|ant [--json OUT] [--seeds N]");
        return ExitCode::from(2);
    };
    let report = match physics {
        sim::Physics::Rapier => probe(robot, &config),
        #[cfg(feature = "mujoco")]
        sim::Physics::Mujoco => sim::fidelity::probe_mujoco(robot, &config),
        #[cfg(not(feature = "mujoco"))]
        other => {
            eprintln!("error: {}", other.ensure_available().unwrap_err());
            return ExitCode::from(2);
        }
    };
    let text = serde_json::to_string_pretty(&report).expect("a JSON value serialises");
    match out {
        Some(path) => {
            let tmp = format!("{path}.tmp");
            if let Err(e) = std::fs::write(&tmp, &text).and_then(|()| std::fs::rename(&tmp, &path))
            {
                let _ = std::fs::remove_file(&tmp);
                eprintln!("error: writing {path}: {e}");
                return ExitCode::FAILURE;
            }
        }
        None => println!("{text}"),
    }
    ExitCode::SUCCESS
}
