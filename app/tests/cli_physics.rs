//! The plant is chosen per run and recorded: `--physics` on expert, demos, train, eval and
//! export; a demo file or policy of one plant is refused by a run on the other. With the
//! `mujoco` feature the whole pipeline runs on MuJoCo; without it, asking for MuJoCo says how
//! to get it.

mod common;
#[cfg(feature = "mujoco")]
use common::ok;
use common::{s, smile};

use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-cli-physics", name)
}

fn stderr(out: &std::process::Output) -> String {
    assert!(!out.status.success(), "expected a refusal, got success");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[cfg(not(feature = "mujoco"))]
#[test]
fn a_build_without_mujoco_says_how_to_get_it() {
    let dir = tmp("no-feature");
    let e = dir.join("e");
    let mut args = vec!["expert", "--env", "cheetah-vel", "--physics", "mujoco"];
    args.extend([
        "--total-steps",
        "10",
        "--learning-starts",
        "5",
        "-o",
        s(&e),
        "--quiet",
    ]);
    let out = smile(&args);
    let err = stderr(&out);
    assert!(
        err.contains("fetch-mujoco.sh") && err.contains("--features mujoco"),
        "{err}"
    );
    let out = smile(&[
        "expert",
        "--env",
        "cheetah-vel",
        "--physics",
        "bullet",
        "-o",
        s(&dir.join("f")),
    ]);
    assert!(stderr(&out).contains("rapier or mujoco"));
}

/// expert -> demos -> SMILe and Meta-BC -> eval -> export on MuJoCo's cheetah, each file
/// recording the plant; Rapier runs refuse the MuJoCo files and the other way round.
#[cfg(feature = "mujoco")]
#[test]
fn the_pipeline_runs_on_mujoco_and_each_plant_refuses_the_others_files() {
    let dir = tmp("pipeline");
    let expert = dir.join("expert");
    ok(&smile(&[
        "expert",
        "--env",
        "cheetah-vel",
        "--physics",
        "mujoco",
        "--total-steps",
        "600",
        "--learning-starts",
        "300",
        "--horizon",
        "50",
        "--hidden",
        "16,16",
        "--batch-size",
        "32",
        "--eval-every",
        "0",
        "--eval-episodes",
        "1",
        "-o",
        s(&expert),
        "--quiet",
    ]));
    let config = std::fs::read_to_string(expert.join("config.toml")).unwrap();
    assert!(config.contains("physics = \"mujoco\""), "{config}");

    // Demos take the expert's plant without being told; asking for Rapier is refused.
    let (train, test) = (dir.join("train.safetensors"), dir.join("test.safetensors"));
    let demos = |split: &str, out: &PathBuf, extra: &[&str]| {
        let mut args = vec![
            "demos",
            "--env",
            "cheetah-vel",
            "--split",
            split,
            "--per-task",
            "1",
            "--horizon",
            "20",
            "--expert",
            s(&expert),
            "-o",
            s(out),
        ];
        args.extend_from_slice(extra);
        smile(&args)
    };
    let err = stderr(&demos(
        "train",
        &dir.join("rapier.safetensors"),
        &["--physics", "rapier"],
    ));
    assert!(
        err.contains("mujoco plant") && err.contains("rapier"),
        "{err}"
    );
    ok(&demos("train", &train, &[]));
    ok(&demos("test", &test, &[]));
    let ds = sim::DemoDataset::read(&train).unwrap();
    assert_eq!(ds.physics, sim::Physics::Mujoco);

    // Training defaults to the demos' plant; a Rapier run refuses them with a message.
    let err = stderr(&smile(&[
        "train",
        "--algo",
        "meta-bc",
        "--demos",
        s(&train),
        "--physics",
        "rapier",
        "-o",
        s(&dir.join("bc-rapier")),
        "--updates",
        "10",
        "--quiet",
    ]));
    assert!(
        err.contains("mujoco plant") && err.contains("--physics mujoco"),
        "{err}"
    );
    let run = dir.join("smile");
    let short = dir.join("short.toml");
    std::fs::write(&short, "horizon = 20\n").unwrap();
    ok(&smile(&[
        "train",
        "--config",
        s(&short),
        "--demos",
        s(&train),
        "-o",
        s(&run),
        "--updates",
        "30",
        "--hidden",
        "16,16",
        "--eval-every",
        "0",
        "--quiet",
    ]));
    let config = std::fs::read_to_string(run.join("config.toml")).unwrap();
    assert!(config.contains("physics = \"mujoco\""), "{config}");
    let record = std::fs::read_to_string(run.join("run.json")).unwrap();
    assert!(record.contains("\"physics\": \"mujoco\""), "{record}");
    let mp = trainer::MetaPolicy::load(&run).unwrap();
    assert_eq!(mp.physics, sim::Physics::Mujoco);

    // Evaluation runs on the policy's plant; contexts of another plant are refused.
    let eval = dir.join("eval");
    // `smile eval` of `run` on cheetah-vel's meta-test `contexts`, one rollout, then `rest`.
    let eval_on = |contexts: &PathBuf, rest: &[&str]| {
        let head = [
            "eval",
            "--env",
            "cheetah-vel",
            "--policy",
            s(&run),
            "--contexts",
            s(contexts),
            "--split",
            "test",
            "--rollouts",
            "1",
        ];
        smile(&[&head[..], rest].concat())
    };
    let sizes = ["--context-sizes", "1", "--horizon", "20", "-o", s(&eval)];
    ok(&eval_on(&test, &sizes));
    let rapier_test = dir.join("rapier-test.safetensors");
    common::open_loop_demos(
        sim::Family::CHEETAH_VEL,
        sim::Split::Test,
        sim::Family::CHEETAH_VEL.test_tasks(),
        20,
    )
    .write(&rapier_test)
    .unwrap();
    let eval2 = dir.join("eval2");
    let err = stderr(&eval_on(
        &rapier_test,
        &["--horizon", "20", "-o", s(&eval2)],
    ));
    assert!(
        err.contains("rapier plant") && err.contains("mujoco"),
        "{err}"
    );

    // The export report records the plant.
    let blob = dir.join("policy.blob");
    ok(&smile(&[
        "export",
        "--policy",
        s(&run),
        "--quant",
        "f32",
        "--contexts",
        s(&test),
        "--rollouts",
        "1",
        "--horizon",
        "20",
        "-o",
        s(&blob),
    ]));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("policy.blob.json")).unwrap())
            .unwrap();
    assert_eq!(report["physics"], "mujoco");
}
