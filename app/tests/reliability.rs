//! Nothing a user runs leaves a result that looks finished but is not (issue 27): killed and
//! concurrent runs, edited resumes, NaN weights, interrupted writes and values that cannot
//! train, each called as a user calls the binary. Every case here failed on the code before.

mod common;
use common::{eval_args, ok, resume_args, s, smile, train_args};

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sim::{Family, Split};

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-reliability", name)
}

/// A fresh directory for the test `name` holding point-goal PD demos: (dir, train, test).
fn with_demos(name: &str) -> (PathBuf, PathBuf, PathBuf) {
    let dir = tmp(name);
    let (train, test) = common::point_goal_demo_files(&dir);
    (dir, train, test)
}

/// `with_demos(name)` and a finished 20-step Meta-BC run `bc` in it: (dir, test, run).
fn with_tiny_bc(name: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (dir, train, test) = with_demos(name);
    let run = dir.join("bc");
    common::tiny_bc(&train, &run);
    (dir, test, run)
}

fn err_of(out: &std::process::Output) -> String {
    assert!(
        !out.status.success(),
        "expected a refusal; stdout: {}\nstderr: {}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Starts a Meta-BC run of 100M steps in the background with the config `cfg_text` (no early
/// stop: it must still be going when the test kills it) and waits until `ready` holds.
fn spawn_long_bc(
    train: &Path,
    run: &Path,
    cfg_text: &str,
    seed: &str,
    ready: impl Fn() -> bool,
) -> std::process::Child {
    let cfg = run.with_extension("toml");
    std::fs::write(&cfg, cfg_text).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_smile"))
        .args(common::meta_bc_args(train, run))
        .args([
            "--config",
            s(&cfg),
            "--updates",
            "100000000",
            "--seed",
            seed,
        ])
        .args(["--eval-every", "20", "--hidden", "8,8", "--quiet"])
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !ready() {
        assert!(t0.elapsed() < Duration::from_secs(60), "no policy written");
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

/// A long Meta-BC run that has written a kept policy and a checkpoint.
fn start_long_bc(train: &Path, run: &Path) -> std::process::Child {
    spawn_long_bc(train, run, "patience = 0\n", "0", || {
        run.join(trainer::META_POLICY_FILE).exists()
            && run.join(trainer::checkpoint::CHECKPOINT_FILE).exists()
    })
}

/// Overwrites the first f32 of the first tensor of the safetensors `file` with NaN.
fn nan_first_float(file: &Path) {
    set_first_float(file, f32::NAN);
}

fn set_first_float(file: &Path, value: f32) {
    let mut bytes = std::fs::read(file).unwrap();
    let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    bytes[8 + header..8 + header + 4].copy_from_slice(&value.to_le_bytes());
    std::fs::write(file, &bytes).unwrap();
}

/// Items 1 and 6: a second writer is refused with the holder's pid; a killed run's policy is
/// refused by eval, export and latents (with the command that finishes it) until the run is
/// finished with --resume; --allow-unfinished uses it with a warning.
#[test]
fn a_killed_run_does_not_look_finished_and_a_second_writer_is_refused() {
    let (dir, train, test) = with_demos("killed");
    let run = dir.join("bc");
    let mut child = start_long_bc(&train, &run);
    let second = smile(&[&resume_args(&train, &run)[..], &["--quiet"]].concat());
    let e = err_of(&second);
    assert!(
        e.contains("in use by another process") && e.contains(&child.id().to_string()),
        "{e}"
    );
    child.kill().unwrap();
    child.wait().unwrap();
    let ev = dir.join("eval");
    let eval = |extra: &[&str]| {
        let mut args = eval_args(&run, &test, &ev);
        args.extend_from_slice(extra);
        smile(&args)
    };
    let e = err_of(&eval(&[]));
    assert!(
        e.contains("unfinished run") && e.contains("smile train --resume"),
        "{e}"
    );
    assert!(!ev.join("eval.json").exists());
    let blob = dir.join("p.blob");
    let e = err_of(&smile(
        &[
            &common::export_args(&run, "f32", &test)[..],
            &["-o", s(&blob)],
        ]
        .concat(),
    ));
    assert!(e.contains("unfinished run"), "{e}");
    let e = err_of(&smile(&[
        "latents",
        "--policy",
        s(&run),
        "--env",
        "point-goal",
        "--contexts",
        s(&test),
        "-o",
        s(&dir.join("z.csv")),
    ]));
    assert!(e.contains("unfinished run"), "{e}");
    let warned = ok(&eval(&["--allow-unfinished"]));
    assert!(
        warned.contains("warning") && warned.contains("unfinished"),
        "{warned}"
    );
    // Finishing it (a budget already spent) marks the kept policy finished.
    let finish = ["--updates", "1", "--quiet"];
    ok(&smile(&[&resume_args(&train, &run)[..], &finish].concat()));
    ok(&eval(&[]));
    std::fs::remove_dir_all(&dir).ok();
}

/// Starts a Meta-BC run whose first checkpoint never comes (`checkpoint_every` past its
/// budget) and kills it with SIGKILL once it has kept a policy: the state a run killed in its
/// first window leaves (issue 57, item 1).
fn killed_before_first_checkpoint(train: &Path, run: &Path, seed: &str) {
    let cfg = "patience = 0\ncheckpoint_every = 1000000000\n";
    let mut child = spawn_long_bc(train, run, cfg, seed, || {
        run.join(trainer::META_POLICY_FILE).exists()
    });
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!run.join(trainer::checkpoint::CHECKPOINT_FILE).exists());
}

/// The metrics log's rows at step 0 and the number of TensorBoard event files in `run`.
fn step0_rows_and_event_files(run: &Path) -> (usize, usize) {
    let log = std::fs::read_to_string(run.join("metrics.jsonl")).unwrap();
    let rows = log
        .lines()
        .filter(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["step"] == 0)
        .count();
    let events = std::fs::read_dir(run.join("tb")).unwrap().count();
    (rows, events)
}

/// Issue 57, items 1 and 2: a run killed after its first kept policy but before its first
/// checkpoint is neither stuck nor mixed into the next run: `--resume` starts it over with its
/// recorded configuration, a fresh start into the directory clears the dead run's log and
/// event files first, and either way the finished run's log holds one start.
#[test]
fn a_run_killed_before_its_first_checkpoint_restarts_cleanly() {
    let (dir, train, _) = with_demos("first-window");
    let run = dir.join("bc");
    killed_before_first_checkpoint(&train, &run, "0");
    let (rows0, _) = step0_rows_and_event_files(&run);
    let resumed = ok(&smile(
        &[&resume_args(&train, &run)[..], &["--updates", "40"]].concat(),
    ));
    assert!(resumed.contains("no checkpoint yet"), "{resumed}");
    let (rows, events) = step0_rows_and_event_files(&run);
    assert_eq!((rows, events), (rows0, 1), "one start in the log");
    let mark = trainer::MetaPolicy::training_mark(&run).unwrap().unwrap();
    assert!(mark.finished && mark.total_updates == 40, "{mark:?}");
    // A fresh run (another seed) into a directory left the same way.
    std::fs::remove_dir_all(&run).unwrap();
    killed_before_first_checkpoint(&train, &run, "0");
    let fresh = ok(&smile(
        &[
            &common::meta_bc_args(&train, &run)[..],
            &[
                "--updates",
                "40",
                "--eval-every",
                "20",
                "--hidden",
                "8,8",
                "--seed",
                "1",
            ],
        ]
        .concat(),
    ));
    assert!(
        fresh.contains("interrupted before its first checkpoint"),
        "{fresh}"
    );
    assert_eq!(step0_rows_and_event_files(&run), (rows0, 1));
    let cfg = std::fs::read_to_string(run.join("config.toml")).unwrap();
    assert!(cfg.contains("seed = 1"), "{cfg}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Item 7: --resume refuses flags it would ignore, an edited config.toml, and other demos.
#[test]
fn resume_refuses_changed_flags_edited_config_and_other_demos() {
    let (dir, train, _) = with_demos("resume");
    let run = dir.join("bc");
    let tail = ["--hidden", "8,8", "--eval-every", "20", "--quiet"];
    let base = [&common::meta_bc_args(&train, &run)[..], &tail].concat();
    ok(&smile(&[&base[..], &["--updates", "40"]].concat()));
    let resume = |extra: &[&str]| {
        let mut args = resume_args(&train, &run);
        args.push("--quiet");
        args.extend_from_slice(extra);
        smile(&args)
    };
    let e = err_of(&resume(&["--seed", "7", "--updates", "60"]));
    assert!(e.contains("--seed") && e.contains("Only --updates"), "{e}");
    let e = err_of(&resume(&["--hidden", "32,32", "--updates", "60"]));
    assert!(e.contains("policy_hidden"), "{e}");
    // An edited config.toml is refused, not silently rewritten.
    let cfg_path = run.join("config.toml");
    let original = std::fs::read_to_string(&cfg_path).unwrap();
    let edited = original.replace("seed = 0", "seed = 3");
    assert_ne!(
        edited, original,
        "config.toml has no `seed = 0` line:\n{original}"
    );
    std::fs::write(&cfg_path, &edited).unwrap();
    let e = err_of(&resume(&["--updates", "60"]));
    assert!(e.contains("`seed`") && e.contains("config.toml"), "{e}");
    // A flag given with the run's own value is not blamed for the file's change.
    let e = err_of(&resume(&["--hidden", "8,8", "--updates", "60"]));
    assert!(
        e.contains("but config.toml changes `seed`") && !e.contains("--hidden"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&cfg_path).unwrap(), edited);
    std::fs::write(&cfg_path, &original).unwrap();
    // Other demos (another file's checksum) are refused.
    let other = dir.join("other.safetensors");
    common::pd_demos(
        Split::Train,
        Family::POINT_GOAL.train_tasks()[..8].to_vec(),
        3,
        20,
    )
    .write(&other)
    .unwrap();
    let budget = ["--updates", "60", "--quiet"];
    let e = err_of(&smile(&[&resume_args(&other, &run)[..], &budget].concat()));
    assert!(
        e.contains("are not the file") && e.contains("SHA-256") && e.contains("(--demos)"),
        "{e}"
    );
    // What may change, changes: the budget.
    ok(&resume(&["--updates", "60"]));
    let cfg = std::fs::read_to_string(&cfg_path).unwrap();
    assert!(cfg.contains("total_steps = 60"), "{cfg}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Item 8: a policy file holding NaN weights is refused by name, not evaluated to a number.
#[test]
fn nan_weights_are_refused() {
    let (dir, test, run) = with_tiny_bc("nan");
    nan_first_float(&run.join(trainer::META_POLICY_FILE));
    let e = err_of(&smile(&eval_args(&run, &test, &dir.join("ev"))));
    assert!(e.contains("non-finite") && e.contains("diverged"), "{e}");
    // A finite weight of 3e38 (issue 72, item 8: evaluated, and a resume failed at update 201
    // without naming the file) is as diverged.
    set_first_float(&run.join(trainer::META_POLICY_FILE), 3e38);
    let e = err_of(&smile(&eval_args(&run, &test, &dir.join("ev"))));
    assert!(
        e.contains(trainer::META_POLICY_FILE) && e.contains("overflows f32"),
        "{e}"
    );
    // The same in the run's checkpoint: a resume names the file and the tensor (issue 57,
    // item 9), not a loss gone NaN some updates later.
    nan_first_float(&run.join(trainer::checkpoint::CHECKPOINT_FILE));
    let train = dir.join("train.safetensors");
    let e = err_of(&smile(
        &[
            &resume_args(&train, &run)[..],
            &["--updates", "40", "--quiet"],
        ]
        .concat(),
    ));
    assert!(
        e.contains("checkpoint.safetensors") && e.contains("non-finite"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 57, item 9: Meta-DAgger given an expert of another family says which family it got.
#[test]
fn a_dagger_expert_of_another_family_is_named() {
    let (dir, train, _) = with_demos("dagger-family");
    let walker = dir.join("walker-expert");
    ok(&smile(&[
        "expert",
        "--env",
        "walker-dyn",
        "--total-steps",
        "30",
        "--learning-starts",
        "10",
        "--horizon",
        "10",
        "--hidden",
        "8,8",
        "--batch-size",
        "8",
        "--eval-episodes",
        "1",
        "-o",
        s(&walker),
        "--quiet",
    ]));
    let e = err_of(&smile(&[
        "train",
        "--algo",
        "meta-dagger",
        "--demos",
        s(&train),
        "--expert",
        s(&walker),
        "-o",
        s(&dir.join("dagger")),
        "--updates",
        "10",
        "--quiet",
    ]));
    assert!(e.contains("walker-dyn") && e.contains("point-goal"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Item 4: `smile demos` onto an existing file replaces it atomically: a refused or failed
/// recording leaves the old file whole, and no temporary file is left beside it.
#[test]
fn demos_never_truncate_an_existing_file() {
    let dir = tmp("demos");
    let pd = common::scripted_pd_expert(dir.join("pd"));
    let out = dir.join("d.safetensors");
    let record = [
        "demos",
        "--env",
        "point-goal",
        "--horizon",
        "10",
        "--expert",
        s(&pd),
        "-o",
        s(&out),
    ];
    let rec = |extra: &[&str]| smile(&[&record[..], extra].concat());
    ok(&rec(&["--per-task", "1"]));
    let before = std::fs::read(&out).unwrap();
    // A full disk, as the kernel reports it: the child may write files of at most 4 KiB
    // (RLIMIT_FSIZE, with SIGXFSZ ignored so the write fails with EFBIG instead of killing
    // it). Recording 16 demos a task needs more: the write fails, the old file stays whole.
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_smile"));
    cmd.args(record).args(["--per-task", "16"]);
    use std::os::unix::process::CommandExt;
    // SAFETY: only async-signal-safe calls (setrlimit, signal) between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 4096,
                rlim_max: 4096,
            };
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let result = cmd.output().unwrap();
    let e = err_of(&result);
    assert!(e.contains(s(&out)), "{e}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        before,
        "the old file was damaged"
    );
    sim::DemoDataset::read(&out).unwrap();
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.contains("tmp")), "{names:?}");
    // Zero trajectories or subsampling by 0 are refused at the door.
    for bad in [["--per-task", "0"], ["--subsample", "0"]] {
        let e = err_of(&rec(&bad));
        assert!(e.contains(bad[0]) && e.contains("at least 1"), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Items 11 and 12: numeric flags are checked at the door with the flag's name and range.
#[test]
fn numeric_flags_are_validated_by_name() {
    let (dir, train, test) = with_demos("flags");
    let run = dir.join("r");
    let train_args = ["train", "--demos", s(&train), "-o", s(&run)];
    let train_with = |extra: &[&str]| smile(&[&train_args[..], extra].concat());
    for (flag, value) in [
        ("--gp-weight", "nan"),
        ("--gp-weight=-1", ""),
        ("--reward-scale", "0"),
        ("--reward-scale", "inf"),
        ("--updates", "0"),
    ] {
        let e = if value.is_empty() {
            err_of(&train_with(&[flag, "--quiet"]))
        } else {
            err_of(&train_with(&["--updates", "5", flag, value, "--quiet"]))
        };
        let name = flag.split('=').next().unwrap();
        assert!(e.contains(name), "{flag} {value}: {e}");
        assert!(!run.exists(), "{flag} {value} created the run directory");
    }
    // A setting the algorithm lacks is refused by its flag (its place among the settings the
    // flags gave maps back to it), and nothing is created.
    let args = [
        "--algo",
        "meta-bc",
        "--updates",
        "5",
        "--seed",
        "3",
        "--gp-weight",
        "1",
    ];
    let e = err_of(&train_with(&[&args[..], &["--quiet"]].concat()));
    assert!(
        e.contains("--gp-weight is a SMILe setting") && e.contains("meta-bc"),
        "{e}"
    );
    assert!(!run.exists(), "a refused setting created the run directory");
    // Config files: NaN and negative values are refused by key (log_std_min = nan panicked).
    for (text, key) in [
        ("gp_weight = nan\n", "gp_weight"),
        ("logit_clamp = nan\n", "logit_clamp"),
        ("[sac]\nlog_std_min = nan\n", "sac.log_std_min"),
        ("[sac]\nactor_lr = -0.001\n", "sac.actor_lr"),
    ] {
        let cfg = dir.join("bad.toml");
        std::fs::write(&cfg, text).unwrap();
        let e = err_of(&train_with(&["--config", s(&cfg), "--quiet"]));
        assert!(e.contains(key) && e.contains("finite"), "{text}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    let e = err_of(&smile(
        &[&["--threads", "1000"][..], &train_args, &["--quiet"]].concat(),
    ));
    assert!(e.contains("--threads") && e.contains("1 to 64"), "{e}");
    // Zero, and counts no run finishes (issue 72, item 4: they ran forever or aborted), from a
    // flag as from a config: refused with the bound named.
    for (flag, value, bound) in [
        ("--rollouts", "0", "at least 1"),
        ("--rollouts", "4294967296", "at most 16777216"),
        ("--horizon", "18446744073709551615", "at most 1000000"),
    ] {
        let e = err_of(&smile(&[
            "eval",
            "--policy",
            s(&run),
            "--contexts",
            s(&test),
            flag,
            value,
        ]));
        assert!(e.contains(flag) && e.contains(bound), "{e}");
    }
    let cfg = dir.join("huge.toml");
    std::fs::write(&cfg, "replay_per_task = 1099511627776\n").unwrap();
    let e = err_of(&train_with(&["--config", s(&cfg), "--quiet"]));
    assert!(
        e.contains("replay_per_task must be a count from 1 to 16777216"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Item 5: the quickstart refuses a non-empty output directory unless told --force.
#[test]
fn quickstart_refuses_a_non_empty_directory() {
    let dir = tmp("quickstart");
    let out = dir.join("qs");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("eval.json"), "{}").unwrap();
    let e = err_of(&smile(&[
        "quickstart",
        "--budget",
        "tiny",
        "--out",
        s(&out),
        "--quiet",
    ]));
    assert!(
        e.contains("--force") && e.contains("nothing was touched"),
        "{e}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("eval.json")).unwrap(),
        "{}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Item 13: messages that name what is wrong: `eval -o` onto a file names the path; an
/// unfinished expert directory says how to finish it.
#[test]
fn messages_name_the_path_and_the_fix() {
    let (dir, test, run) = with_tiny_bc("messages");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let e = err_of(&smile(&eval_args(&run, &test, &file)));
    assert!(e.contains(s(&file)), "{e}");
    // An expert run with a checkpoint but no policy yet.
    let ex = dir.join("expert");
    ok(&smile(&[
        "expert",
        "--env",
        "point-goal",
        "--total-steps",
        "300",
        "--learning-starts",
        "100",
        "--checkpoint-every",
        "100",
        "--hidden",
        "8,8",
        "--batch-size",
        "16",
        "-o",
        s(&ex),
        "--quiet",
    ]));
    std::fs::remove_file(ex.join("policy.safetensors")).unwrap();
    let e = err_of(&smile(&[
        "demos",
        "--env",
        "point-goal",
        "--per-task",
        "1",
        "--expert",
        s(&ex),
        "-o",
        s(&dir.join("d.safetensors")),
    ]));
    assert!(
        e.contains("unfinished expert run") && e.contains("(--resume)"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 57, items 6-8 and 10: a zero a flag refuses is refused from a config file too (no
/// untrained policy marked finished), and so are a config naming another family than the
/// demos', a zero-step expert, a zero subsample, the same evaluation counted twice, latents of
/// one plant's policy on the other plant's contexts, and a quantized ONNX export.
#[test]
fn values_a_flag_refuses_are_refused_from_files_and_every_command() {
    let (dir, train, test) = with_demos("zeros");
    common::tiny_bc(&train, &dir.join("bc"));
    let run = dir.join("r");
    let cfg = dir.join("c.toml");
    for (algo, text) in [
        ("smile", "total_updates = 0"),
        ("smile", "horizon = 0"),
        ("smile", "rollouts_per_iter = 0"),
        ("meta-bc", "total_steps = 0"),
        ("meta-bc", "env = \"cheetah-vel\""),
    ] {
        std::fs::write(&cfg, text).unwrap();
        let rest = ["--config", s(&cfg), "-o", s(&run), "--quiet"];
        let e = err_of(&smile(&[&train_args(algo, &train)[..], &rest].concat()));
        let key = text.split(' ').next().unwrap();
        assert!(e.contains(key), "{text}: {e}");
        assert!(!run.join(trainer::META_POLICY_FILE).exists(), "{text}");
    }
    let e = err_of(&smile(&[
        "expert",
        "--env",
        "point-goal",
        "--total-steps",
        "0",
        "-o",
        s(&dir.join("x")),
        "--quiet",
    ]));
    assert!(e.contains("total_steps"), "{e}");
    let e = err_of(&smile(&[
        "quickstart",
        "--subsample",
        "0",
        "--out",
        s(&dir.join("q")),
    ]));
    assert!(e.contains("--subsample"), "{e}");
    // A width no machine holds is refused by the parser, not by an allocation abort (issue 72).
    let wide = dir.join("wide");
    for (cmd, first) in [
        ("train", ["--demos", s(&train)]),
        ("expert", ["--env", "point-goal"]),
    ] {
        let out = smile(&[
            cmd,
            first[0],
            first[1],
            "--hidden",
            "128,4294967296",
            "-o",
            s(&wide),
        ]);
        let e = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{cmd}: {e}");
        assert!(e.contains("--hidden") && e.contains("16384"), "{cmd}: {e}");
    }
    // A budget that trains nothing, and demos that keep no transition, are refused by name
    // (issue 72, item 4): before, both ran and exited 0.
    let e = err_of(&smile(&[
        "expert",
        "--env",
        "point-goal",
        "--total-steps",
        "100",
        "--learning-starts",
        "200",
        "-o",
        s(&wide),
        "--quiet",
    ]));
    assert!(e.contains("learning") && e.contains("total"), "{e}");
    assert!(!wide.join("policy.safetensors").exists(), "{e}");
    let pd = dir.join("pd");
    ok(&smile(&["expert", "--kind", "scripted-pd", "-o", s(&pd)]));
    let e = err_of(&smile(&[
        "demos",
        "--env",
        "point-goal",
        "--expert",
        s(&pd),
        "--split",
        "test",
        "--subsample",
        "100000",
        "-o",
        s(&dir.join("empty.safetensors")),
    ]));
    assert!(
        e.contains("subsample") && e.contains("shortest demo"),
        "{e}"
    );
    assert!(!dir.join("empty.safetensors").exists(), "{e}");
    // An evaluation of no episode is refused, not written as a metric of 0 (issue 72, item 6).
    let out = smile(&[
        "expert",
        "--env",
        "point-goal",
        "--eval-episodes",
        "0",
        "-o",
        s(&wide),
    ]);
    let e = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("--eval-episodes") && !wide.exists(), "{e}");
    // The same evaluation twice is one seed, not two with a std of 0.
    let ev = dir.join("eval");
    ok(&smile(&eval_args(&dir.join("bc"), &test, &ev)));
    let json = ev.join("eval.json");
    let e = err_of(&smile(&[
        "report",
        s(&json),
        s(&json),
        "-o",
        s(&dir.join("rep")),
    ]));
    assert!(e.contains("same evaluation"), "{e}");
    // Latents of a Rapier policy on contexts said to be MuJoCo's.
    let mut mujoco = sim::DemoDataset::read(&test).unwrap();
    mujoco.physics = sim::Physics::Mujoco;
    let mj = dir.join("mj.safetensors");
    mujoco.write(&mj).unwrap();
    let e = err_of(&smile(&[
        "latents",
        "--policy",
        s(&dir.join("bc")),
        "--env",
        "point-goal",
        "--contexts",
        s(&mj),
        "-o",
        s(&dir.join("z.csv")),
    ]));
    assert!(e.contains("mujoco"), "{e}");
    let e = err_of(&smile(&[
        "export",
        "--policy",
        s(&dir.join("bc")),
        "--format",
        "onnx",
        "--quant",
        "w8a8",
        "--contexts",
        s(&test),
        "-o",
        s(&dir.join("onnx")),
    ]));
    assert!(e.contains("--quant w8a8") && e.contains("float32"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 72, item 6: a context size beyond the demos a task has is refused by name, not
/// measured at the demos' count and recorded as the size asked for.
#[test]
fn context_sizes_beyond_the_demos_given_are_refused() {
    let (dir, test, run) = with_tiny_bc("context-sizes");
    let ev = dir.join("eval");
    let mut args = eval_args(&run, &test, &ev);
    args.extend_from_slice(&["--context-sizes", "1,50"]);
    let e = err_of(&smile(&args));
    assert!(
        e.contains("--context-sizes") && e.contains("context size 50") && e.contains("(1)"),
        "{e}"
    );
    assert!(!ev.join("eval.json").exists());
    // The sizes the demos hold are measured and recorded as such.
    let mut args = eval_args(&run, &test, &ev);
    args.extend_from_slice(&["--context-sizes", "1"]);
    ok(&smile(&args));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ev.join("eval.json")).unwrap()).unwrap();
    assert_eq!(report["protocol"]["context_sizes"], serde_json::json!([1]));
}

/// Issue 72, item 5: `smile device-table` measures the shipped blob or refuses, naming it: a
/// missing, changed or foreign `policy.blob` never gives a table.
#[test]
fn device_table_refuses_a_shipped_blob_that_is_not_the_one_shipped() {
    let dir = tmp("shipped-blob");
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/policies/point-goal-rapier-smile");
    let policy = dir.join("point-goal-rapier-smile");
    copy_files(&src, &policy);
    let blob = policy.join("policy.blob");
    let table = |out: &str| smile(&["device-table", s(&policy), "-o", s(&dir.join(out))]);
    // A changed byte.
    let mut bytes = std::fs::read(&blob).unwrap();
    let n = bytes.len() - 1;
    bytes[n] ^= 0x01;
    std::fs::write(&blob, &bytes).unwrap();
    let e = err_of(&table("t1"));
    assert!(e.contains("policy.blob") && e.contains("SHA256SUMS"), "{e}");
    // Missing.
    std::fs::remove_file(&blob).unwrap();
    let e = err_of(&table("t2"));
    assert!(
        e.contains("policy.blob") && e.contains("smile export"),
        "{e}"
    );
    // Another family's blob, its checksum list written again to pass (a foreign blob).
    let other = src.join("../cheetah-vel-rapier-meta-bc/policy.blob");
    std::fs::copy(&other, &blob).unwrap();
    std::fs::remove_file(policy.join("SHA256SUMS")).unwrap();
    let e = err_of(&table("t3"));
    assert!(
        e.contains("policy.blob") && e.contains("not of this point-goal policy"),
        "{e}"
    );
    assert!(!dir.join("t3").join("device-table.json").exists());
}

/// Issue 72, item 6: `smile device-table` measures new tasks only on tasks the policy never
/// trained on, and calibrates only on meta-train demos.
#[test]
fn device_table_refuses_train_tasks_as_new_and_test_demos_as_calibration() {
    let dir = tmp("device-table-inputs");
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies");
    let shipped = assets.join("point-goal-rapier-smile");
    let train = assets.join("point-goal-demos-train.safetensors");
    let out = dir.join("t");
    let e = err_of(&smile(&[
        "device-table",
        s(&shipped),
        "--new-tasks",
        s(&train),
        "-o",
        s(&out),
    ]));
    assert!(
        e.contains("meta-train task") && e.contains("point-goal-demos-train"),
        "{e}"
    );
    // A copy whose deploy.toml calibrates on the test demos.
    let policy = dir.join("pg");
    copy_files(&shipped, &policy);
    let test = assets.join("point-goal-demos-test.safetensors");
    let manifest = format!(
        "method = \"SMILe\"\ndemos = {:?}\ncontexts = {:?}\n",
        s(&test),
        s(&test)
    );
    std::fs::write(policy.join("deploy.toml"), manifest).unwrap();
    let e = err_of(&smile(&["device-table", s(&policy), "-o", s(&out)]));
    assert!(
        e.contains("deploy.toml") && e.contains("calibration") && e.contains("test demos"),
        "{e}"
    );
    assert!(!out.join("device-table.json").exists());
}

/// Copies the files of the folder `src` into a new folder `dst`.
fn copy_files(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dst.join(p.file_name().unwrap())).unwrap();
    }
}

/// Issue 72, item 8: `--resume` of a finished run whose checkpoint is gone is refused,
/// naming the missing file, and the finished policy is kept (before: "starting it over",
/// then a refusal saying to resume it).
#[test]
fn resuming_a_finished_run_without_its_checkpoint_names_the_missing_file() {
    let (dir, train, _test) = with_demos("finished-no-checkpoint");
    let run = dir.join("bc");
    common::tiny_bc(&train, &run);
    let ck = run.join("checkpoint.safetensors");
    std::fs::remove_file(&ck).unwrap();
    let policy = std::fs::read(run.join("meta_policy.safetensors")).unwrap();
    let mut args = resume_args(&train, &run);
    args.extend_from_slice(&["--updates", "40", "--quiet"]);
    let e = err_of(&smile(&args));
    assert!(
        e.contains("checkpoint.safetensors")
            && e.contains("is gone")
            && !e.contains("starting it over"),
        "{e}"
    );
    assert_eq!(
        std::fs::read(run.join("meta_policy.safetensors")).unwrap(),
        policy
    );
}
