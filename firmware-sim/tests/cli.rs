//! The `firmware-sim` binary as a user calls it: `run` with `--task N` and `--task
//! param=VALUE` (what it prints and writes), and `compare` against an export report, with its
//! errors' messages. (`run`'s refusals of a bad `--task` or context have their own tests.)

mod common;
use common::{firmware_sim, run_args, s, tmp};

use std::path::{Path, PathBuf};
use std::process::Output;

use firmware_sim::reference::pd_point_goal_blob;
use infer_core::Quant;
use sim::{DemoDataset, EnvConfig, Family, PointGoalPdExpert, Split, TaskDemos, make_env};

/// What `smile export` writes beside a blob (the typed report firmware-sim reads), with the
/// host's per-task metric `(task value, metric)` and the blob's checksum.
fn export_report(tasks: &[(f64, f32)], blob_sha256: &str) -> String {
    let rows: Vec<sim::TaskResult> = tasks
        .iter()
        .map(|&(value, metric)| sim::TaskResult {
            task: format!("value={value}"),
            value,
            metric,
            by_context_size: vec![metric],
            no_op_rate: None,
        })
        .collect();
    let report = sim::ExportReport {
        bytes: 0,
        blob_sha256: blob_sha256.into(),
        quant: "w8a8".into(),
        edges: None,
        context: None,
        qat_steps: None,
        algo: "scripted-pd".into(),
        env: Family::POINT_GOAL,
        physics: sim::Physics::Rapier,
        parity: sim::Parity {
            contexts: 0,
            actions: 0,
            z_max_abs_diff: 0.0,
            action_max_abs_diff: 0.0,
            action_mean_abs_diff: 0.0,
            action_mean_abs_diff_same_z: 0.0,
        },
        metric: "min distance to goal".into(),
        split: "test".into(),
        metric_blob: 0.0,
        metric_candle: 0.0,
        metric_relative_difference: 0.0,
        per_task_blob: rows.clone(),
        per_task_candle: rows,
    };
    serde_json::to_string_pretty(&report).unwrap()
}

/// Stdout of a successful run (panics with its stderr otherwise).
fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Stderr of a failed run; it must be a clean error exit, not a panic.
fn fails(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "not a clean error exit: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// A fresh directory for the test `name` holding the hand-built PD blob and one PD demo for each
/// of the first `n` test goals: (dir, blob, demos).
fn blob_and_demos(name: &str, n: usize) -> (PathBuf, PathBuf, PathBuf) {
    let dir = tmp(name);
    let fam = Family::POINT_GOAL;
    let mut env = make_env(fam, EnvConfig::default()).unwrap();
    let pd = PointGoalPdExpert::default();
    let mut ds = DemoDataset::new(fam, Split::Test, "scripted-pd");
    for (i, task) in fam.test_tasks().into_iter().take(n).enumerate() {
        let tr = sim::record_trajectory(env.as_mut(), &task, 100 + i as u64, |o, a| {
            pd.act(o, a).unwrap()
        })
        .unwrap();
        ds.tasks.push(TaskDemos {
            task,
            trajectories: vec![tr],
        });
    }
    let demos: Vec<_> = ds.tasks.iter().map(|t| &t.trajectories[0]).collect();
    let blob = pd_point_goal_blob(Quant::W8A8, &demos).unwrap();
    let (blob_path, demos_path) = (dir.join("pd.blob"), dir.join("demos.safetensors"));
    std::fs::write(&blob_path, blob).unwrap();
    ds.write(&demos_path).unwrap();
    (dir, blob_path, demos_path)
}

/// The arguments of `firmware-sim compare` of `blob` on point-goal with `demos`; append the rest.
fn compare_args<'a>(blob: &'a Path, demos: &'a Path) -> Vec<&'a str> {
    let blob = ["compare", "--blob", s(blob), "--env", "point-goal"];
    [&blob[..], &["--contexts", s(demos)]].concat()
}

/// `metric          MinGoalDistance = 0.0123` -> 0.0123.
fn summary_metric(summary: &str) -> f32 {
    let line = summary
        .lines()
        .find(|l| l.starts_with("metric"))
        .unwrap_or_else(|| panic!("no metric line: {summary}"));
    line.rsplit("= ").next().unwrap().trim().parse().unwrap()
}

#[test]
fn run_by_test_index_and_by_parameter_writes_a_trace_of_the_taught_goal() {
    let (dir, blob, demos) = blob_and_demos("run", 6);
    let tasks = Family::POINT_GOAL.test_tasks();
    for (spec, task) in [
        ("3".to_string(), tasks[3]),
        (format!("param={}", tasks[5].value()), tasks[5]),
    ] {
        let out_dir = dir.join(format!("out-{}", spec.replace('=', "-")));
        let faults = ["--ticks", "60", "--link-corrupt", "0.05", "-o", s(&out_dir)];
        let args = [&run_args(&blob, "point-goal", &spec, &demos)[..], &faults].concat();
        let stdout = ok(&firmware_sim(&args));
        let label = task.label();
        assert!(
            stdout.contains(&format!("task            {label} (point-goal)")),
            "--task {spec}: {stdout}"
        );
        assert!(stdout.contains("ticks           60 "), "{stdout}");
        assert!(stdout.contains("faults          0\n"), "{stdout}");
        // The PD blob taught this goal's demo reaches it.
        let metric = summary_metric(&stdout);
        assert!(metric < 0.15, "--task {spec}: min distance {metric}");
        // summary.txt is what was printed; trace.csv has a header and one row per tick.
        let summary = std::fs::read_to_string(out_dir.join("summary.txt")).unwrap();
        assert!(stdout.contains(&summary), "{summary}\nvs\n{stdout}");
        let trace = std::fs::read_to_string(out_dir.join("trace.csv")).unwrap();
        assert!(trace.starts_with("tick,time,obs0"), "{}", &trace[..80]);
        assert_eq!(trace.lines().count(), 1 + 60);
        assert!(
            std::fs::read_to_string(out_dir.join("plot.svg"))
                .unwrap()
                .contains("<svg")
        );
    }

    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn compare_runs_the_reports_tasks_on_the_device() {
    let (dir, blob, demos) = blob_and_demos("compare", 3);
    let tasks = Family::POINT_GOAL.test_tasks();
    let report = export_report(&[(tasks[0].value(), 0.5), (tasks[2].value(), 0.25)], "");
    let mut reference = blob.clone().into_os_string();
    reference.push(".json");
    std::fs::write(&reference, report).unwrap();
    let out_dir = dir.join("cmp");
    let episodes = ["--episodes", "2", "-o", s(&out_dir)];
    let stdout = ok(&firmware_sim(
        &[&compare_args(&blob, &demos)[..], &episodes].concat(),
    ));
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("compare.json")).unwrap())
            .unwrap();
    assert_eq!(rep["metric"], "min distance to goal");
    assert_eq!(rep["episodes_per_task"], 2);
    let rows = rep["tasks"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for (row, (task, host)) in rows.iter().zip([(tasks[0], 0.5), (tasks[2], 0.25)]) {
        assert_eq!(row["task"], task.label());
        assert_eq!(row["host_float"].as_f64().unwrap(), host);
        let device = row["device_blob"].as_f64().unwrap();
        // The PD blob reaches the goal on the device.
        assert!((0.0..0.15).contains(&device), "{row}");
        assert!((row["difference"].as_f64().unwrap() - (device - host)).abs() < 1e-6);
    }
    assert!((rep["host_mean"].as_f64().unwrap() - 0.375).abs() < 1e-6);
    // compare.md is the table printed.
    let md = std::fs::read_to_string(out_dir.join("compare.md")).unwrap();
    assert!(stdout.contains(&md));
    assert!(
        md.contains(&format!("| {} | 0.5000 |", tasks[0].label())) && md.contains("| **mean** |"),
        "{md}"
    );

    // A report whose task has no demo in --contexts (the message names the file), a file that
    // is not an export report, an entry without a metric, and no report at all.
    std::fs::write(&reference, export_report(&[(tasks[7].value(), 0.1)], "")).unwrap();
    let args = [&compare_args(&blob, &demos)[..], &["-o", s(&out_dir)]].concat();
    let err = fails(&firmware_sim(&args));
    assert!(err.contains(s(&demos)), "{err}");
    std::fs::write(&reference, "{\"bytes\": 3}").unwrap();
    let err = fails(&firmware_sim(&args));
    assert!(
        err.contains("is not an export report: missing field"),
        "{err}"
    );
    let without_metric = export_report(&[(0.1, 0.5)], "").replace("\"metric\": 0.5,", "");
    std::fs::write(&reference, without_metric).unwrap();
    let err = fails(&firmware_sim(&args));
    assert!(
        err.contains("is not an export report: missing field `metric`"),
        "{err}"
    );
    let missing = dir.join("none.json");
    let mut with_missing = args.clone();
    with_missing.extend(["--reference", s(&missing)]);
    let err = fails(&firmware_sim(&with_missing));
    assert!(
        err.contains(&missing.display().to_string()) && err.contains("No such file"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 27, items 3, 9 and 11: a report beside another blob (an interrupted re-export) is
/// refused by checksum; ADC settings that panicked, probabilities out of [0, 1], zero or
/// too many ticks and zero episodes are refused at the door, by flag.
#[test]
fn a_report_of_another_blob_and_values_out_of_range_are_refused() {
    let (dir, blob, demos) = blob_and_demos("refuse", 1);
    let task = Family::POINT_GOAL.test_tasks()[0];
    let mut reference = blob.clone().into_os_string();
    reference.push(".json");
    let report = |sha: &str| export_report(&[(task.value(), 0.5)], sha);
    std::fs::write(&reference, report(&"0".repeat(64))).unwrap();
    let cmp = dir.join("cmp");
    let compare = |episodes: &str| {
        let rest = ["--episodes", episodes, "-o", s(&cmp)];
        firmware_sim(&[&compare_args(&blob, &demos)[..], &rest].concat())
    };
    let err = fails(&compare("1"));
    assert!(err.contains("describes another blob"), "{err}");
    let sha = sim::sha256_hex(&std::fs::read(&blob).unwrap());
    std::fs::write(&reference, report(&sha)).unwrap();
    ok(&compare("1"));
    let e = String::from_utf8_lossy(&compare("0").stderr).into_owned();
    assert!(e.contains("--episodes"), "{e}");
    let run_out = dir.join("run");
    let run = |extra: &[&str]| {
        let mut args = run_args(&blob, "point-goal", "0", &demos);
        args.extend(["-o", s(&run_out)]);
        args.extend_from_slice(extra);
        firmware_sim(&args)
    };
    for (bad, flag) in [
        (&["--adc-bits", "12", "--adc-range=-5"][..], "--adc-range"),
        (
            &["--adc-bits", "12", "--adc-range", "NaN"][..],
            "--adc-range",
        ),
        (&["--adc-bits", "0"][..], "--adc-bits"),
        (&["--link-drop", "NaN"][..], "--link-drop"),
        (&["--link-drop=-0.1"][..], "--link-drop"),
        (&["--link-corrupt", "1.5"][..], "--link-corrupt"),
        (&["--ticks", "0"][..], "--ticks"),
        (&["--trajectories", "0"][..], "--trajectories"),
    ] {
        let o = run(bad);
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success() && e.contains(flag), "{bad:?}: {e}");
        assert!(!e.contains("panicked"), "{bad:?}: {e}");
    }
    let e = fails(&run(&["--ticks", "2000000"]));
    assert!(e.contains("2000000 ticks asked"), "{e}");
    // A truncated blob is named as one, not as a device refusal of message N.
    let bytes = std::fs::read(&blob).unwrap();
    std::fs::write(&blob, &bytes[..bytes.len() / 2]).unwrap();
    let e = fails(&run(&[]));
    assert!(
        e.contains("is not a valid policy blob") && !e.contains("BadBlob"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_plant_is_the_blobs_and_demos_of_another_plant_are_refused() {
    let (dir, blob, demos) = blob_and_demos("physics", 1);
    let run = |extra: &[&str]| {
        let out = dir.join("out");
        let mut args = run_args(&blob, "point-goal", "0", &demos);
        args.extend(["--ticks", "5", "-o", s(&out)]);
        args.extend_from_slice(extra);
        firmware_sim(&args)
    };
    // A report beside the blob that names another plant than --physics: refused.
    let on_mujoco =
        export_report(&[], "").replace(r#""physics": "rapier""#, r#""physics": "mujoco""#);
    std::fs::write(dir.join("pd.blob.json"), on_mujoco).unwrap();
    let err = fails(&run(&["--physics", "rapier"]));
    assert!(err.contains("trained on the mujoco plant"), "{err}");
    std::fs::remove_file(dir.join("pd.blob.json")).unwrap();
    // Demos of another plant: refused with the plant named.
    let mut ds = DemoDataset::read(&demos).unwrap();
    ds.physics = sim::Physics::Mujoco;
    ds.write(&demos).unwrap();
    let err = fails(&run(&[]));
    assert!(err.contains("recorded on the mujoco plant"), "{err}");
    // point-goal is Rapier's alone, with or without the MuJoCo backend built in.
    let err = fails(&run(&["--physics", "mujoco"]));
    assert!(err.contains("no MuJoCo model"), "{err}");
}

/// Issue 57, items 5, 7 and 10: a blob whose report names another family is refused by `run`
/// and `compare` alike, with the family it is; `--horizon 0` and more `--trajectories` than
/// the context file holds are refused by name, not run as one tick or clamped.
#[test]
fn a_blob_of_another_family_and_counts_that_cannot_run_are_refused() {
    let (dir, blob, demos) = blob_and_demos("family", 1);
    let task = Family::POINT_GOAL.test_tasks()[0];
    let sha = sim::sha256_hex(&std::fs::read(&blob).unwrap());
    std::fs::write(
        dir.join("pd.blob.json"),
        export_report(&[(task.value(), 0.5)], &sha),
    )
    .unwrap();
    let out = dir.join("out");
    let mut args = run_args(&blob, "cheetah-vel", "0", &demos);
    args.extend(["-o", s(&out)]);
    let err = fails(&firmware_sim(&args));
    assert!(
        err.contains("is a point-goal policy") && err.contains("--env is cheetah-vel"),
        "{err}"
    );
    let mut cmp = compare_args(&blob, &demos);
    cmp[4] = "cheetah-vel";
    let err = fails(&firmware_sim(&[&cmp[..], &["-o", s(&out)]].concat()));
    assert!(err.contains("is a point-goal policy"), "{err}");
    let run = |extra: &[&str]| {
        let mut args = run_args(&blob, "point-goal", "0", &demos);
        args.extend(["-o", s(&out)]);
        args.extend_from_slice(extra);
        firmware_sim(&args)
    };
    let e = String::from_utf8_lossy(&run(&["--horizon", "0"]).stderr).into_owned();
    assert!(e.contains("--horizon") && !e.contains("panicked"), "{e}");
    // Values no run can mean are refused by the parser, naming the flag (issue 72, item 3).
    for (flag, value) in [
        ("--rate", "0"),
        ("--rate", "NaN"),
        ("--rate", "-10"),
        ("--budget-us", "NaN"),
        ("--budget-us", "-1"),
        ("--horizon", "18446744073709551615"),
        ("--flash-kib", "99999999"),
        ("--ram-kib", "0"),
    ] {
        let out = run(&[&format!("{flag}={value}")]);
        let e = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {e}");
        assert!(
            e.contains(flag) && !e.contains("panicked"),
            "{flag} {value}: {e}"
        );
    }
    let e = fails(&run(&["--trajectories", "5"]));
    assert!(
        e.contains("--trajectories 5") && e.contains("holds 1 demo"),
        "{e}"
    );
    ok(&run(&["--ticks", "3"]));
    // An export interrupted between its blob and its report leaves the old report: `run`
    // refuses the pair as `compare` does (issue 57, item 3).
    std::fs::write(
        dir.join("pd.blob.json"),
        export_report(&[(task.value(), 0.5)], &"0".repeat(64)),
    )
    .unwrap();
    let e = fails(&run(&[]));
    assert!(e.contains("describes another blob"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
