//! The firmware on a Cortex-M4F (issue 74): `firmware/` built for thumbv7em-none-eabihf
//! (`scripts/build-firmware.sh`) and booted on QEMU's MPS2 AN386 board, its UART a
//! pseudo-terminal. Over that UART, with this crate's host side:
//! - infer-core's golden vectors give the golden bits (the latent and every action);
//! - every shipped blob that fits gives the host's latent and actions bit for bit, and every
//!   one that does not is refused;
//! - `firmware-sim host` runs a cheetah-vel episode against it whose trace is the in-process
//!   `firmware-sim run`'s bit for bit; a corrupting line finishes with its errors counted; a
//!   silent host trips the firmware's watchdog; a blob larger than its flash is refused in words.
//!
//! Ignored by default: they need the firmware ELF and `qemu-system-arm`, and fail loudly without
//! them. `.ci/run` builds the firmware and runs them with `--ignored`. Every QEMU is killed at
//! the end (and `.ci/run` kills any left).

mod common;
#[path = "../../infer-core/tests/common/mod.rs"]
#[allow(unused_imports)]
mod golden_inputs;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::hil::{columns, hil_json};
use common::{ok, s, tmp};
use device_core::{Controller, DeviceConfig, DeviceMessage, HostMessage, Refusal};
use firmware_sim::host;
use firmware_sim::link::{Floats, LinkError};
use firmware_sim::serial::{SerialConfig, SerialLink};
use golden_inputs::Rng;
use infer_core::{Dims, FloatModel, Model, ModelKind};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The firmware ELF: `SMILE_FIRMWARE_ELF`, else where `scripts/build-firmware.sh` puts it.
fn firmware() -> PathBuf {
    let elf = std::env::var_os("SMILE_FIRMWARE_ELF").map_or_else(
        || repo().join("firmware/target/thumbv7em-none-eabihf/release/smile-firmware"),
        PathBuf::from,
    );
    assert!(
        elf.exists(),
        "no firmware at {}: build it with scripts/build-firmware.sh",
        elf.display()
    );
    elf
}

/// The firmware booted on QEMU's MPS2 AN386, killed when dropped.
struct Board {
    child: Child,
    log: PathBuf,
    /// The board's UART0 as a pseudo-terminal.
    uart: PathBuf,
    /// This process's link to the UART (greeted until the board answered), until a test
    /// hands the port to a `firmware-sim host` (the link holds it exclusively).
    link: Option<SerialLink>,
    /// The UART held open for the board's life: QEMU notices a pseudo-terminal's other end
    /// opening only on a timer (up to a second late), and its closing at once, so the end is
    /// kept open while hosts come and go.
    _keep: std::fs::File,
}

impl Board {
    fn boot(dir: &Path, name: &str) -> Self {
        Self::boot_with(dir, name, &[])
    }

    /// Boots with `extra` QEMU options (`-icount shift=0` for instruction counts).
    fn boot_with(dir: &Path, name: &str, extra: &[&str]) -> Self {
        let log = dir.join(format!("{name}.log"));
        let file = std::fs::File::create(&log).unwrap();
        let child = Command::new("qemu-system-arm")
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4"])
            .args(["-display", "none", "-monitor", "none", "-serial", "pty"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(extra)
            .arg("-kernel")
            .arg(firmware())
            .stdin(Stdio::null())
            .stdout(file.try_clone().unwrap())
            .stderr(file)
            .spawn()
            .expect("qemu-system-arm runs the firmware: apt-get install qemu-system-arm");
        let started = Instant::now();
        let mut log_text = String::new();
        while !log_text.contains("booted") {
            assert!(
                started.elapsed() < Duration::from_secs(20),
                "the firmware did not boot"
            );
            std::thread::sleep(Duration::from_millis(20));
            log_text = std::fs::read_to_string(&log).unwrap_or_default();
        }
        let at = log_text
            .find("char device redirected to ")
            .expect("QEMU names its pty")
            + 25;
        let uart = PathBuf::from(log_text[at..].split_whitespace().next().unwrap());
        let keep = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&uart)
            .unwrap();
        let mut board = Self {
            child,
            log,
            uart,
            link: None,
            _keep: keep,
        };
        assert!(
            board.wait_for("booted", Duration::from_secs(20)),
            "the firmware did not boot: {}",
            board.log()
        );
        let mut config = SerialConfig::new(board.uart.clone(), 0);
        // Upload and teach answers wait this long: QEMU's UART takes about 60 us a byte.
        config.reply_timeout = Duration::from_millis(500);
        let mut link = SerialLink::open(config).expect("the board's UART opens");
        let t0 = Instant::now();
        while link.hello().is_err() {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "the board never answered Hello"
            );
        }
        board.link = Some(link);
        board
    }

    fn link(&mut self) -> &mut SerialLink {
        self.link.as_mut().unwrap()
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    fn wait_for(&mut self, text: &str, limit: Duration) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < limit {
            if self.log().contains(text) {
                return true;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("QEMU exited ({status}): {}", self.log());
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Every shipped policy blob, in name order.
fn shipped_blobs() -> Vec<PathBuf> {
    let mut policies: Vec<PathBuf> = std::fs::read_dir(repo().join("assets/policies"))
        .unwrap()
        .map(|e| e.unwrap().path().join("policy.blob"))
        .filter(|p| p.exists())
        .collect();
    policies.sort();
    policies
}

fn floats(v: &[f32]) -> Floats {
    Floats::from_slice(v).unwrap()
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn hex(v: &[f32]) -> String {
    let words: Vec<String> = v.iter().map(|x| format!("{:08x}", x.to_bits())).collect();
    words.join(" ")
}

/// Teaching messages for `trajectories`, each a list of (obs, action, next_obs).
fn teach_messages(trajectories: &[Vec<[Vec<f32>; 3]>]) -> Vec<HostMessage<'static>> {
    let mut out = vec![HostMessage::TeachBegin];
    for trajectory in trajectories {
        for [o, a, n] in trajectory {
            out.push(HostMessage::Transition {
                obs: floats(o),
                action: floats(a),
                next_obs: floats(n),
            });
        }
        out.push(HostMessage::EndTrajectory);
    }
    out.push(HostMessage::TeachEnd);
    out
}

fn upload(link: &mut SerialLink, blob: &[u8]) -> Result<(), LinkError> {
    host::upload_with(&mut |m| link.send(m), blob)
}

/// The action the board answers for `obs` at `tick`, with its compute time in microseconds
/// (stop-and-wait, as the upload: a real-time tick's resends every few milliseconds would
/// outpace QEMU's UART).
fn act(link: &mut SerialLink, tick: u32, obs: &[f32]) -> (Vec<f32>, u32) {
    let message = HostMessage::Tick {
        tick,
        obs: floats(obs),
    };
    match link.request(&message).unwrap() {
        DeviceMessage::Action {
            action,
            fault,
            compute_us,
            ..
        } => {
            assert!(!fault);
            (action.to_vec(), compute_us)
        }
        other => panic!("a tick answered with {other:?}"),
    }
}

#[test]
#[ignore = "needs the firmware ELF and qemu-system-arm: .ci/run builds and runs it"]
fn golden_vectors_and_every_shipped_blob_are_bit_exact_on_the_cortex_m4f() {
    let dir = tmp("qemu-bits");
    let mut board = Board::boot(&dir, "board");
    let link = board.link();
    assert_eq!(link.hello().unwrap().blob, None);

    // infer-core's golden vectors: the inputs of infer-core/tests/golden.rs, the bits of its
    // .expected files.
    let dims = Dims {
        obs: 4,
        act: 2,
        r: 8,
        z: 4,
        hidden: 16,
    };
    let float = FloatModel::random(ModelKind::StateAction, dims, 42);
    let golden = repo().join("infer-core/tests/golden");
    for name in ["f32", "w8a32", "w8a8", "w8a8-edges-w8a32"] {
        let blob = std::fs::read(golden.join(format!("{name}.blob"))).unwrap();
        let text = std::fs::read_to_string(golden.join(format!("{name}.expected"))).unwrap();
        let expected: BTreeMap<&str, &str> =
            text.lines().filter_map(|l| l.split_once(' ')).collect();
        upload(link, &blob).unwrap();
        let mut rng = Rng(2024);
        for n in 1..=3 {
            let context = golden_inputs::context(&mut rng, &float, n);
            let split: Vec<Vec<[Vec<f32>; 3]>> = context
                .iter()
                .map(|t| {
                    t.iter()
                        .map(|x| [x[..4].to_vec(), x[4..6].to_vec(), x[6..].to_vec()])
                        .collect()
                })
                .collect();
            for m in teach_messages(&split) {
                link.send(&m).unwrap();
            }
            let z = link.latent().unwrap();
            assert_eq!(hex(&z), expected[format!("z{n}").as_str()], "{name}: z{n}");
            for k in 0..3 {
                let obs = rng.vec(4, 2.0);
                let (a, _) = act(link, (n * 10 + k) as u32, &obs);
                assert_eq!(
                    hex(&a),
                    expected[format!("a{n}.{k}").as_str()],
                    "{name}: a{n}.{k}"
                );
            }
        }
    }

    // Every shipped blob: the board's latent and actions are the host's, bit for bit.
    let mut fits = 0;
    let policies = shipped_blobs();
    assert!(policies.len() >= 16, "{policies:?}");
    for path in &policies {
        let blob = std::fs::read(path).unwrap();
        let model = Model::from_bytes(&blob).unwrap();
        let Ok(mut local) = Controller::new(&model, DeviceConfig::default()) else {
            let refused = upload(link, &blob).unwrap_err();
            assert!(
                matches!(
                    refused,
                    LinkError::Refused {
                        reason: Refusal::DoesNotFit | Refusal::BlobTooLarge,
                        ..
                    }
                ),
                "{}: {refused}",
                path.display()
            );
            continue;
        };
        fits += 1;
        let h = *model.header();
        let (o, a) = (h.obs_dim as usize, h.act_dim as usize);
        let mut rng = Rng(7 + fits);
        let trajectories: Vec<Vec<[Vec<f32>; 3]>> = (0..2)
            .map(|_| {
                (0..12)
                    .map(|_| [rng.vec(o, 1.0), rng.vec(a, 1.0), rng.vec(o, 1.0)])
                    .collect()
            })
            .collect();
        upload(link, &blob).unwrap();
        for m in teach_messages(&trajectories) {
            local.apply(&m).unwrap();
            link.send(&m).unwrap();
        }
        let z = link.latent().unwrap();
        assert_eq!(bits(&z), bits(local.z().unwrap()), "{}: z", path.display());
        let mut micros = Vec::new();
        for tick in 0..8 {
            let obs = rng.vec(o, 1.0);
            let mut want = vec![0.0; a];
            local.act(&obs, &mut want).unwrap().unwrap();
            let (got, us) = act(link, tick, &obs);
            assert_eq!(bits(&got), bits(&want), "{}: tick {tick}", path.display());
            micros.push(us);
        }
        eprintln!("{}: bit-exact; act {micros:?} us", path.display());
    }
    assert!(fits >= 16, "{fits} shipped blobs fit");
    drop(board);
    std::fs::remove_dir_all(&dir).ok();
}

/// `firmware-sim host` against the board (or `run` in process, with `port` None): the shipped
/// Rapier cheetah-vel SMILe + BC blob on test velocity 3, taught one shipped test demo.
fn drive(port: Option<&Path>, out: &Path, extra: &[&str]) -> Output {
    let policy = repo().join("assets/policies/cheetah-vel-rapier-smile-bc/policy.blob");
    let demos = repo().join("assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors");
    let mut cmd = Command::new("timeout");
    cmd.args(["120", env!("CARGO_BIN_EXE_firmware-sim")]);
    match port {
        // At the protocol's 115200 baud: the host's tick resends wait a round trip of that
        // line (40 ms), which QEMU's UART (about 60 us a byte) keeps up with.
        // Half the plant's rate: a 100 ms deadline per tick, so a loaded CI machine does not
        // make a tick miss (a held action would differ from the in-process run's).
        Some(p) => cmd.args([
            "host",
            "--port",
            s(p),
            "--baud",
            "115200",
            "--speedup",
            "0.5",
        ]),
        None => cmd.arg("run"),
    };
    cmd.args(["--blob", s(&policy), "--env", "cheetah-vel", "--task", "3"])
        .args(["--context", s(&demos), "--seed", "7", "-o", s(out)])
        .args(extra)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

#[test]
#[ignore = "needs the firmware ELF and qemu-system-arm: .ci/run builds and runs it"]
fn the_hil_loop_runs_against_the_firmware_over_its_uart() {
    let dir = tmp("qemu-hil");
    let mut board = Board::boot(&dir, "board");
    let uart = board.uart.clone();
    board.link = None;
    let ticks = ["--ticks", "60"];

    // A clean line: the trace is the in-process run's, bit for bit.
    let host_out = dir.join("host");
    let err = ok(&drive(Some(&uart), &host_out, &ticks));
    assert!(err.contains("uploaded the blob"), "{err}");
    let run_out = dir.join("run");
    ok(&drive(None, &run_out, &ticks));
    let cols = ["computed", "action", "obs"];
    let (remote, local) = (columns(&host_out, &cols), columns(&run_out, &cols));
    let hil = hil_json(&host_out);
    assert_eq!(hil["deadline_misses"], 0, "{hil}");
    assert_eq!(hil["link"]["bad_frames"], 0, "{hil}");
    assert_eq!(remote.len(), 60);
    let first = (0..60).find(|&t| remote[t] != local[t]);
    assert_eq!(
        first, None,
        "the firmware over its UART acts as the device in process"
    );

    // The host has stopped talking: the firmware's watchdog holds the safe action.
    assert!(
        board.wait_for("watchdog: no tick for", Duration::from_secs(10)),
        "{}",
        board.log()
    );

    // A corrupting, dropping line: the run finishes with its errors counted (the blob is in
    // the board's flash already, so this is teach and ticks).
    let lossy = dir.join("lossy");
    let faults = [
        "--link-corrupt",
        "0.1",
        "--link-drop",
        "0.1",
        "--ticks",
        "40",
    ];
    ok(&drive(Some(&uart), &lossy, &faults));
    let hil = hil_json(&lossy);
    assert_eq!(hil["ticks"], 40, "{hil}");
    let injected = hil["wire"]["injected_corrupt"].as_u64().unwrap()
        + hil["wire"]["injected_drop"].as_u64().unwrap();
    assert!(injected > 0, "{hil}");
    assert!(hil["link"]["retries"].as_u64().unwrap() > 0, "{hil}");

    // The ants' SMILe + BC blob (2 x 256, 123 KB): refused in words before it is sent (the board
    // refuses it too when sent: the bit-exactness test uploads every shipped blob).
    let ant = repo().join("assets/policies/ant-goal-rapier-smile-bc/policy.blob");
    let demos = repo().join("assets/experts/ant-goal/demos-test-4x-sub1.safetensors");
    let refused = Command::new("timeout")
        .args([
            "60",
            env!("CARGO_BIN_EXE_firmware-sim"),
            "host",
            "--baud",
            "115200",
        ])
        .args([
            "--port",
            s(&uart),
            "--blob",
            s(&ant),
            "--env",
            "ant-goal",
            "--task",
            "0",
        ])
        .args(["--context", s(&demos), "-o", s(&dir.join("ant"))])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(
        err.contains("blob rejected") && err.contains("width 256"),
        "{err}"
    );
    drop(board);
    std::fs::remove_dir_all(&dir).ok();
}

/// One shipped blob measured on the emulated part.
#[derive(Debug, serde::Serialize)]
struct Footprint {
    policy: String,
    blob_bytes: usize,
    quant: String,
    /// Instructions per `act` (the Tick's compute), mean over the ticks.
    act_instructions: f64,
    /// Instructions per encoder push, mean over the teach.
    push_instructions: f64,
    /// The stack's high-water mark after teach and ticks, bytes.
    stack_bytes: usize,
}

/// The last number before `suffix` in the last line of `log` holding `marker`.
fn logged(log: &str, marker: &str, suffix: &str) -> f64 {
    let line = log.lines().rev().find(|l| l.contains(marker)).unwrap();
    let head = &line[..line.find(suffix).unwrap()];
    head.split_whitespace().last().unwrap().parse().unwrap()
}

/// docs/DEVICE.md's "On a Cortex-M4F" table: every shipped blob that fits, on QEMU with
/// `-icount shift=0` (one instruction is one nanosecond of the board's SysTick time, so the
/// device's times are instruction counts, the same on every run). Writes
/// `$SMILE_CORTEX_M4F_OUT` (JSON) when set. Not in `.ci/run` (a few minutes): the command is in
/// DEVICE.md.
#[test]
#[ignore = "needs the firmware ELF and qemu-system-arm; a measurement, run by hand"]
fn instructions_and_stack_per_shipped_blob_on_the_cortex_m4f() {
    let dir = tmp("qemu-measure");
    let mut board = Board::boot_with(&dir, "board", &["-icount", "shift=0"]);
    let mut rows = Vec::new();
    let policies = shipped_blobs();
    for path in &policies {
        let blob = std::fs::read(path).unwrap();
        let model = Model::from_bytes(&blob).unwrap();
        if Controller::new(&model, DeviceConfig::default()).is_err() {
            continue;
        }
        let h = *model.header();
        let (o, a) = (h.obs_dim as usize, h.act_dim as usize);
        let mut rng = Rng(11);
        let trajectories: Vec<Vec<[Vec<f32>; 3]>> = (0..2)
            .map(|_| {
                (0..16)
                    .map(|_| [rng.vec(o, 1.0), rng.vec(a, 1.0), rng.vec(o, 1.0)])
                    .collect()
            })
            .collect();
        let link = board.link();
        upload(link, &blob).unwrap();
        for m in teach_messages(&trajectories) {
            link.send(&m).unwrap();
        }
        let ticks = 20;
        let act_us: u32 = (0..ticks).map(|t| act(link, t, &rng.vec(o, 1.0)).1).sum();
        link.hello().unwrap();
        let log = board.log();
        let push_ns = logged(&log, "context taught from 32 transitions", " ns");
        let row = Footprint {
            policy: path
                .parent()
                .unwrap()
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into(),
            blob_bytes: blob.len(),
            quant: format!("{:?}", h.quant),
            act_instructions: f64::from(act_us) * 1000.0 / f64::from(ticks),
            push_instructions: push_ns / 32.0,
            stack_bytes: logged(&log, "stack high-water", " B of") as usize,
        };
        eprintln!("{row:?}");
        assert!(
            row.act_instructions > 1000.0 && row.push_instructions > 1000.0,
            "{row:?}"
        );
        assert!(row.stack_bytes < 128 * 1024, "{row:?}");
        rows.push(row);
    }
    assert!(rows.len() >= 16);
    if let Some(out) = std::env::var_os("SMILE_CORTEX_M4F_OUT") {
        std::fs::write(out, serde_json::to_string_pretty(&rows).unwrap()).unwrap();
    }
    drop(board);
    std::fs::remove_dir_all(&dir).ok();
}
