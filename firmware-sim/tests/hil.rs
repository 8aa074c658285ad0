//! Hardware in the loop over a real OS serial device (issue 55): `firmware-sim device` in its
//! own process on a pseudo-terminal, `firmware-sim host` driving it. On a clean line the run is
//! the in-process `firmware-sim run` bit for bit; a corrupting line finishes with its errors
//! counted; a device killed mid-run is survived (safe action held, reconnect, upload again);
//! a silent host trips the device's watchdog; a blob the device cannot hold is refused with the
//! device's reason. Every process here is bounded in time and killed at the end.

mod common;
use common::hil::{columns, hil_json};
use common::{ok, s, tmp};

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use firmware_sim::reference::pd_point_goal_blob;
use infer_core::Quant;
use sim::{DemoDataset, Family, Split, TaskDemos};

/// A device process, killed when dropped.
struct DeviceProcess {
    child: Child,
    log: PathBuf,
    link: PathBuf,
}

impl DeviceProcess {
    /// `firmware-sim device --pty LINK` with `extra` flags; waits for the link to appear.
    fn start(dir: &Path, link: &Path, extra: &[&str], name: &str) -> Self {
        let log = dir.join(format!("{name}.log"));
        let child = Command::new(env!("CARGO_BIN_EXE_firmware-sim"))
            .args(["device", "--pty", s(link)])
            .args(extra)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        while !std::fs::read_to_string(&log)
            .unwrap_or_default()
            .contains("booted")
        {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "the device did not boot"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Self {
            child,
            log,
            link: link.to_path_buf(),
        }
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Waits up to `limit` for `text` in the device's log.
    fn wait_for(&self, text: &str, limit: Duration) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < limit {
            if self.log().contains(text) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

impl Drop for DeviceProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        // A killed device leaves its link naming a pty number the system hands to the next
        // pty opened, in this process another test's device: a host reconnecting through the
        // stale link would reach that one. Its supervisor would remove the link; so does this.
        let _ = std::fs::remove_file(&self.link);
    }
}

/// A point-goal PD blob with its export report, and one PD demo of each of the first four
/// test goals: (blob, demos).
fn blob_and_demos(dir: &Path) -> (PathBuf, PathBuf) {
    let fam = Family::POINT_GOAL;
    let mut ds = DemoDataset::new(fam, Split::Test, "scripted-pd");
    for (i, task) in fam.test_tasks().into_iter().take(4).enumerate() {
        ds.tasks.push(TaskDemos {
            task,
            trajectories: vec![common::pd_demo(&task, 100 + i as u64)],
        });
    }
    let demos: Vec<_> = ds.tasks.iter().map(|t| &t.trajectories[0]).collect();
    let blob = pd_point_goal_blob(Quant::W8A8, &demos).unwrap();
    let (blob_path, demos_path) = (dir.join("pd.blob"), dir.join("demos.safetensors"));
    std::fs::write(&blob_path, blob).unwrap();
    ds.write(&demos_path).unwrap();
    (blob_path, demos_path)
}

/// `firmware-sim host` (or `run`, with `port` None) of the blob on test goal 2, `ticks` ticks,
/// bounded by a 60 s timeout.
fn drive(port: Option<&Path>, blob: &Path, demos: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut cmd = Command::new("timeout");
    cmd.args(["60", env!("CARGO_BIN_EXE_firmware-sim")]);
    match port {
        Some(p) => cmd.args(["host", "--port", s(p)]),
        None => cmd.arg("run"),
    };
    cmd.args(["--blob", s(blob), "--env", "point-goal", "--task", "2"])
        .args(["--context", s(demos), "--seed", "7", "-o", s(out)])
        .args(extra)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

#[test]
fn a_clean_pty_run_is_the_in_process_run_bit_for_bit_and_a_silent_host_trips_the_watchdog() {
    let dir = tmp("hil-clean");
    let (blob, demos) = blob_and_demos(&dir);
    let link = dir.join("tty");
    // Unpaced: a round trip of tens of microseconds against a 100 ms deadline, so that a
    // loaded CI machine cannot make a tick miss (a held action would differ from the run's).
    let device = DeviceProcess::start(
        &dir,
        &link,
        &["--watchdog-ms", "300", "--baud", "0"],
        "device",
    );
    let host_out = dir.join("host");
    let err = ok(&drive(
        Some(&link),
        &blob,
        &demos,
        &host_out,
        &["--ticks", "25", "--baud", "0"],
    ));
    let ticks = ["--ticks", "25"];
    assert!(err.contains("uploaded the blob"), "{err}");
    let run_out = dir.join("run");
    ok(&drive(None, &blob, &demos, &run_out, &ticks));
    let cols = ["computed", "action", "obs"];
    let (host, local) = (columns(&host_out, &cols), columns(&run_out, &cols));
    assert_eq!(host.len(), 25);
    assert_eq!(
        host, local,
        "the device over the port acts as the one in process"
    );
    let hil = hil_json(&host_out);
    assert_eq!(hil["deadline_misses"], 0, "{hil}");
    assert_eq!(hil["link"]["bad_frames"], 0, "{hil}");
    // The host has stopped talking: the device holds the safe action.
    assert!(
        device.wait_for("watchdog: no tick for", Duration::from_secs(5)),
        "{}",
        device.log()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_corrupting_line_still_finishes_with_its_errors_counted() {
    let dir = tmp("hil-lossy");
    let (blob, demos) = blob_and_demos(&dir);
    let link = dir.join("tty");
    let _device = DeviceProcess::start(&dir, &link, &["--baud", "0"], "device");
    let out = dir.join("host");
    let faults = [
        "--ticks",
        "30",
        "--baud",
        "0",
        "--link-corrupt",
        "0.1",
        "--link-drop",
        "0.1",
    ];
    ok(&drive(Some(&link), &blob, &demos, &out, &faults));
    let hil = hil_json(&out);
    assert_eq!(hil["ticks"], 30, "{hil}");
    let injected = hil["wire"]["injected_corrupt"].as_u64().unwrap()
        + hil["wire"]["injected_drop"].as_u64().unwrap();
    assert!(injected > 0, "{hil}");
    assert!(hil["link"]["retries"].as_u64().unwrap() > 0, "{hil}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_device_killed_mid_run_is_survived_and_a_blob_it_cannot_run_is_refused_by_name() {
    let dir = tmp("hil-kill");
    let (blob, demos) = blob_and_demos(&dir);
    let link = dir.join("tty");
    let first = DeviceProcess::start(&dir, &link, &[], "first");
    let out = dir.join("host");
    let host = {
        let (blob, demos, out, link) = (blob.clone(), demos.clone(), out.clone(), link.clone());
        std::thread::spawn(move || drive(Some(&link), &blob, &demos, &out, &["--ticks", "60"]))
    };
    assert!(
        first.wait_for("context taught", Duration::from_secs(20)),
        "{}",
        first.log()
    );
    std::thread::sleep(Duration::from_millis(1500));
    drop(first);
    std::thread::sleep(Duration::from_millis(700));
    let second = DeviceProcess::start(&dir, &link, &[], "second");
    let err = ok(&host.join().unwrap());
    let hil = hil_json(&out);
    assert_eq!(hil["ticks"], 60, "{hil}");
    assert_eq!(hil["reconnects"], 1, "{err}\n{hil}");
    // No flash file: the restarted device booted empty and got the blob again.
    assert_eq!(hil["uploads"], 2, "{err}\n{hil}");
    assert!(hil["held_safe"].as_u64().unwrap() > 0, "{hil}");
    assert!(
        err.contains("holding the safe action") && err.contains("ticks resume"),
        "{err}"
    );
    assert!(second.log().contains("blob committed"), "{}", second.log());
    drop(second);
    // A device with 1 KiB of RAM refuses the blob; the host says why and stops.
    let small = DeviceProcess::start(&dir, &link, &["--ram-kib", "1"], "small");
    let refused = drive(Some(&link), &blob, &demos, &dir.join("refused"), &[]);
    let err = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the device refused the blob") && err.contains("RAM"),
        "{err}"
    );
    assert!(small.log().contains("DoesNotFit"), "{}", small.log());
    std::fs::remove_dir_all(&dir).ok();
}

/// `firmware-sim device ARGS` that must exit with `code` at once: its stderr.
fn device_refused(args: &[&str], code: i32) -> String {
    let out = Command::new("timeout")
        .args(["10", env!("CARGO_BIN_EXE_firmware-sim"), "device"])
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "{err}");
    err
}

#[test]
fn a_pty_path_that_is_a_file_or_a_live_link_is_refused_and_kept() {
    let dir = tmp("hil-pty-path");
    // A regular file: refused by name, its contents kept.
    let file = dir.join("notes.txt");
    std::fs::write(&file, "keep me").unwrap();
    let err = device_refused(&["--pty", s(&file)], 1);
    assert!(
        err.contains("notes.txt") && err.contains("refusing to replace"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
    // A flash no part has: refused by the parser, not an allocation abort.
    let big = dir.join("tty-big");
    let err = device_refused(&["--flash-kib", "99999999", "--pty", s(&big)], 2);
    assert!(
        err.contains("--flash-kib") && !err.contains("memory allocation"),
        "{err}"
    );
    // A link a running device serves: a second device is refused and the first keeps it.
    let link = dir.join("tty");
    let first = DeviceProcess::start(&dir, &link, &[], "first");
    let target = std::fs::read_link(&link).unwrap();
    let err = device_refused(&["--pty", s(&link)], 1);
    assert!(err.contains("another device serves it"), "{err}");
    assert_eq!(std::fs::read_link(&link).unwrap(), target);
    // Once that device is gone its link is stale, and a new device takes the path.
    drop(first);
    // (`start` fails the test unless the second device boots on that path.)
    let second = DeviceProcess::start(&dir, &link, &[], "second");
    drop(second);
    std::fs::remove_dir_all(&dir).ok();
}

/// A device that speaks the protocol but answers every tick with `action` (a broken board, or
/// one flashed with another model), holding `blob` so that the host skips the upload; stops
/// when `stop` is set.
fn rogue_device(
    link: &Path,
    blob: Vec<u8>,
    action: Vec<f32>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> std::thread::JoinHandle<()> {
    use firmware_sim::link::{
        DeviceMessage, Floats, HostMessage, MAX_FRAME, PROTOCOL_VERSION, Packet, decode_frame,
        decode_message, encode_frame,
    };
    let (mut wire, keep, _) = firmware_sim::serial::pty(link, 0).unwrap();
    std::thread::spawn(move || {
        let _keep = keep;
        let crc = infer_core::crc32(&blob);
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            let until = Instant::now() + Duration::from_millis(20);
            let Ok(Some(frame)) = wire.receive(until) else {
                continue;
            };
            let frame = frame.to_vec();
            let mut scratch = [0u8; MAX_FRAME];
            let Ok(payload) = decode_frame(&frame, &mut scratch) else {
                continue;
            };
            let Ok(p) = decode_message::<Packet<HostMessage<'_>>>(payload) else {
                continue;
            };
            let seq = p.seq;
            let answer = match p.message {
                HostMessage::Hello { .. } => DeviceMessage::Status {
                    seq,
                    version: PROTOCOL_VERSION,
                    blob_len: blob.len() as u32,
                    blob_crc: crc,
                    taught: false,
                    watchdog_trips: 0,
                },
                HostMessage::Tick { tick, .. } => DeviceMessage::Action {
                    seq,
                    tick,
                    action: Floats::from_slice(&action).unwrap(),
                    fault: false,
                    compute_us: 1,
                },
                _ => DeviceMessage::Ack { seq },
            };
            let mut out = [0u8; MAX_FRAME];
            let n = encode_frame(&answer, &mut out).unwrap();
            let _ = wire.send(&out[..n]);
        }
    })
}

#[test]
fn a_device_answering_the_wrong_size_or_nan_never_reaches_the_plant() {
    let dir = tmp("hil-rogue");
    let (blob, demos) = blob_and_demos(&dir);
    let bytes = std::fs::read(&blob).unwrap();
    // The PD blob acts in 2 dimensions: one value, then a NaN.
    for (name, action) in [("short", vec![0.5]), ("nan", vec![f32::NAN, 0.0])] {
        let link = dir.join(format!("tty-{name}"));
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let device = rogue_device(&link, bytes.clone(), action, stop.clone());
        let out = dir.join(name);
        let run = drive(
            Some(&link),
            &blob,
            &demos,
            &out,
            &["--ticks", "10", "--baud", "0"],
        );
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        device.join().unwrap();
        let err = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(!err.contains("panicked"), "{name}: {err}");
        // Every tick on the safe action: the files are written, and the run is no result
        // (issue 72, item 1: it exited 0 with a metric before).
        assert_eq!(run.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains("10 of 10 ticks") && err.contains("--max-held-safe"),
            "{name}: {err}"
        );
        let hil = hil_json(&out);
        assert_eq!(hil["held_safe"], 10, "{name}: {hil}");
        assert!(
            hil.to_string().contains("holding the safe action"),
            "{name}: {hil}"
        );
        // The plant only ever got the safe action: one action, every tick, all finite.
        let applied = columns(&out, &["action"]);
        assert!(applied.iter().all(|row| row == &applied[0]), "{applied:?}");
        assert!(
            applied[0]
                .iter()
                .all(|v| v.parse::<f32>().unwrap().is_finite())
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_paused_device_is_reconnected_on_the_same_port() {
    let dir = tmp("hil-pause");
    let (blob, demos) = blob_and_demos(&dir);
    let link = dir.join("tty");
    let device = DeviceProcess::start(&dir, &link, &["--baud", "0"], "device");
    let out = dir.join("host");
    let host = {
        let (blob, demos, out, link) = (blob.clone(), demos.clone(), out.clone(), link.clone());
        std::thread::spawn(move || {
            drive(
                Some(&link),
                &blob,
                &demos,
                &out,
                &["--ticks", "80", "--baud", "0"],
            )
        })
    };
    assert!(
        device.wait_for("context taught", Duration::from_secs(20)),
        "{}",
        device.log()
    );
    std::thread::sleep(Duration::from_millis(500));
    let pid = device.child.id().to_string();
    let signal = |sig: &str| {
        let ok = Command::new("kill").args([sig, &pid]).status().unwrap();
        assert!(ok.success());
    };
    // Paused past the host's patience (5 missed ticks), then back: the host holds the safe
    // action, reopens the same port and carries on (before issue 72 every reopen failed on the
    // host's own still-open handle: "Unable to acquire exclusive lock").
    signal("-STOP");
    std::thread::sleep(Duration::from_millis(1500));
    signal("-CONT");
    let err = ok(&host.join().unwrap());
    let hil = hil_json(&out);
    assert_eq!(hil["ticks"], 80, "{hil}");
    assert!(hil["reconnects"].as_u64().unwrap() >= 1, "{err}\n{hil}");
    assert!(!err.contains("exclusive lock"), "{err}");
    assert!(err.contains("ticks resume"), "{err}");
    let held = hil["held_safe"].as_u64().unwrap();
    assert!(held > 0 && held < 60, "{hil}");
    drop(device);
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 72, item 4: a line rate or a speed-up no run can finish is refused by the parser,
/// naming the flag and its bounds (before: `--baud 300` and `--speedup 1e-9` ran on, for hours).
#[test]
fn line_rates_and_speedups_no_run_can_finish_are_refused() {
    let dir = tmp("hil-bounds");
    let link = dir.join("tty");
    let err = device_refused(&["--baud", "300", "--pty", s(&link)], 2);
    assert!(err.contains("--baud") && err.contains("1200"), "{err}");
    assert!(!link.exists(), "nothing was linked");
    for (flag, value, bound) in [
        ("--baud", "300", "1200"),
        ("--speedup", "1e-9", "0.01"),
        ("--speedup", "NaN", "0.01"),
        ("--speedup", "1e9", "1000"),
    ] {
        let out = Command::new("timeout")
            .args(["10", env!("CARGO_BIN_EXE_firmware-sim"), "host"])
            .args(["--port", s(&link), flag, value])
            .args(["--blob", "p.blob", "--env", "point-goal", "--task", "0"])
            .args(["--context", "c.safetensors"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(
            err.contains(flag) && err.contains(bound),
            "{flag} {value}: {err}"
        );
    }
}

/// Issue 72, item 1: a host that gives a run up (its device gone past `--reconnect-s`) still
/// writes `hil.json`, with why and the events, and exits non-zero (before: no file at all).
#[test]
fn a_host_that_gives_up_still_writes_hil_json() {
    let dir = tmp("hil-give-up");
    let (blob, demos) = blob_and_demos(&dir);
    let link = dir.join("tty");
    let device = DeviceProcess::start(&dir, &link, &[], "device");
    let out = dir.join("host");
    let host = {
        let (blob, demos, out, link) = (blob.clone(), demos.clone(), out.clone(), link.clone());
        let extra = ["--ticks", "400", "--reconnect-s", "1"];
        std::thread::spawn(move || drive(Some(&link), &blob, &demos, &out, &extra))
    };
    assert!(
        device.wait_for("context taught", Duration::from_secs(20)),
        "{}",
        device.log()
    );
    std::thread::sleep(Duration::from_millis(500));
    drop(device);
    let run = host.join().unwrap();
    let err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "{err}");
    assert!(
        err.contains("given up") && err.contains("hil.json"),
        "{err}"
    );
    let hil = hil_json(&out);
    assert!(hil["gave_up"].is_string(), "{hil}");
    assert!(hil["metric"].is_null() && hil["ticks"].is_null(), "{hil}");
    assert!(!hil["events"].as_array().unwrap().is_empty(), "{hil}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `firmware-sim host` of the blob on test goal 2 as a child process, its stderr to `log`
/// (read while it runs), bounded by a 60 s timeout.
fn spawn_host(
    link: &Path,
    blob: &Path,
    demos: &Path,
    out: &Path,
    log: &Path,
    extra: &[&str],
) -> Child {
    Command::new("timeout")
        .args([
            "60",
            env!("CARGO_BIN_EXE_firmware-sim"),
            "host",
            "--port",
            s(link),
        ])
        .args(["--blob", s(blob), "--env", "point-goal", "--task", "2"])
        .args(["--context", s(demos), "--seed", "7", "-o", s(out)])
        .args(extra)
        .env_remove("RUST_BACKTRACE")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .unwrap()
}

/// Kills `device` as soon as it has greeted the host: the host's next message is the first of
/// its upload, which takes about 3.3 s (a shipped 37,836 B blob at 115,200 baud), so the kill
/// lands in it and the device has committed nothing.
fn kill_during_the_upload(device: DeviceProcess) {
    assert!(
        device.wait_for("greeted a host", Duration::from_secs(20)),
        "{}",
        device.log()
    );
    assert!(!device.log().contains("blob committed"), "{}", device.log());
    drop(device);
}

/// Issue 72, item 1: a device killed during the blob's upload and restarted is brought up
/// again (the host reopens the port, greets it and uploads from the start); one that never
/// comes back is given up after `--reconnect-s` with its events in `hil.json`. Before: "Broken
/// pipe", and the host ended at once whatever `--reconnect-s` said, writing nothing.
#[test]
fn a_device_killed_during_the_upload_is_brought_up_again_or_given_up_with_its_events() {
    let dir = tmp("hil-upload-kill");
    let (_, demos) = blob_and_demos(&dir);
    let blob = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/policies/point-goal-rapier-smile/policy.blob");
    let link = dir.join("tty");
    let first = DeviceProcess::start(&dir, &link, &[], "first");
    let (out, log) = (dir.join("host"), dir.join("host.log"));
    let mut host = spawn_host(&link, &blob, &demos, &out, &log, &["--ticks", "20"]);
    kill_during_the_upload(first);
    std::thread::sleep(Duration::from_millis(300));
    let second = DeviceProcess::start(&dir, &link, &[], "second");
    let status = host.wait().unwrap();
    let err = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{err}");
    let hil = hil_json(&out);
    assert_eq!(hil["ticks"], 20, "{hil}");
    assert_eq!(
        (hil["uploads"].as_u64(), hil["reconnects"].as_u64()),
        (Some(1), Some(1)),
        "{err}\n{hil}"
    );
    assert!(
        err.contains("starting over") && err.contains("brought up"),
        "{err}"
    );
    assert!(second.log().contains("blob committed"), "{}", second.log());
    drop(second);

    // Killed during the upload and never restarted: given up after 1 s, hil.json says why.
    let third = DeviceProcess::start(&dir, &link, &[], "third");
    let (out, log) = (dir.join("gave-up"), dir.join("gave-up.log"));
    let mut host = spawn_host(&link, &blob, &demos, &out, &log, &["--reconnect-s", "1"]);
    kill_during_the_upload(third);
    let status = host.wait().unwrap();
    let err = std::fs::read_to_string(&log).unwrap();
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("did not come back within 1 s") && err.contains("hil.json"),
        "{err}"
    );
    let hil = hil_json(&out);
    let events = hil["events"].to_string();
    assert!(
        events.contains("starting over") && events.contains("did not come back"),
        "{hil}"
    );
    assert!(
        hil["gave_up"]
            .as_str()
            .unwrap()
            .contains("did not come back"),
        "{hil}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
