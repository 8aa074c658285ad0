//! What a user sees when `smile` refuses: one `error:` line that says what to do (the OS error
//! once, no "Caused by" chain, no backtrace unless RUST_BACKTRACE is set), exit status 1;
//! "invalid config:" only for configuration; and plain progress lines when stderr is not a
//! terminal.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use sim::{Family, Split};

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-cli-msg", name)
}

use common::{one_line_error, s};

/// `smile` with stdout and stderr piped (stderr is not a terminal), RUST_BACKTRACE unset and
/// the extra environment `env`.
fn smile_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_smile"));
    cmd.args(args).env_remove("RUST_BACKTRACE");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run smile")
}

/// Cheetah-vel test-split "demos" of an open-loop action: only family, split and shapes matter.
fn cheetah_test_demos(path: &Path) {
    let fam = Family::CHEETAH_VEL;
    common::open_loop_demos(fam, Split::Test, fam.test_tasks(), 5)
        .write(path)
        .unwrap();
}

/// Point-goal train demos of 6 goals and a tiny Meta-BC run on them, in `dir`.
fn tiny_run(dir: &Path, quiet: bool, env: &[(&str, &str)]) -> (PathBuf, PathBuf, Output) {
    let train = dir.join("train.safetensors");
    common::train_demos(6, 2, 20).write(&train).unwrap();
    let run = dir.join("bc");
    let mut args = common::meta_bc_args(&train, &run);
    args.extend(["--updates", "400", "--eval-every", "0", "--hidden", "16,16"]);
    if quiet {
        args.push("--quiet");
    }
    let out = smile_env(&args, env);
    (train, run, out)
}

#[test]
fn errors_are_one_line_that_says_what_to_do() {
    let dir = tmp("errors");
    let missing = dir.join("missing.safetensors");
    // A missing file: the input, the file, the OS error once and the flag.
    let line = one_line_error(&smile_env(
        &["train", "--demos", s(&missing), "-o", s(&dir.join("r"))],
        &[],
    ));
    assert!(
        line.contains(&format!("the demos {}", s(&missing))) && line.ends_with("(--demos)"),
        "{line}"
    );
    assert_eq!(line.matches("No such file").count(), 1, "{line}");
    assert_eq!(line.matches(s(&missing)).count(), 1, "{line}");

    // Demos of another family than --env: the file, the family that fits, the flag.
    let cheetah = dir.join("cheetah-test.safetensors");
    cheetah_test_demos(&cheetah);
    let line = one_line_error(&smile_env(
        &[
            "train",
            "--env",
            "point-goal",
            "--demos",
            s(&cheetah),
            "-o",
            s(&dir.join("r")),
        ],
        &[],
    ));
    assert!(
        line.contains(&format!("the demos {} hold cheetah-vel demos", s(&cheetah)))
            && line.contains("choose the family cheetah-vel")
            && line.ends_with("(--env)"),
        "{line}"
    );
    assert!(!dir.join("r").exists());
    // Without --env the family is the file's: here a meta-test file, refused as such.
    let line = one_line_error(&smile_env(
        &["train", "--demos", s(&cheetah), "-o", s(&dir.join("r"))],
        &[],
    ));
    assert!(line.contains("meta-test"), "{line}");
    assert!(!dir.join("r").exists());

    // A policy trained on another family than --env says which --env to pass.
    let (_, run, out) = tiny_run(&dir, true, &[]);
    common::ok(&out);
    let line = one_line_error(&smile_env(
        &[
            "eval",
            "--policy",
            s(&run),
            "--env",
            "cheetah-vel",
            "--contexts",
            s(&cheetah),
            "-o",
            s(&dir.join("ev")),
        ],
        &[],
    ));
    assert!(
        line.contains("was trained on point-goal")
            && line.contains("evaluate it on point-goal (--env)"),
        "{line}"
    );

    // Not configuration: no "invalid config:".
    let line = one_line_error(&smile_env(
        &[
            "quickstart",
            "--env",
            "walker-dyn",
            "--out",
            s(&dir.join("qs")),
        ],
        &[],
    ));
    assert!(
        !line.contains("invalid config") && line.contains("--budget"),
        "{line}"
    );
    let line = one_line_error(&smile_env(
        &[
            "export",
            "--policy",
            s(&run),
            "--quant",
            "w9",
            "--contexts",
            s(&cheetah),
            "-o",
            "x",
        ],
        &[],
    ));
    assert!(
        !line.contains("invalid config") && line.contains("w8a8"),
        "{line}"
    );
    // Configuration: "invalid config:".
    let line = one_line_error(&smile_env(
        &["expert", "--batch-size", "0", "-o", s(&dir.join("ex"))],
        &[],
    ));
    assert!(
        line.starts_with("error: invalid config: sac.batch_size"),
        "{line}"
    );
    // A flag of one family on another: refused before any training.
    let line = one_line_error(&smile_env(
        &[
            "expert",
            "--env",
            "cheetah-vel",
            "--nominal",
            "-o",
            s(&dir.join("nominal")),
        ],
        &[],
    ));
    assert!(line.contains("cheetah-vel has none"), "{line}");

    // RUST_BACKTRACE asks for the whole chain.
    let out = smile_env(
        &["train", "--demos", s(&missing), "-o", s(&dir.join("r"))],
        &[("RUST_BACKTRACE", "1")],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with("error: ") && err.lines().count() > 1,
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_piped_run_prints_plain_progress_lines() {
    let dir = tmp("progress");
    let interval = [("SMILE_PROGRESS_INTERVAL_S", "0.05")];
    let (_, _, out) = tiny_run(&dir, false, &interval);
    let err = common::ok(&out);
    let line = err
        .lines()
        .find(|l| l.starts_with("[progress] "))
        .unwrap_or_else(|| panic!("no progress line in: {err}"));
    assert!(
        line.contains("/400 steps (") && line.contains("ETA "),
        "{line}"
    );
    // --quiet prints none.
    let quiet_dir = dir.join("quiet");
    std::fs::create_dir_all(&quiet_dir).unwrap();
    let (_, _, out) = tiny_run(&quiet_dir, true, &interval);
    let err = common::ok(&out);
    assert!(!err.contains("[progress]"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `--sensing FILE` (issue 73): the shipped preset trains a run through the device's senses
/// and lands in its config.toml; a file that is not a `[sensing]` section, or one no sensor
/// can read, is refused before any training, naming the file.
#[test]
fn the_sensing_preset_trains_through_the_sensors_and_a_bad_one_is_refused() {
    let dir = tmp("sensing");
    let train = dir.join("train.safetensors");
    common::train_demos(6, 2, 20).write(&train).unwrap();
    let preset = format!(
        "{}/../docs/configs/sensing-noise01-adc12.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let run = dir.join("bc");
    let mut args = common::meta_bc_args(&train, &run);
    args.extend(["--updates", "50", "--eval-every", "0", "--hidden", "16,16"]);
    args.extend(["--quiet", "--sensing", &preset]);
    common::ok(&smile_env(&args, &[]));
    let config = std::fs::read_to_string(run.join("config.toml")).unwrap();
    assert!(
        config.contains("[sensing]") && config.contains("adc_bits = 12"),
        "{config}"
    );

    for (name, text, says) in [
        (
            "typo.toml",
            "[sensing]\nnoise = 0.01\n",
            "not a [sensing] section",
        ),
        (
            "share.toml",
            "[sensing]\nnoise_std = 0.01\nfraction = 2.0\n",
            "fraction = 2",
        ),
    ] {
        let bad = dir.join(name);
        std::fs::write(&bad, text).unwrap();
        let out_dir = dir.join(format!("r-{name}"));
        let mut args = common::meta_bc_args(&train, &out_dir);
        args.extend(["--sensing", s(&bad)]);
        let line = one_line_error(&smile_env(&args, &[]));
        assert!(line.contains(s(&bad)) && line.contains(says), "{line}");
        assert!(!out_dir.exists());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `smile distill` (issue 73): a trained policy distilled through the position-sensing preset
/// writes a policy folder the other commands load, with `distill.json`; a zero budget and demos
/// of another family are refused, naming the flag or the file.
#[test]
fn distill_writes_a_policy_and_refuses_bad_input_by_name() {
    let dir = tmp("distill");
    let (train, run, out) = tiny_run(&dir, true, &[]);
    common::ok(&out);
    let preset = format!(
        "{}/../docs/configs/sensing-positions.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let student = dir.join("student");
    let base = [
        "distill",
        "--policy",
        s(&run),
        "--demos",
        s(&train),
        "--sensing",
        &preset,
        "--horizon",
        "20",
        "--rounds",
        "2",
    ];
    let args = [&base[..], &["--steps", "40", "-o", s(&student)]].concat();
    let said = String::from_utf8_lossy(&smile_env(&args, &[]).stdout).into_owned();
    assert!(said.contains("action gap"), "{said}");
    trainer::MetaPolicy::load(&student).unwrap();
    let report = std::fs::read_to_string(student.join("distill.json")).unwrap();
    assert!(report.contains("\"positions\": true") && report.contains("closed_loop_ticks"));

    let zero = [&base[..], &["--steps", "0", "-o", s(&student)]].concat();
    let refused = smile_env(&zero, &[]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(err.contains("--steps"), "{err}");
    let cheetah = dir.join("cheetah.safetensors");
    cheetah_test_demos(&cheetah);
    let mut wrong = base.to_vec();
    wrong[4] = s(&cheetah);
    let nowhere = dir.join("no");
    let wrong = [&wrong[..], &["-o", s(&nowhere)]].concat();
    let err = one_line_error(&smile_env(&wrong, &[]));
    assert!(err.contains("cheetah") && err.contains("demos"), "{err}");
    assert!(
        !dir.join("no").exists(),
        "nothing written for refused input"
    );
    std::fs::remove_dir_all(&dir).ok();
}
