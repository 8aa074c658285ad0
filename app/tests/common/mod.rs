//! Shared by the app's integration tests: the `smile` binary, run directories, demo files.
#![allow(dead_code)]

use std::process::{Command, Output};

use sim::{Family, Split};

// The demo fixtures are the trainer's (one definition for both crates' tests).
#[path = "../../../trainer/tests/common/demos.rs"]
mod demos;

pub use demos::*;

// The run checks are firmware-sim's test helpers (one definition for both binaries).
#[path = "../../../firmware-sim/tests/common/output.rs"]
mod output;
#[allow(unused_imports)] // not every test binary checks a run
pub use output::{ok, one_line_error};

/// A new, empty directory `<temp>/<prefix>-<name>-<pid>` (removed first if a previous run left
/// it behind).
pub fn fresh_dir(prefix: &str, name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("{prefix}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as a `&str` argument.
pub fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

/// Runs the `smile` binary built for these tests.
pub fn smile(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smile"))
        .args(args)
        .output()
        .expect("run smile")
}

/// Point-goal PD demo files in `dir`: `train.safetensors` (8 meta-train tasks x 2 demos of 20
/// steps) and `test.safetensors` (every meta-test task x 1); returns (train, test).
pub fn point_goal_demo_files(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let fam = Family::POINT_GOAL;
    let (train, test) = (dir.join("train.safetensors"), dir.join("test.safetensors"));
    pd_demos(Split::Train, fam.train_tasks()[..8].to_vec(), 2, 20)
        .write(&train)
        .unwrap();
    pd_demos(Split::Test, fam.test_tasks(), 1, 20)
        .write(&test)
        .unwrap();
    (train, test)
}

/// A finished 20-step Meta-BC run in `run`.
pub fn tiny_bc(train: &std::path::Path, run: &std::path::Path) {
    let tail = [
        "--updates",
        "20",
        "--eval-every",
        "10",
        "--hidden",
        "8,8",
        "--quiet",
    ];
    ok(&smile(&[&meta_bc_args(train, run)[..], &tail].concat()));
}

/// `smile expert` for a tiny per-task point-goal SAC expert of task `value` into `run` (40 env
/// steps, 8 x 8 nets, one evaluation episode); returns its stderr.
pub fn tiny_per_task_expert(value: &str, run: &std::path::Path) -> String {
    ok(&smile(&[
        "expert",
        "--env",
        "point-goal",
        "--task-value",
        value,
        "--total-steps",
        "40",
        "--learning-starts",
        "20",
        "--horizon",
        "20",
        "--hidden",
        "8,8",
        "--batch-size",
        "8",
        "-o",
        s(run),
        "--quiet",
        "--eval-episodes",
        "1",
    ]))
}

/// The arguments of `smile train --algo meta-bc` on `train` into `run`; append the rest.
pub fn meta_bc_args<'a>(train: &'a std::path::Path, run: &'a std::path::Path) -> Vec<&'a str> {
    [&train_args("meta-bc", train)[..], &["-o", s(run)]].concat()
}

/// The arguments of `smile train --algo <algo>` on `demos`; append the rest.
pub fn train_args<'a>(algo: &'a str, demos: &'a std::path::Path) -> Vec<&'a str> {
    vec!["train", "--algo", algo, "--demos", s(demos)]
}

/// The arguments of `smile train --resume` of `run` on `train`; append the rest.
pub fn resume_args<'a>(train: &'a std::path::Path, run: &'a std::path::Path) -> Vec<&'a str> {
    vec!["train", "--resume", "--demos", s(train), "-o", s(run)]
}

/// The arguments of `smile eval` of `policy` on `contexts` into `out`, one rollout, quiet;
/// append the rest.
pub fn eval_args<'a>(
    policy: &'a std::path::Path,
    contexts: &'a std::path::Path,
    out: &'a std::path::Path,
) -> Vec<&'a str> {
    vec![
        "eval",
        "--policy",
        s(policy),
        "--contexts",
        s(contexts),
        "-o",
        s(out),
        "--rollouts",
        "1",
        "--quiet",
    ]
}

/// `smile expert --kind scripted-pd` for point-goal into `dir` (the scripted PD expert);
/// returns `dir`.
pub fn scripted_pd_expert(dir: std::path::PathBuf) -> std::path::PathBuf {
    let kind = ["--env", "point-goal", "--kind", "scripted-pd"];
    ok(&smile(&[&["expert"][..], &kind, &["-o", s(&dir)]].concat()));
    dir
}

/// The arguments of `smile export` of `policy` at `quant` with `contexts`; append the rest.
pub fn export_args<'a>(
    policy: &'a std::path::Path,
    quant: &'a str,
    contexts: &'a std::path::Path,
) -> Vec<&'a str> {
    let policy = ["export", "--policy", s(policy)];
    [&policy[..], &["--quant", quant, "--contexts", s(contexts)]].concat()
}

/// The arguments of `smile demos --env point-goal` with `options`, from `expert` into `out`.
pub fn point_goal_demos_args<'a>(
    options: &[&'a str],
    expert: &'a str,
    out: &'a str,
) -> Vec<&'a str> {
    let env = ["demos", "--env", "point-goal"];
    [&env[..], options, &["--expert", expert, "-o", out]].concat()
}

/// The tiny SMILe and Meta-BC configurations the CLI tests train with (widths 16 and 8, four
/// tasks a batch, 20-step episodes, one evaluation episode), sharing one context encoder; a
/// test sets its budget and cadence on them.
pub fn tiny_meta_configs() -> (trainer::smile::SmileConfig, trainer::meta_bc::MetaBcConfig) {
    let mut sc = trainer::smile::SmileConfig {
        disc_hidden: vec![16, 16],
        tasks_per_batch: 4,
        disc_per_task: 16,
        sac_per_task: 16,
        rollouts_per_iter: 1,
        updates_per_iter: 10,
        holdout_every: 4,
        eval_episodes: 1,
        horizon: Some(20),
        ..Default::default()
    };
    sc.sac.hidden = vec![16, 16];
    sc.context.enc_hidden = vec![8];
    sc.context.r_dim = 4;
    sc.context.z_dim = 2;
    let bc = trainer::meta_bc::MetaBcConfig {
        policy_hidden: vec![16, 16],
        tasks_per_batch: 4,
        per_task: 16,
        holdout_every: 4,
        eval_episodes: 1,
        horizon: Some(20),
        context: sc.context.clone(),
        ..Default::default()
    };
    (sc, bc)
}
