//! A task named by its parameter, called as a user calls `smile`: the value read off a label
//! (`goal_angle=0.4909` for test goal 0.490874) names that task in `smile demos --task-params`,
//! `smile expert --task-value` (and so in the per-task expert lookup of `smile demos`), and the
//! contexts lookup of `smile eval`; the commands say which task they matched.

mod common;
use common::{ok, smile};

use std::path::PathBuf;

use sim::{DemoDataset, Family, Split, Task};

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-cli-tasks", name)
}

use common::s;

/// Test goal 1 (0.490874 rad) as its label prints it.
const LABEL_VALUE: &str = "0.4909";

#[test]
fn demos_task_params_and_per_task_experts_match_a_label_value() {
    let dir = tmp("demos");
    let goal = Family::POINT_GOAL.test_tasks()[1];
    assert_eq!(goal.label(), format!("goal_angle={LABEL_VALUE}"));

    let pd = dir.join("pd");
    ok(&smile(&[
        "expert",
        "--kind",
        "scripted-pd",
        "-o",
        s(&pd),
        "--eval-episodes",
        "1",
    ]));
    let demos = dir.join("new.safetensors");
    let params = format!("{LABEL_VALUE},0.3");
    let options = [
        "--task-params",
        &params,
        "--per-task",
        "1",
        "--horizon",
        "20",
    ];
    let err = ok(&smile(&common::point_goal_demos_args(
        &options,
        s(&pd),
        s(&demos),
    )));
    // The stored task is the test task itself, not a neighbour 2.6e-5 rad away; 0.3 is new.
    let ds = DemoDataset::read(&demos).unwrap();
    assert_eq!(ds.tasks[0].task, goal, "{err}");
    assert_eq!(ds.tasks[1].task, Task::point_goal(0.3));
    assert!(
        err.contains(&format!(
            "--task-params {LABEL_VALUE}: the test task goal_angle=0.4909 (value 0.49087"
        )),
        "{err}"
    );

    // A per-task expert trained with --task-value 0.4909 is the one used in that test task.
    let per_task = dir.join("per-task");
    let err = common::tiny_per_task_expert(LABEL_VALUE, &per_task);
    assert!(
        err.contains("a per-task expert on goal_angle=0.4909 (value 0.49087"),
        "{err}"
    );
    let test_demos = dir.join("test.safetensors");
    let experts = format!("{},{}", s(&per_task), s(&pd));
    let options = ["--split", "test", "--per-task", "1", "--horizon", "20"];
    let err = ok(&smile(&common::point_goal_demos_args(
        &options,
        &experts,
        s(&test_demos),
    )));
    assert!(
        err.contains(&format!(
            "goal_angle=0.4909: expert {} (trained on goal_angle=0.4909)",
            s(&per_task)
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!(
            "goal_angle=0.0982: expert {} (general expert)",
            s(&pd)
        )),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn eval_finds_contexts_recorded_at_label_values() {
    let dir = tmp("eval");
    let fam = Family::POINT_GOAL;
    let train = dir.join("train.safetensors");
    common::pd_demos(Split::Train, fam.train_tasks()[..6].to_vec(), 2, 20)
        .write(&train)
        .unwrap();
    // Contexts recorded at the 4-decimal values of the labels (as a user's --task-params
    // recorded them before), not the exact test goals.
    let rounded: Vec<Task> = fam
        .test_tasks()
        .iter()
        .map(|t| Task::point_goal((t.value() * 1e4).round() as f32 / 1e4))
        .collect();
    assert_ne!(rounded[1], fam.test_tasks()[1]);
    let contexts = dir.join("contexts.safetensors");
    common::pd_demos(Split::Test, rounded, 1, 20)
        .write(&contexts)
        .unwrap();
    let run = dir.join("bc");
    let tail = [
        "--updates",
        "20",
        "--eval-every",
        "0",
        "--hidden",
        "8,8",
        "--quiet",
    ];
    ok(&smile(
        &[&common::meta_bc_args(&train, &run)[..], &tail].concat(),
    ));
    let out = dir.join("eval");
    ok(&smile(&[
        "eval",
        "--policy",
        s(&run),
        "--contexts",
        s(&contexts),
        "--rollouts",
        "1",
        "--horizon",
        "10",
        "-o",
        s(&out),
        "--quiet",
    ]));
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(rep["methods"][0]["tasks"].as_array().unwrap().len(), 16);
    std::fs::remove_dir_all(&dir).ok();
}
