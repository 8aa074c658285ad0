//! Shared by firmware-sim's integration tests: temp directories, the binary, its output
//! checks, and point-goal PD demos.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub mod hil;

// The run checks are shared with the app's tests (they include output.rs by path).
mod output;
#[allow(unused_imports)] // not every test binary checks a run
pub use output::{ok, one_line_error};

use sim::{EnvConfig, Family, PointGoalPdExpert, Task, Trajectory, make_env, record_trajectory};

/// A new, empty directory `<temp>/fwsim-cli-<name>-<pid>`.
pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fwsim-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as a `&str` argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs the `firmware-sim` binary built for these tests (no backtraces asked for).
pub fn firmware_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_firmware-sim"))
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("run firmware-sim")
}

/// One point-goal demo of `task` by the scripted PD expert from reset seed `seed`.
pub fn pd_demo(task: &Task, seed: u64) -> Trajectory {
    let mut env = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let expert = PointGoalPdExpert::default();
    record_trajectory(env.as_mut(), task, seed, |oracle, action| {
        expert.act(oracle, action).unwrap()
    })
    .unwrap()
}

/// The arguments of `firmware-sim run` of `blob` on `env`'s task `task` taught by `context`;
/// append the rest.
pub fn run_args<'a>(
    blob: &'a Path,
    env: &'a str,
    task: &'a str,
    context: &'a Path,
) -> Vec<&'a str> {
    let blob = ["run", "--blob", s(blob), "--env", env];
    [&blob[..], &["--task", task, "--context", s(context)]].concat()
}
