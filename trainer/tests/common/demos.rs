//! Demo fixtures shared by the trainer's and the app's integration tests (the app's
//! `tests/common` includes this file).
#![allow(dead_code)]

use sim::{DemoDataset, EnvConfig, Family, Split, Task, TaskDemos};

/// `per_task` scripted-PD point-goal demos of `horizon` steps for each of `tasks` (reset seeds
/// 0, 1, ...), labelled `split`.
pub fn pd_demos(split: Split, tasks: Vec<Task>, per_task: usize, horizon: usize) -> DemoDataset {
    let fam = Family::POINT_GOAL;
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
        Family::POINT_GOAL
            .train_tasks()
            .into_iter()
            .take(tasks)
            .collect(),
        per_task,
        horizon,
    )
}
