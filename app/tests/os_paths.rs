//! Paths the OS allows but UTF-8 does not (issue 27, item 13): a Meta-DAgger run whose expert
//! lives under such a folder resumes with that very expert, a local sweep whose plan lives
//! there trains and evaluates its cells, and a Slurm script, which is text, is refused naming
//! the path instead of naming another file. Also: a `run.json` that names another algorithm
//! than the run's config is refused naming that file.
#![cfg(unix)]

mod common;
use common::{ok, s, smile};

use std::ffi::{OsStr, OsString};
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh directory whose own name is not UTF-8 (Latin-1 "café").
fn non_utf8_dir(name: &str) -> PathBuf {
    let parent = common::fresh_dir("smile-os-paths", name);
    let dir = parent.join(OsStr::from_bytes(b"caf\xe9"));
    std::fs::create_dir_all(&dir).unwrap();
    assert!(dir.to_str().is_none(), "the test needs a non-UTF-8 path");
    dir
}

/// Runs `smile` with arguments that need not be UTF-8, in `cwd`.
fn smile_os(cwd: &Path, args: &[&OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smile"))
        .current_dir(cwd)
        .args(args)
        .output()
        .expect("run smile")
}

fn os(p: &str) -> &OsStr {
    OsStr::new(p)
}

fn as_refs(v: &[OsString]) -> Vec<&OsStr> {
    v.iter().map(OsString::as_os_str).collect()
}

/// Point-goal PD demos: (train, test) files in `dir`.
fn demos(dir: &Path) -> (PathBuf, PathBuf) {
    common::point_goal_demo_files(dir)
}

#[test]
fn meta_dagger_resumes_with_an_expert_under_a_non_utf8_folder() {
    let dir = non_utf8_dir("dagger");
    let (train, _) = demos(&dir);
    let pd = dir.join("pd");
    ok(&smile_os(
        &dir,
        &[
            os("expert"),
            os("--env"),
            os("point-goal"),
            os("--kind"),
            os("scripted-pd"),
            os("-o"),
            pd.as_os_str(),
        ],
    ));
    let run = dir.join("run");
    let train_args = |updates: &str, resume: bool| {
        let mut a: Vec<OsString> = vec!["train".into()];
        if resume {
            a.push("--resume".into());
        } else {
            a.extend([
                "--algo".into(),
                "meta-dagger".into(),
                "--expert".into(),
                pd.clone().into_os_string(),
                "--hidden".into(),
                "8,8".into(),
                "--eval-every".into(),
                "10".into(),
            ]);
        }
        a.extend([
            "--demos".into(),
            train.clone().into_os_string(),
            "-o".into(),
            run.clone().into_os_string(),
            "--updates".into(),
            updates.into(),
            "--quiet".into(),
        ]);
        a
    };
    ok(&smile_os(&dir, &as_refs(&train_args("20", false))));
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("run.json")).unwrap()).unwrap();
    assert!(
        info.get("expert_os").is_some(),
        "run.json keeps the path as the OS gave it: {info}"
    );
    // The resumed run finds the very same expert (a lossy copy would name "caf\u{FFFD}/pd").
    let err = ok(&smile_os(&dir, &as_refs(&train_args("40", true))));
    assert!(err.contains("resuming from step 20"), "{err}");
    std::fs::remove_dir_all(dir.parent().unwrap()).ok();
}

#[test]
fn a_sweep_under_a_non_utf8_folder_runs_and_slurm_refuses_naming_the_path() {
    let dir = non_utf8_dir("sweep");
    demos(&dir);
    let plan = dir.join("plan.toml");
    std::fs::write(
        &plan,
        r#"env = "point-goal"
demos = ["train.safetensors"]
seeds = [0]

[algo.meta-bc]
set = { total_steps = 20, eval_every = 10, policy_hidden = [8, 8] }

[eval]
contexts = "test.safetensors"
rollouts = 1
"#,
    )
    .unwrap();
    // Run from the folder's parent: the cells' demo and context paths are the plan's folder
    // joined with the plan's names, so they carry the non-UTF-8 component to each child.
    let cwd = dir.parent().unwrap();
    let err = ok(&smile_os(
        cwd,
        &[
            os("sweep"),
            plan.as_os_str(),
            os("--jobs"),
            os("1"),
            os("--quiet"),
        ],
    ));
    assert!(err.contains("1 of 1 cells done"), "{err}");
    let eval = cwd.join("runs/plan/meta-bc-s0/eval/eval.json");
    serde_json::from_slice::<serde_json::Value>(&std::fs::read(&eval).unwrap())
        .expect("the cell's evaluation is whole JSON");

    // A Slurm script is text: the plan's path cannot be written into it faithfully.
    let o = smile_os(cwd, &[os("sweep"), plan.as_os_str(), os("--slurm")]);
    assert!(!o.status.success(), "a lossy Slurm script was written");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("not UTF-8") && e.contains("caf"), "{e}");
    std::fs::remove_dir_all(cwd).ok();
}

#[test]
fn a_run_json_naming_another_algorithm_is_named_in_the_refusal() {
    let dir = common::fresh_dir("smile-os-paths", "algo");
    let (train, _) = demos(&dir);
    let run = dir.join("run");
    common::tiny_bc(&train, &run);
    let info = run.join("run.json");
    let text = std::fs::read_to_string(&info).unwrap();
    std::fs::write(&info, text.replace("\"meta-bc\"", "\"smile\"")).unwrap();
    let o = smile(&[
        "train",
        "--resume",
        "--demos",
        s(&train),
        "-o",
        s(&run),
        "--updates",
        "40",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("config.toml") && e.contains("run.json names the algorithm"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
