//! Resume exactness, as a user meets it: a `smile train` process killed with SIGKILL once it has
//! written a checkpoint, then continued with `smile train --resume -o DIR --demos ...`, ends
//! with the same bytes (best-validation policy, last policy, checkpoint) as an uninterrupted
//! run of the same seed. SMILe and Meta-BC.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sim::Family;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("smile-resume-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The checkpoint's update / step counter (`key`), read from `checkpoint.safetensors`, the
/// file a resume reads (`checkpoint.json` beside it is a copy written after it, so a kill
/// between the two leaves the copy one checkpoint behind).
fn checkpoint_count(run: &Path, key: &str) -> u64 {
    let ck = trainer::checkpoint::load(run).unwrap();
    ck.meta[key].as_u64().unwrap()
}

/// Runs `smile train ARGS -o run`, kills it (SIGKILL) as soon as it has written a checkpoint at
/// `after` or later, and returns that checkpoint's counter.
fn train_and_kill(args: &[&str], run: &Path, key: &str, after: u64) -> u64 {
    let mut child = Command::new(env!("CARGO_BIN_EXE_smile"))
        .args(args)
        .args(["-o", s(run)])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let ck = run.join("checkpoint.safetensors");
    while !(ck.exists() && checkpoint_count(run, key) >= after) {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("smile train exited ({status}) before the kill");
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no checkpoint");
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    checkpoint_count(run, key)
}

/// The files an uninterrupted run and a killed-and-resumed run must hold byte for byte.
fn assert_same_bytes(algo: &str, a: &Path, b: &Path) {
    for f in [
        "meta_policy.safetensors",
        "last/meta_policy.safetensors",
        "checkpoint.safetensors",
    ] {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(x == y, "{algo}: {f} differs after kill -9 and --resume");
    }
}

#[test]
fn killed_and_resumed_runs_end_byte_identical_to_uninterrupted_ones() {
    let dir = tmp("exact");
    let train = dir.join("train.safetensors");
    common::pd_demos(
        sim::Split::Train,
        Family::POINT_GOAL.train_tasks()[..8].to_vec(),
        2,
        20,
    )
    .write(&train)
    .unwrap();

    let (mut sc, mut bc) = common::tiny_meta_configs();
    sc.context.head_hidden = vec![8];
    bc.context = sc.context.clone();
    (sc.total_updates, sc.eval_every, sc.eval_contexts) = (400, 50, 1);
    (bc.total_steps, bc.eval_every, bc.patience) = (1500, 100, 0);
    (sc.checkpoint_every, bc.checkpoint_every) = (20, 20);
    (sc.seed, bc.seed) = (5, 5);
    let (smile_toml, bc_toml) = (dir.join("smile.toml"), dir.join("bc.toml"));
    std::fs::write(&smile_toml, toml::to_string(&sc).unwrap()).unwrap();
    std::fs::write(&bc_toml, toml::to_string(&bc).unwrap()).unwrap();

    // Killed after the first held-out evaluation, so that the best-so-far policy and its
    // value are part of what the resumed process must continue from.
    for (algo, config, key, unit, after, total) in [
        (
            "smile",
            &smile_toml,
            "updates",
            "update",
            60,
            sc.total_updates,
        ),
        ("meta-bc", &bc_toml, "steps", "step", 120, bc.total_steps),
    ] {
        let mut args = common::train_args(algo, &train);
        args.extend(["--config", s(config), "--quiet"]);
        let whole = dir.join(format!("{algo}-whole"));
        let cut = dir.join(format!("{algo}-cut"));
        let mut with_out = args.to_vec();
        with_out.extend(["-o", s(&whole)]);
        common::ok(&common::smile(&with_out));
        assert_eq!(checkpoint_count(&whole, key), total);

        let at = train_and_kill(&args, &cut, key, after);
        eprintln!("{algo}: killed with a checkpoint at {at} of {total}");
        assert!(
            at < total,
            "{algo}: the kill came after the run ended (checkpoint at {at})"
        );
        let err = common::ok(&common::smile(&[
            "train",
            "--resume",
            "-o",
            s(&cut),
            "--demos",
            s(&train),
            "--quiet",
        ]));
        assert!(
            err.contains(&format!("resuming from {unit} {at}\n")),
            "{algo}: {err}"
        );
        assert_eq!(checkpoint_count(&cut, key), total);
        assert_same_bytes(algo, &whole, &cut);
    }
    std::fs::remove_dir_all(&dir).ok();
}
