//! Shared by the trainer's integration tests.
#![allow(dead_code)]

use std::process::{Command, Output};

use sim::{DemoDataset, EnvConfig, Family, Split, Task, TaskDemos};

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

/// Asserts that a `smile` run succeeded (printing its output if not); returns its stderr.
pub fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "stdout: {}\nstderr: {err}",
        String::from_utf8_lossy(&out.stdout)
    );
    err
}

/// `per_task` scripted-PD point-goal demos of `horizon` steps for each of `tasks` (reset seeds
/// 0, 1, ...), labelled `split`.
pub fn pd_demos(split: Split, tasks: Vec<Task>, per_task: usize, horizon: usize) -> DemoDataset {
    let fam = Family::PointGoal;
    let mut ds = DemoDataset::new(fam, split, "scripted-pd");
    let env_config = EnvConfig {
        horizon: Some(horizon),
        ..EnvConfig::default()
    };
    let mut env = sim::make_env(fam, env_config).unwrap();
    let pd = sim::PointGoalPdExpert::default();
    for task in tasks {
        let trajectories = (0..per_task)
            .map(|j| {
                sim::record_trajectory(env.as_mut(), &task, j as u64, |o, a| pd.act(o, a).unwrap())
                    .unwrap()
            })
            .collect();
        ds.tasks.push(TaskDemos { task, trajectories });
    }
    ds
}

/// One `horizon`-step trajectory of a fixed open-loop action (0.1 everywhere) per task of
/// `family`, labelled `split`: "demos" whose family, split and shapes are all that matter.
pub fn open_loop_demos(
    family: Family,
    split: Split,
    tasks: Vec<Task>,
    horizon: usize,
) -> DemoDataset {
    let mut ds = DemoDataset::new(family, split, "open-loop");
    let env_config = EnvConfig {
        horizon: Some(horizon),
        ..EnvConfig::default()
    };
    let mut env = sim::make_env(family, env_config).unwrap();
    for task in tasks {
        let tr = sim::record_trajectory(env.as_mut(), &task, 0, |_, a| a.fill(0.1)).unwrap();
        ds.tasks.push(TaskDemos {
            task,
            trajectories: vec![tr],
        });
    }
    ds
}

/// Meta-train demos of the first `tasks` point-goal train goals.
pub fn train_demos(tasks: usize, per_task: usize, horizon: usize) -> DemoDataset {
    pd_demos(
        Split::Train,
        Family::PointGoal
            .train_tasks()
            .into_iter()
            .take(tasks)
            .collect(),
        per_task,
        horizon,
    )
}

/// Point-goal PD demo files in `dir`: `train.safetensors` (8 meta-train tasks x 2 demos of 20
/// steps) and `test.safetensors` (every meta-test task x 1); returns (train, test).
pub fn point_goal_demo_files(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let fam = Family::PointGoal;
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
    ok(&smile(&[
        "train",
        "--algo",
        "meta-bc",
        "--demos",
        s(train),
        "-o",
        s(run),
        "--updates",
        "20",
        "--eval-every",
        "10",
        "--hidden",
        "8,8",
        "--quiet",
    ]));
}
