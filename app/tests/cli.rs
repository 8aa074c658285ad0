//! The `smile` binary end to end on tiny budgets: expert (TOML config) -> resume -> demos,
//! corrupt checkpoint and bad config errors.

mod common;
use common::{ok, point_goal_demos_args, smile};

use std::path::{Path, PathBuf};

/// The shipped point-goal meta-train demos (all 32 goals).
const SHIPPED_TRAIN_DEMOS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../assets/experts/point-goal/demos-train-4x-sub20.safetensors"
);

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-cli", name)
}

fn last_metrics(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    serde_json::from_str(text.lines().last().unwrap()).unwrap()
}

#[test]
fn help_lists_working_commands() {
    let out = smile(&["--help"]);
    ok(&out);
    let help = String::from_utf8_lossy(&out.stdout);
    for cmd in ["expert", "demos", "bench"] {
        assert!(help.contains(cmd), "{help}");
    }
    let out = smile(&["expert", "--help"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("Examples:"));
}

#[test]
fn expert_resume_demos_pipeline() {
    let d = tmp("pipeline");
    let run = d.join("run");
    let cfg = d.join("expert.toml");
    std::fs::write(
        &cfg,
        "env = \"point-goal\"\ntotal_steps = 60\nlearning_starts = 20\nhorizon = 20\n\
         checkpoint_every = 40\n[sac]\nhidden = [16, 16]\nbatch_size = 16\n",
    )
    .unwrap();
    let (cfg_s, run_s) = (cfg.to_str().unwrap(), run.to_str().unwrap());
    ok(&smile(&[
        "expert",
        "--config",
        cfg_s,
        "-o",
        run_s,
        "--quiet",
        "--eval-episodes",
        "1",
    ]));
    for f in [
        "config.toml",
        "checkpoint.safetensors",
        "policy.safetensors",
        "eval.json",
    ] {
        assert!(run.join(f).exists(), "{f}");
    }
    let m = last_metrics(&run);
    assert_eq!(m["step"], 60);
    assert!(m["losses/qf_loss"].is_number() && m["charts/sps"].is_number());

    ok(&smile(&[
        "expert",
        "--resume",
        run_s,
        "--total-steps",
        "100",
        "--quiet",
        "--eval-episodes",
        "1",
    ]));
    assert_eq!(last_metrics(&run)["step"], 100);
    // A resume keeps the run's configuration: a flag that would set it is refused, not ignored.
    for flag in [&["--seed", "3"][..], &["--hidden", "8,8"], &["--keep-best"]] {
        let out = smile(&[&["expert", "--resume", run_s, "--quiet"][..], flag].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("cannot be used with"),
            "{err}"
        );
    }

    let demos = d.join("demos.safetensors");
    let demos_s = demos.to_str().unwrap();
    let options = [
        "--split",
        "test",
        "--per-task",
        "1",
        "--subsample",
        "5",
        "--horizon",
        "20",
    ];
    ok(&smile(&point_goal_demos_args(&options, run_s, demos_s)));
    let ds = sim::DemoDataset::read(&demos).unwrap();
    assert_eq!(
        (ds.tasks.len(), ds.expert.as_str(), ds.subsample_factor),
        (16, "sac-oracle", 5)
    );
    let options = [
        "--task-params",
        "0.3,-1.2",
        "--per-task",
        "2",
        "--horizon",
        "20",
    ];
    ok(&smile(&point_goal_demos_args(&options, run_s, demos_s)));
    assert_eq!(
        sim::DemoDataset::read(&demos).unwrap().trajectory_count(),
        4
    );
    // Wrong family for this expert.
    assert!(
        !smile(&[
            "demos",
            "--env",
            "cheetah-vel",
            "--expert",
            run_s,
            "-o",
            demos_s
        ])
        .status
        .success()
    );

    // Corrupt checkpoint: a clear error naming it.
    let ck = run.join("checkpoint.safetensors");
    let bytes = std::fs::read(&ck).unwrap();
    std::fs::write(&ck, &bytes[..100]).unwrap();
    let out = smile(&[
        "expert",
        "--resume",
        run_s,
        "--total-steps",
        "200",
        "--quiet",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("checkpoint.safetensors"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// `--distinct-starts` evaluates the scripted classifier from every task's own reset seeds and
/// says so in `eval.json`; without it the evaluation's seeds are shared across tasks.
#[test]
fn the_scripted_classifier_is_evaluated_from_distinct_starts_when_asked() {
    let d = tmp("linclass-distinct");
    let goal = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts/ant-goal");
    let mut evals = Vec::new();
    for (name, extra) in [
        ("shared", &[][..]),
        ("distinct", &["--distinct-starts"][..]),
    ] {
        let out = d.join(name);
        let base = [
            "expert",
            "--kind",
            "scripted-linclass",
            "--eval-episodes",
            "1",
            "--quiet",
        ];
        let paths = [
            "--goal-expert",
            goal.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        let res = smile(&[&base[..], &paths, extra].concat());
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        let text = std::fs::read_to_string(out.join("eval.json")).unwrap();
        evals.push(serde_json::from_str::<serde_json::Value>(&text).unwrap());
    }
    assert_eq!(evals[0]["distinct_starts"], false);
    assert_eq!(evals[1]["distinct_starts"], true);
    // The same tasks, other walks: the per-task successes differ somewhere.
    assert_ne!(
        evals[0]["report"]["per_task"],
        evals[1]["report"]["per_task"]
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn unknown_config_key_is_rejected() {
    let d = tmp("badcfg");
    let cfg = d.join("bad.toml");
    std::fs::write(&cfg, "env = \"point-goal\"\ntotal_stepz = 5\n").unwrap();
    let out = smile(&[
        "expert",
        "--config",
        cfg.to_str().unwrap(),
        "-o",
        d.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("total_stepz"));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn per_task_experts_make_demos_for_their_tasks() {
    let d = tmp("pertask");
    let mut dirs = Vec::new();
    for v in ["0.3", "-1.2"] {
        let run = d.join(format!("task{v}"));
        common::tiny_per_task_expert(v, &run);
        let eval: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(run.join("eval.json")).unwrap()).unwrap();
        assert_eq!(eval["tasks"].as_array().unwrap().len(), 1);
        dirs.push(run.to_str().unwrap().to_string());
    }
    // A trained expert is never overwritten by a fresh run (SAC or scripted) into its directory.
    let policy = std::fs::read(d.join("task0.3").join("policy.safetensors")).unwrap();
    for extra in [&["--env", "point-goal"][..], &["--kind", "scripted-pd"][..]] {
        let mut args = vec!["expert", "-o", &dirs[0], "--quiet"];
        args.extend_from_slice(extra);
        let out = smile(&args);
        assert!(
            !out.status.success(),
            "{extra:?} overwrote a trained expert"
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("already holds a run"), "{err}");
    }
    assert_eq!(
        std::fs::read(d.join("task0.3").join("policy.safetensors")).unwrap(),
        policy
    );
    let experts = dirs.join(",");
    let demos = d.join("demos.safetensors");
    let demos_with = |expert: &str, out: &std::path::Path| {
        let options = [
            "--task-params",
            "0.3,-1.2",
            "--per-task",
            "1",
            "--horizon",
            "20",
        ];
        ok(&smile(&point_goal_demos_args(
            &options,
            expert,
            out.to_str().unwrap(),
        )))
    };
    demos_with(&experts, &demos);
    let ds = sim::DemoDataset::read(&demos).unwrap();
    assert_eq!(
        (ds.tasks.len(), ds.expert.as_str()),
        (2, "sac-oracle-per-task")
    );
    // A task without its expert (and no general expert) is an error.
    let options = ["--task-params", "0.5", "--horizon", "20"];
    let out = smile(&point_goal_demos_args(
        &options,
        &experts,
        demos.to_str().unwrap(),
    ));
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no expert for task"));
    // A folder of policy files stands for its experts: the same demos as the list.
    let folder = d.join("per-task");
    std::fs::create_dir_all(&folder).unwrap();
    for v in ["0.3", "-1.2"] {
        std::fs::copy(
            d.join(format!("task{v}")).join("policy.safetensors"),
            folder.join(format!("goal{v}.safetensors")),
        )
        .unwrap();
    }
    let from_folder = d.join("demos-folder.safetensors");
    demos_with(folder.to_str().unwrap(), &from_folder);
    // (safetensors' JSON header has no fixed key order: compare the data, not the bytes)
    let (a, b) = (
        sim::DemoDataset::read(&from_folder).unwrap(),
        sim::DemoDataset::read(&demos).unwrap(),
    );
    assert_eq!((a.tasks, a.expert), (b.tasks, b.expert));
    // Meta-DAgger checks up front that every meta-train task has its relabelling expert (the
    // shipped demos cover all 32 goals, the folder two other ones).
    let train = SHIPPED_TRAIN_DEMOS;
    let out = smile(&[
        "train",
        "--algo",
        "meta-dagger",
        "--demos",
        train,
        "--expert",
        folder.to_str().unwrap(),
        "--updates",
        "10",
        "-o",
        d.join("dagger").to_str().unwrap(),
        "--quiet",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "trained with missing experts");
    assert!(err.contains("no expert for task"), "{err}");
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let to = d.join("none.safetensors");
    let out = smile(&point_goal_demos_args(
        &[],
        empty.to_str().unwrap(),
        to.to_str().unwrap(),
    ));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("holds no expert"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn two_tiny_quickstarts_with_one_seed_are_byte_identical() {
    let d = tmp("determinism");
    let runs = [d.join("a"), d.join("b")];
    // Two processes at once, as two users would run them.
    let children: Vec<_> = runs
        .iter()
        .map(|out| {
            std::process::Command::new(env!("CARGO_BIN_EXE_smile"))
                .args(["quickstart", "--budget", "tiny", "--seed", "3", "--quiet"])
                .args(["--out", out.to_str().unwrap()])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for f in [
        "eval.json",
        "policy.blob",
        "policy.blob.json",
        "smile/meta_policy.safetensors",
        "meta-bc/meta_policy.safetensors",
    ] {
        let (a, b) = (
            std::fs::read(runs[0].join(f)).unwrap(),
            std::fs::read(runs[1].join(f)).unwrap(),
        );
        assert!(!a.is_empty(), "{f} is empty");
        assert!(a == b, "{f} differs between two runs of seed 3");
    }
    // The demo files hold the same data; not the same bytes: the safetensors header's
    // `__metadata__` map is written in HashMap order, which differs between processes.
    for f in ["demos-train.safetensors", "demos-test.safetensors"] {
        assert_eq!(
            sim::DemoDataset::read(runs[0].join(f)).unwrap(),
            sim::DemoDataset::read(runs[1].join(f)).unwrap(),
            "{f}"
        );
    }
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(runs[0].join("eval.json")).unwrap()).unwrap();
    assert_eq!(eval["methods"].as_array().unwrap().len(), 3);
    // The encoder's z of the trained SMILe, for every test task's three context draws.
    let csv = d.join("latents.csv");
    let out = smile(&[
        "latents",
        "--policy",
        runs[0].join("smile").to_str().unwrap(),
        "--env",
        "point-goal",
        "--contexts",
        runs[0].join("demos-test.safetensors").to_str().unwrap(),
        "--context-sizes",
        "1,2",
        "-o",
        csv.to_str().unwrap(),
    ]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("2 context demos: mean"));
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("task_value,context_size,draw,param_0,param_1,z_0,"));
    assert_eq!(text.lines().count(), 1 + 16 * 2 * 3);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bench_times_one_tiny_iteration_and_names_bad_flags() {
    let d = tmp("bench");
    let json = d.join("bench.json");
    // One timed iteration, no warm-up, rows into `json` (the options before that first).
    let bench = |options: &[&str]| {
        let once = [
            "--iters",
            "1",
            "--warmup",
            "0",
            "--json",
            json.to_str().unwrap(),
        ];
        smile(&[&["bench"][..], options, &once].concat())
    };
    let out = bench(&["--hidden", "8", "16"]);
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.starts_with(
            "sac update, batch 256, obs 20 + z 16, act 6, candle threads 1, learner threads 1\n"
        ),
        "{stdout}"
    );
    // A header and one row per width, each with a positive median time.
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 4, "{stdout}");
    assert!(lines[1].contains("median_us") && lines[1].contains("GFLOP/s"));
    for (line, h) in lines[2..].iter().zip(["8x2", "16x2"]) {
        let cols: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(cols[0], h, "{line}");
        assert!(cols[1].parse::<f64>().unwrap() > 0.0, "{line}");
    }
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for (row, h) in rows.iter().zip([8, 16]) {
        assert_eq!(
            (row["workload"].as_str(), row["H"].as_u64()),
            (Some("sac"), Some(h))
        );
        assert_eq!(row["shape"]["hidden"], serde_json::json!([h, h]));
        // the products' work: 2 x batch x (multiply-adds of every product the update needs)
        assert!(row["flops"].as_f64().unwrap() > 2.0 * 256.0 * (36.0 * h as f64));
        assert!(row["gflop_per_s"].as_f64().unwrap() > 0.0);
        let t = &row["timing"];
        let med = t["median_us"].as_f64().unwrap();
        assert!(
            med > 0.0
                && (t["updates_per_s"].as_f64().unwrap() - 1e6 / med).abs() < 1e-6 * (1e6 / med)
        );
    }

    // The discriminator step and whole SMILe iterations, one tiny timing each.
    let demos = SHIPPED_TRAIN_DEMOS;
    let out = bench(&[
        "--workload",
        "disc",
        "pair",
        "--hidden",
        "8",
        "--demos",
        demos,
    ]);
    ok(&out);
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["workload"], "disc");
    assert!(rows[0]["timing"]["median_us"].as_f64().unwrap() > 0.0);
    assert_eq!(rows[1]["workload"], "pair");
    let t = &rows[1]["timing"];
    let (all, upd) = (
        t["per_pair_us"].as_f64().unwrap(),
        t["updates_only_per_pair_us"].as_f64().unwrap(),
    );
    assert!(upd > 0.0 && all >= upd, "{t}");
    let out = smile(&[
        "bench",
        "--workload",
        "pair",
        "--demos",
        "/nonexistent.safetensors",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("reading the demos /nonexistent"),
        "{err}"
    );

    // The authors' shapes, and every layer named, on two learner threads.
    let out = bench(&[
        "--workload",
        "sac",
        "disc",
        "--authors",
        "--learner-threads",
        "2",
    ]);
    ok(&out);
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (sac, disc) = (&rows[0], &rows[1]);
    assert_eq!(sac["shape"]["hidden"], serde_json::json!([256, 256, 256]));
    assert_eq!(
        (
            sac["shape"]["batch"].as_u64(),
            sac["learner_threads"].as_u64()
        ),
        (Some(1024), Some(2))
    );
    assert!((sac["flops"].as_f64().unwrap() / 1e9 - 4.93).abs() < 0.01);
    assert_eq!(disc["shape"]["hidden"], serde_json::json!([512, 512, 512]));
    assert_eq!(disc["shape"]["enc_hidden"], serde_json::json!([256, 256]));
    assert!((disc["flops"].as_f64().unwrap() / 1e9 - 11.87).abs() < 0.01);
    let out = bench(&["--hidden", "16,8,4"]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("16,8,4"));

    // Errors name the flag or the value.
    let out = smile(&["bench", "--hidden", "0", "--iters", "1", "--warmup", "0"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--hidden \"0\": widths are positive integers, e.g. 256 or 512,512,512"),
        "{err}"
    );
    let out = smile(&["bench", "--iters", "many"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("invalid value 'many' for '--iters <ITERS>'"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).ok();
}
