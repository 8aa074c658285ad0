//! What a new user trips on, called as a user calls the binary: `smile export` on demos of
//! another family, `--quant f32` without calibration demos, `--resume` of every algorithm
//! (reading the algorithm from the run directory), a refused run leaving no directory, and the
//! metrics log after a resume.

mod common;
use common::{ok, smile};

use std::path::{Path, PathBuf};

use sim::{Family, Split};

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-cli-user", name)
}

use common::s;

/// Cheetah-vel "demos" of a fixed open-loop action: only their family and shapes matter here.
fn cheetah_demos(path: &Path) {
    let fam = Family::CHEETAH_VEL;
    common::open_loop_demos(fam, Split::Train, fam.train_tasks()[..2].to_vec(), 5)
        .write(path)
        .unwrap();
}

/// A tiny Meta-BC run on point-goal demos in `dir/bc`; returns (run dir, train demos, test demos).
fn tiny_bc(dir: &Path, steps: &str) -> (PathBuf, PathBuf, PathBuf) {
    let fam = Family::POINT_GOAL;
    let (train, test) = (dir.join("train.safetensors"), dir.join("test.safetensors"));
    common::pd_demos(Split::Train, fam.train_tasks()[..8].to_vec(), 2, 20)
        .write(&train)
        .unwrap();
    common::pd_demos(Split::Test, fam.test_tasks(), 1, 20)
        .write(&test)
        .unwrap();
    let run = dir.join("bc");
    let tail = [
        "--updates",
        steps,
        "--eval-every",
        "50",
        "--hidden",
        "16,16",
        "--quiet",
    ];
    ok(&smile(
        &[&common::meta_bc_args(&train, &run)[..], &tail].concat(),
    ));
    (run, train, test)
}

#[test]
fn export_refuses_demos_of_another_family_in_one_line_and_f32_needs_no_calibration() {
    let dir = tmp("export");
    let (run, train, test) = tiny_bc(&dir, "100");
    let cheetah = dir.join("cheetah.safetensors");
    cheetah_demos(&cheetah);
    let blob = dir.join("p.blob");
    for (demos, contexts) in [(&cheetah, &test), (&train, &cheetah)] {
        let out = smile(&[
            "export",
            "--policy",
            s(&run),
            "--quant",
            "w8a8",
            "--demos",
            s(demos),
            "--contexts",
            s(contexts),
            "-o",
            s(&blob),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "not a clean error exit: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            err.contains(
                "cheetah.safetensors, for this policy: family cheetah-vel, expected point-goal"
            ),
            "{err}"
        );
        assert!(!blob.exists(), "a blob was written from mismatched demos");
    }
    // f32 and w8a32 need no calibration demos; w8a8 says it needs them.
    for quant in ["f32", "w8a32"] {
        let export = common::export_args(&run, quant, &test);
        let err = ok(&smile(&[&export[..], &["-o", s(&blob)]].concat()));
        assert!(err.contains(&format!("bytes, {quant}")), "{err}");
    }
    let out = smile(&[
        "export",
        "--policy",
        s(&run),
        "--contexts",
        s(&test),
        "-o",
        s(&dir.join("w8a8.blob")),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("needs --demos"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn resume_reads_the_algorithm_and_truncates_the_metrics_log() {
    let dir = tmp("resume");
    let (run, train, _) = tiny_bc(&dir, "100");
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("run.json")).unwrap()).unwrap();
    assert_eq!(info["algo"], "meta-bc");

    // Lines the interrupted process wrote after its last checkpoint (step 100).
    let metrics = run.join("metrics.jsonl");
    let mut log = std::fs::read_to_string(&metrics).unwrap();
    log.push_str("{\"step\":150,\"stale\":1.0}\n{\"step\":16");
    std::fs::write(&metrics, log).unwrap();

    // The guide's resume line, without --algo: continues the Meta-BC run.
    let err = ok(&smile(&[
        "train",
        "--resume",
        "-o",
        s(&run),
        "--demos",
        s(&train),
        "--updates",
        "200",
        "--quiet",
    ]));
    assert!(err.contains("resuming from step 100"), "{err}");
    let steps: Vec<u64> = std::fs::read_to_string(&metrics)
        .unwrap()
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("every line parses");
            assert!(
                v.get("stale").is_none(),
                "a line past the checkpoint survived: {l}"
            );
            v["step"].as_u64().unwrap()
        })
        .collect();
    // Each logged step (a training line and an evaluation line every 50 steps) exactly once.
    let want: Vec<u64> = (1..=4).flat_map(|k| [50 * k, 50 * k]).collect();
    assert_eq!(steps, want);

    // A different --algo is refused, naming the run's algorithm.
    let out = smile(&[
        "train",
        "--resume",
        "--algo",
        "smile",
        "-o",
        s(&run),
        "--demos",
        s(&train),
        "--quiet",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("is a meta-bc run"),
        "{err}"
    );

    // Meta-DAgger without --expert on point-goal records the scripted expert and resumes with it.
    let dagger = dir.join("dagger");
    let err = ok(&smile(&[
        "train",
        "--algo",
        "meta-dagger",
        "--demos",
        s(&train),
        "-o",
        s(&dagger),
        "--updates",
        "60",
        "--hidden",
        "16,16",
        "--quiet",
    ]));
    assert!(err.contains("scripted point-goal PD expert"), "{err}");
    let err = ok(&smile(&[
        "train",
        "--resume",
        "-o",
        s(&dagger),
        "--demos",
        s(&train),
        "--updates",
        "120",
        "--quiet",
    ]));
    assert!(
        err.contains("scripted point-goal PD expert") && err.contains("resuming from step 60"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_refused_run_leaves_no_directory() {
    let dir = tmp("refused");
    let test = dir.join("test.safetensors");
    common::pd_demos(Split::Test, Family::POINT_GOAL.test_tasks(), 1, 10)
        .write(&test)
        .unwrap();
    for algo in ["smile", "meta-bc"] {
        let out_dir = dir.join(algo);
        let out = smile(&[
            "train",
            "--algo",
            algo,
            "--demos",
            s(&test),
            "-o",
            s(&out_dir),
            "--quiet",
        ]);
        assert!(!out.status.success());
        assert!(
            !out_dir.exists(),
            "{algo}: {} was created",
            out_dir.display()
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn meta_learner_configs_refuse_unknown_keys_and_invalid_values_by_name() {
    let dir = tmp("configs");
    let train = dir.join("train.safetensors");
    common::pd_demos(
        Split::Train,
        Family::POINT_GOAL.train_tasks()[..4].to_vec(),
        1,
        5,
    )
    .write(&train)
    .unwrap();
    // (algo, TOML, what the error must say): a misspelt key at the top level and in nested
    // tables, then values that parse but cannot train (they must reach the config's
    // validate()). Each also sets a one-step budget, so that a config wrongly accepted fails
    // the test quickly instead of training for minutes.
    let mut cases: Vec<(&str, String, String)> = [
        ("smile", "total_updatez = 5\n", "total_updatez"),
        ("smile", "[context]\nz_dimm = 3\n", "z_dimm"),
        ("smile", "[sac]\nhiden = [8]\n", "hiden"),
        (
            "smile",
            "gp_weight = -1.0\n",
            "gp_weight must be a finite number >= 0",
        ),
        ("smile", "[sac]\nbatch_size = 0\n", "sac.batch_size"),
        ("meta-bc", "total_stepz = 5\n", "total_stepz"),
        ("meta-bc", "[context]\nr_dimm = 3\n", "r_dimm"),
        ("meta-bc", "lr = -0.001\n", "lr must be positive"),
    ]
    .map(|(algo, toml_text, needle)| (algo, toml_text.to_string(), needle.to_string()))
    .into();
    // A count of 0 is refused as a count, by its key's name.
    for (algo, key) in [
        ("smile", "tasks_per_batch"),
        ("smile", "sac_per_task"),
        ("meta-bc", "per_task"),
        ("meta-bc", "tasks_per_batch"),
    ] {
        let needle = format!("{key} must be a count from 1 to");
        cases.push((algo, format!("{key} = 0\n"), needle));
    }
    for (i, (algo, toml_text, needle)) in cases.into_iter().enumerate() {
        let cfg = dir.join(format!("c{i}.toml"));
        let budget = if algo == "smile" {
            "total_updates = 1\n"
        } else {
            "total_steps = 1\n"
        };
        std::fs::write(&cfg, format!("{budget}{toml_text}")).unwrap();
        let run = dir.join(format!("run{i}"));
        let rest = ["--config", s(&cfg), "-o", s(&run), "--quiet"];
        let out = smile(&[&common::train_args(algo, &train)[..], &rest].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(1),
            "{algo} {toml_text:?} was not refused: {err}"
        );
        assert!(err.contains(&needle), "{algo} {toml_text:?}: {err}");
        assert!(
            !run.exists(),
            "{algo} {toml_text:?}: a run directory was created"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
