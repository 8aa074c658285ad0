//! `smile train | eval | export` end to end on tiny budgets, and the held-out rule: the train
//! command refuses meta-test demos.

mod common;
use common::{ok, smile};

use std::path::PathBuf;

use sim::{Family, Split};
use trainer::sac::SacConfig;

fn demos(split: Split, tasks: Vec<sim::Task>, path: &std::path::Path) {
    common::pd_demos(split, tasks, 2, 20).write(path).unwrap();
}

#[test]
fn train_eval_export_and_refuse_meta_test_data() {
    let dir: PathBuf = std::env::temp_dir().join(format!("smile-cli-meta-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let fam = Family::POINT_GOAL;
    let (train, test) = (dir.join("train.safetensors"), dir.join("test.safetensors"));
    demos(Split::Train, fam.train_tasks()[..8].to_vec(), &train);
    demos(Split::Test, fam.test_tasks(), &test);
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    // `smile train --algo <algo> --demos <demos> -o <run>`, then `rest`.
    let train_run = |algo: &str, demos: &PathBuf, run: &PathBuf, rest: &[&str]| {
        let (demos, run) = (s(demos), s(run));
        smile(
            &[
                &["train", "--algo", algo, "--demos", &demos, "-o", &run][..],
                rest,
            ]
            .concat(),
        )
    };

    // Held-out honesty: a meta-test file is refused by every algorithm, before any training.
    for algo in ["smile", "smile-state-only", "meta-bc", "meta-dagger"] {
        let out_dir = dir.join(format!("refused-{algo}"));
        let out = train_run(algo, &test, &out_dir, &["--quiet"]);
        assert!(!out.status.success(), "{algo} trained on meta-test demos");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("meta-test"), "{algo}: {err}");
        assert!(
            !out_dir.join("metrics.jsonl").exists()
                && !out_dir.join("checkpoint.safetensors").exists()
        );
    }

    // Tiny SMILe and Meta-BC runs from TOML configs.
    let (mut sc, mut bc) = common::tiny_meta_configs();
    sc.sac = SacConfig {
        hidden: vec![16, 16],
        reward_scale: 8.0,
        ..SacConfig::default()
    };
    (sc.total_updates, sc.eval_every) = (20, 10);
    std::fs::write(dir.join("smile.toml"), toml::to_string(&sc).unwrap()).unwrap();
    (bc.total_steps, bc.eval_every) = (60, 30);
    std::fs::write(dir.join("bc.toml"), toml::to_string(&bc).unwrap()).unwrap();
    let (run_s, run_b) = (dir.join("smile"), dir.join("bc"));
    let (smile_toml, bc_toml) = (s(&dir.join("smile.toml")), s(&dir.join("bc.toml")));
    ok(&train_run(
        "smile",
        &train,
        &run_s,
        &["--config", &smile_toml, "--quiet"],
    ));
    ok(&train_run(
        "meta-bc",
        &train,
        &run_b,
        &["--config", &bc_toml, "--quiet"],
    ));
    // Resume extends the run.
    let resume = ["--resume", "--updates", "30", "--quiet"];
    ok(&train_run("smile", &train, &run_s, &resume));
    let ck: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run_s.join("checkpoint.json")).unwrap())
            .unwrap();
    assert_eq!(ck["updates"], 30);
    // Starting a fresh run over an existing one is refused and overwrites nothing.
    let before = std::fs::read(run_s.join("checkpoint.safetensors")).unwrap();
    let out = train_run(
        "smile",
        &train,
        &run_s,
        &["--config", &smile_toml, "--quiet"],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("already holds a run") && err.contains("--resume"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(run_s.join("checkpoint.safetensors")).unwrap(),
        before
    );

    // Eval: JSON, markdown and SVG, one method per policy.
    let ev = dir.join("eval");
    ok(&smile(&[
        "eval",
        "--policy",
        &s(&run_s),
        &s(&run_b),
        "--contexts",
        &s(&test),
        "--rollouts",
        "1",
        "--context-sizes",
        "1,2",
        "--horizon",
        "20",
        "-o",
        &s(&ev),
        "--render",
        "--quiet",
    ]));
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ev.join("eval.json")).unwrap()).unwrap();
    assert_eq!(rep["methods"].as_array().unwrap().len(), 2);
    assert_eq!(rep["methods"][0]["tasks"].as_array().unwrap().len(), 16);
    // --context-sizes replaces point-goal's protocol (1-demo contexts only).
    assert_eq!(rep["protocol"]["context_sizes"], serde_json::json!([1, 2]));
    assert_eq!(
        rep["methods"][0]["by_context_size"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    let md = std::fs::read_to_string(ev.join("eval.md")).unwrap();
    let mean = rep["methods"][1]["mean"].as_f64().unwrap();
    assert!(md.contains(&format!("{mean:.3}")), "{md}");
    assert!(
        std::fs::read_to_string(ev.join("eval.svg"))
            .unwrap()
            .contains("<svg")
    );
    assert!(ev.join("episode-0-smile.svg").exists());
    // Eval refuses contexts of the wrong split.
    assert!(
        !smile(&[
            "eval",
            "--policy",
            &s(&run_s),
            "--contexts",
            &s(&train),
            "-o",
            &s(&ev)
        ])
        .status
        .success()
    );

    // Export with verification report.
    let blob = dir.join("policy.blob");
    ok(&smile(&[
        "export",
        "--policy",
        &s(&run_s),
        "--quant",
        "w8a8",
        "--demos",
        &s(&train),
        "--contexts",
        &s(&test),
        "--rollouts",
        "1",
        "--horizon",
        "20",
        "-o",
        &s(&blob),
    ]));
    let bytes = std::fs::read(&blob).unwrap();
    infer_core::Model::from_bytes(&bytes).unwrap();
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("policy.blob.json")).unwrap())
            .unwrap();
    assert_eq!(rep["bytes"].as_u64().unwrap() as usize, bytes.len());
    assert_eq!(rep["parity"]["contexts"], 16);
    assert!(rep["metric_blob"].as_f64().unwrap().is_finite());
    assert!(rep.get("qat_steps").is_none(), "{rep}");

    // A quantization-aware fine-tune first (issue 59, step 4): another blob, the report says
    // so and still measures the float policy as trained; an f32 blob has no rounding to learn.
    let export_with = |extra: &[&str], out: &std::path::Path| {
        let mut args = vec![
            "export",
            "--policy",
            common::s(&run_s),
            "--demos",
            common::s(&train),
        ];
        args.extend_from_slice(&[
            "--contexts",
            common::s(&test),
            "--rollouts",
            "1",
            "--horizon",
            "20",
        ]);
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", common::s(out)]);
        smile(&args)
    };
    let tuned = dir.join("tuned.blob");
    ok(&export_with(&["--qat-steps", "50"], &tuned));
    let tuned_rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("tuned.blob.json")).unwrap())
            .unwrap();
    assert_eq!(tuned_rep["qat_steps"], 50);
    assert_eq!(tuned_rep["metric_candle"], rep["metric_candle"]);
    assert_ne!(std::fs::read(&tuned).unwrap(), bytes);
    let refused = export_with(&["--quant", "f32", "--qat-steps", "5"], &dir.join("f.blob"));
    let e = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && e.contains("--qat-steps"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Makes the trained `policy` a shipped one: its `deploy.toml` naming the demos, and its
/// deployed w8a8 blob exported beside it.
fn ship(policy: &std::path::Path, train: &std::path::Path, test: &std::path::Path) {
    let manifest = format!(
        "method = \"Meta-BC\"\ndemos = {:?}\ncontexts = {:?}\n",
        common::s(train),
        common::s(test)
    );
    std::fs::write(policy.join("deploy.toml"), manifest).unwrap();
    // The deployed blob the table measures, as `smile export` ships it.
    let blob = policy.join("policy.blob");
    ok(&smile(
        &[
            &common::export_args(policy, "w8a8", test)[..],
            &["--demos", common::s(train), "-o", common::s(&blob)],
        ]
        .concat(),
    ));
}

/// Demos of the point-goal goals `angles` (comma separated), `per_task` each, by the scripted
/// PD expert, in `dir/new.safetensors`: tasks in neither split.
fn new_goals(dir: &std::path::Path, angles: &str, per_task: &str) -> std::path::PathBuf {
    let pd = common::scripted_pd_expert(dir.join("pd"));
    let new = dir.join("new.safetensors");
    ok(&smile(&[
        "demos",
        "--env",
        "point-goal",
        "--task-params",
        angles,
        "--per-task",
        per_task,
        "--expert",
        common::s(&pd),
        "-o",
        common::s(&new),
    ]));
    new
}

/// The rows `smile device-table -o out` wrote.
fn table_rows(out: &std::path::Path) -> serde_json::Value {
    let json = std::fs::read_to_string(out.join("device-table.json")).unwrap();
    serde_json::from_str(&json).unwrap()
}

/// Issue 59: `smile device-table` on a shipped policy directory (weights and `deploy.toml`):
/// every column is measured, the f32 blob scores as the float policy, and the w8a8 blob on the
/// device with ideal sensing scores exactly as the same blob evaluated on the host (the loop
/// and the evaluation run the same episodes); a directory without a manifest is refused by
/// name.
#[test]
fn device_table_measures_float_to_int8_to_the_device_loop() {
    let dir = common::fresh_dir("smile-device-table", "pg");
    let (train, test) = common::point_goal_demo_files(&dir);
    let policy = dir.join("policy");
    common::tiny_bc(&train, &policy);
    let e = String::from_utf8_lossy(
        &smile(&[
            "device-table",
            common::s(&policy),
            "-o",
            common::s(&dir.join("t")),
        ])
        .stderr,
    )
    .into_owned();
    assert!(e.contains("deploy.toml"), "{e}");
    ship(&policy, &train, &test);
    // The table of `policy`, one draw per task, written to `out`.
    let one_draw = |out: &std::path::Path| {
        ok(&smile(&[
            "device-table",
            common::s(&policy),
            "--draws",
            "1",
            "-o",
            common::s(out),
        ]))
    };
    let out = dir.join("table");
    one_draw(&out);
    let rows = table_rows(&out);
    let row = &rows[0];
    let float = row["float"].as_f64().unwrap();
    let f32_blob = row["blobs"][0]["metric"].as_f64().unwrap();
    assert!(
        (f32_blob - float).abs() < 1e-3 * float.abs().max(1.0),
        "{row}"
    );
    assert_eq!(
        row["device"][0]["cell"], row["blobs"][3],
        "the ideal device loop is the host's evaluation of the same (deployed) blob: {row}"
    );
    // Each column's degradation comes with its standard error, paired by task: the f32 blob
    // moves no task, the int8 one some.
    let se = |c: &serde_json::Value| c["stderr_pct"].as_f64().unwrap();
    assert!(se(&row["blobs"][0]) < 1e-3, "{row}");
    assert!(se(&row["blobs"][2]) > 0.0, "{row}");
    // The deployed blob keeps w8a8's flash: its edge layers store int8 weights too.
    let bytes = &row["blob_bytes_all"];
    assert!(bytes[3].as_u64() <= bytes[2].as_u64(), "{row}");
    assert!(
        bytes[3].as_u64().unwrap() * 3 < bytes[0].as_u64().unwrap(),
        "{row}"
    );
    assert_eq!(row["fits"], true, "{row}");
    let md = std::fs::read_to_string(out.join("device-table.md")).unwrap();
    assert_eq!(md.lines().count(), 3, "{md}");

    // The sensor column's ADC full scale comes from deploy.toml (issue 73: the cheetah's joint
    // velocities clipped at the default +-10): a converter of +-0.5 clips point-goal's
    // positions (up to 2), and the row says so; a scale that is no scale is refused by name.
    let manifest = std::fs::read_to_string(policy.join("deploy.toml")).unwrap();
    std::fs::write(
        policy.join("deploy.toml"),
        format!("{manifest}adc_range = 0.5\n"),
    )
    .unwrap();
    let clipped = dir.join("clipped");
    one_draw(&clipped);
    let narrow = &table_rows(&clipped)[0];
    assert_eq!(narrow["adc_range"], 0.5, "{narrow}");
    assert_eq!(row["adc_range"], 10.0, "{row}");
    let noise = |r: &serde_json::Value| r["device"][1]["cell"]["metric"].as_f64().unwrap();
    // (This tiny policy barely moves, so the clipped readings change its metric a little, but
    // change it: the column read through the manifest's converter.)
    assert_ne!(noise(narrow), noise(row), "{narrow} against {row}");
    assert_eq!(
        narrow["device"][0]["cell"], row["device"][0]["cell"],
        "the ideal column is unchanged"
    );
    let md = std::fs::read_to_string(clipped.join("device-table.md")).unwrap();
    assert!(md.contains("[ADC +-0.5]"), "{md}");
    std::fs::write(
        policy.join("deploy.toml"),
        format!("{manifest}adc_range = -1.0\n"),
    )
    .unwrap();
    let e = smile(&[
        "device-table",
        common::s(&policy),
        "-o",
        common::s(&dir.join("x")),
    ]);
    let stderr = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success() && stderr.contains("deploy.toml") && stderr.contains("adc_range"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `smile device-table --new-tasks`: the row is measured on the tasks the file holds (new
/// goals recorded with `smile demos --task-params`), says so in its JSON and markdown, and
/// keeps the loop equal to the host's evaluation there; a missing file is refused by name.
#[test]
fn device_table_measures_the_new_tasks_a_demo_file_holds() {
    let dir = common::fresh_dir("smile-device-table-new", "pg");
    let (train, test) = common::point_goal_demo_files(&dir);
    let policy = dir.join("policy");
    common::tiny_bc(&train, &policy);
    ship(&policy, &train, &test);
    let new = new_goals(&dir, "0.1,1.7,2.9", "2");
    let missing = dir.join("no-such-demos.safetensors");
    let e = smile(&[
        "device-table",
        common::s(&policy),
        "--draws",
        "1",
        "--new-tasks",
        common::s(&missing),
        "-o",
        common::s(&dir.join("t")),
    ]);
    let stderr = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success() && stderr.contains("no-such-demos"),
        "{stderr}"
    );
    let out = dir.join("table");
    ok(&smile(&[
        "device-table",
        common::s(&policy),
        "--draws",
        "2",
        "--new-tasks",
        common::s(&new),
        "-o",
        common::s(&out),
    ]));
    let rows = table_rows(&out);
    let row = &rows[0];
    assert_eq!(row["tasks"], 3, "{row}");
    assert_eq!(row["episodes_per_task"], 2, "{row}");
    assert!(
        row["new_tasks"]
            .as_str()
            .unwrap()
            .ends_with("new.safetensors"),
        "{row}"
    );
    assert_eq!(row["device"][0]["cell"], row["blobs"][3], "{row}");
    let md = std::fs::read_to_string(out.join("device-table.md")).unwrap();
    assert!(md.contains("| 3 new x 2 |"), "{md}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 57: `smile eval --contexts-tasks` scores the tasks the contexts file holds (new goals
/// recorded with `smile demos --task-params`), where a split's evaluation needs demos of the
/// split's tasks; the family comes from the contexts without `--env`.
#[test]
fn eval_scores_the_contexts_own_new_tasks() {
    let dir = common::fresh_dir("smile-eval-new-tasks", "pg");
    let (train, _) = common::point_goal_demo_files(&dir);
    let policy = dir.join("bc");
    common::tiny_bc(&train, &policy);
    let new = new_goals(&dir, "0.1,1.7", "1");
    let out = dir.join("eval");
    let args = common::eval_args(&policy, &new, &out);
    let refused = smile(&args);
    assert!(!refused.status.success());
    ok(&smile(&[&args[..], &["--contexts-tasks"]].concat()));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("eval.json")).unwrap()).unwrap();
    let tasks = report["methods"][0]["tasks"].as_array().unwrap();
    assert_eq!(tasks.len(), 2, "{report}");
    assert!(
        (tasks[1]["value"].as_f64().unwrap() - 1.7).abs() < 1e-3,
        "{report}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
