//! The `firmware-sim` binary called as a user calls it: `--task param=VALUE` names a task within
//! sim's tolerance (and says which demo it used), `--task N` out of range gives the valid range,
//! and every refusal is one `error:` line that says what to do, with exit status 1.

mod common;
use common::{firmware_sim, one_line_error, s, tmp};

use std::path::{Path, PathBuf};
use std::process::Output;

use firmware_sim::reference;
use infer_core::{Dims, FloatModel, ModelKind, Quant, write_blob};
use sim::{
    DemoDataset, EnvConfig, Family, PointGoalPdExpert, Split, TaskDemos, make_env,
    record_trajectory,
};

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The reference point-goal blob and one short PD demo per point-goal test goal.
fn point_goal_files(dir: &Path) -> (PathBuf, PathBuf) {
    let family = Family::POINT_GOAL;
    let mut env = make_env(family, EnvConfig::default()).unwrap();
    let expert = PointGoalPdExpert::default();
    let mut demos = DemoDataset::new(family, Split::Test, "scripted-pd");
    for task in family.test_tasks() {
        let demo =
            record_trajectory(env.as_mut(), &task, 1, |o, a| expert.act(o, a).unwrap()).unwrap();
        demos.tasks.push(TaskDemos {
            task,
            trajectories: vec![demo],
        });
    }
    let recorded: Vec<_> = demos.tasks.iter().map(|t| &t.trajectories[0]).collect();
    let blob = reference::pd_point_goal_blob(Quant::F32, &recorded).unwrap();
    let (blob_path, demo_path) = (dir.join("pd.blob"), dir.join("pg-test.safetensors"));
    std::fs::write(&blob_path, blob).unwrap();
    demos.write(&demo_path).unwrap();
    (blob_path, demo_path)
}

/// A random (untrained) cheetah-vel blob and 10-step demos of the first 5 cheetah test tasks.
fn cheetah_files(dir: &Path) -> (PathBuf, PathBuf) {
    let family = Family::CHEETAH_VEL;
    let dims = Dims {
        obs: family.obs_dim(),
        act: family.act_dim(),
        r: 4,
        z: 2,
        hidden: 8,
    };
    let model = FloatModel::random(ModelKind::StateAction, dims, 1);
    let blob = write_blob(&model, Quant::F32, &Default::default()).unwrap();
    let cfg = EnvConfig {
        horizon: Some(10),
        ..EnvConfig::default()
    };
    let mut env = make_env(family, cfg).unwrap();
    let mut demos = DemoDataset::new(family, Split::Test, "open-loop");
    for task in family.test_tasks().into_iter().take(5) {
        let tr = record_trajectory(env.as_mut(), &task, 0, |_, a| a.fill(0.1)).unwrap();
        demos.tasks.push(TaskDemos {
            task,
            trajectories: vec![tr],
        });
    }
    let (blob_path, demo_path) = (dir.join("cv.blob"), dir.join("cv-test.safetensors"));
    std::fs::write(&blob_path, blob).unwrap();
    demos.write(&demo_path).unwrap();
    (blob_path, demo_path)
}

fn run(blob: &Path, env: &str, task: &str, context: &Path, out: &Path) -> Output {
    let ticks = ["--ticks", "5", "-o", s(out)];
    firmware_sim(&[&common::run_args(blob, env, task, context)[..], &ticks].concat())
}

#[test]
fn task_param_matches_the_label_value_and_says_which_demo_it_used() {
    let dir = tmp("param");
    let (blob, demos) = point_goal_files(&dir);
    // Test goal 1 is 0.490874 rad; the file lists it as goal_angle=0.4909.
    let out = run(&blob, "point-goal", "param=0.4909", &demos, &dir.join("a"));
    let text = stdout(&out);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("goal_angle=0.4909 (--task param=0.4909; value 0.49087")
            && text.contains(s(&demos)),
        "{text}"
    );
    assert!(dir.join("a/trace.csv").exists());
    // The same task by index says the same.
    let out = run(&blob, "point-goal", "1", &demos, &dir.join("b"));
    assert!(
        stdout(&out).contains("goal_angle=0.4909 (--task 1;"),
        "{out:?}"
    );

    // Far from every demo: one line naming the flag, the file and the available values.
    let line = one_line_error(&run(
        &blob,
        "point-goal",
        "param=0.5",
        &demos,
        &dir.join("c"),
    ));
    assert!(line.contains(&format!("--context {}", s(&demos))), "{line}");
    assert!(line.contains("within 0.001 of 0.5"), "{line}");
    assert!(line.contains("available: 0.0982, 0.4909, 0.8836"), "{line}");
    assert!(
        !dir.join("c").exists(),
        "a refused run wrote its output directory"
    );
}

#[test]
fn cheetah_param_0_35_matches_like_0_25() {
    let dir = tmp("cheetah");
    let (blob, demos) = cheetah_files(&dir);
    for (param, label) in [
        ("0.25", "target_velocity=0.25"),
        ("0.35", "target_velocity=0.35"),
    ] {
        let out = run(
            &blob,
            "cheetah-vel",
            &format!("param={param}"),
            &demos,
            &dir.join(param),
        );
        let text = stdout(&out);
        assert!(
            out.status.success(),
            "{param}: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(text.contains(label), "{text}");
    }
}

#[test]
fn refusals_are_one_line_that_says_what_to_do() {
    let dir = tmp("refusals");
    let (blob, demos) = point_goal_files(&dir);
    let (cheetah_blob, cheetah_demos) = cheetah_files(&dir);
    let out = dir.join("out");

    let line = one_line_error(&run(&blob, "point-goal", "99", &demos, &out));
    assert!(
        line.contains("--task 99") && line.contains("0..=15"),
        "{line}"
    );

    // A missing context file: named once, with the OS error once.
    let gone = dir.join("gone.safetensors");
    let line = one_line_error(&run(&blob, "point-goal", "0", &gone, &out));
    assert!(line.contains(&format!("--context {}", s(&gone))), "{line}");
    assert_eq!(line.matches(s(&gone)).count(), 1, "{line}");
    assert_eq!(line.matches("No such file").count(), 1, "{line}");

    // A missing blob: the flag, the file and the OS error once.
    let missing = dir.join("missing.blob");
    let line = one_line_error(&run(&missing, "point-goal", "0", &demos, &out));
    assert!(line.contains(&format!("--blob {}", s(&missing))), "{line}");
    assert_eq!(line.matches("No such file").count(), 1, "{line}");

    // Demos of another family than --env: the file, the flag and the --env to pass.
    let line = one_line_error(&run(&blob, "cheetah-vel", "0", &demos, &out));
    assert!(
        line.contains(&format!("--context {}", s(&demos)))
            && line.contains("holds point-goal demos")
            && line.contains("--env point-goal"),
        "{line}"
    );

    // A blob of another family than the plant: the --env it was made for.
    let line = one_line_error(&run(&blob, "cheetah-vel", "0", &cheetah_demos, &out));
    assert!(line.contains("pass --env point-goal"), "{line}");
    let line = one_line_error(&run(&cheetah_blob, "point-goal", "0", &demos, &out));
    assert!(
        line.contains("pass --env cheetah-vel or --env walker-dyn"),
        "{line}"
    );
    assert!(!out.exists(), "a refused run wrote its output directory");
}

#[test]
fn the_command_pd_blob_prints_runs_the_device() {
    let dir = tmp("pd-blob");
    let (blob, demos) = point_goal_files(&dir);
    let args = reference::pd_run_args(&blob, &demos, &dir.join("device"));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = firmware_sim(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout(&out).contains("goal_angle=1.2763"),
        "{}",
        stdout(&out)
    );
    assert!(dir.join("device/summary.txt").exists());
}
