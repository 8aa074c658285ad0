//! `firmware-sim device` and `firmware-sim host`: the device as its own process behind a
//! serial port, and the plant on the host driving it in real time (`docs/PROTOCOL.md`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use firmware_sim::DeviceConfig;
use firmware_sim::serial::{self, BoardConfig, BoardEvent, Faults, RemoteDevice, SerialConfig};
use serde::Serialize;

use crate::{PlantArgs, plant_config, prepare, write_trace};

/// Arguments of `firmware-sim device`.
#[derive(Args, Debug)]
pub(crate) struct DeviceArgs {
    /// Serve on this serial device (a USB-serial adapter, /dev/ttyUSB0).
    #[arg(long, conflicts_with = "pty", required_unless_present = "pty")]
    port: Option<PathBuf>,
    /// Serve on a new pseudo-terminal and link this path to it (a host opens the path as
    /// its --port; a restarted device links the same path to its new terminal).
    #[arg(long)]
    pty: Option<PathBuf>,
    /// Line rate in baud, 1200 to 12,000,000; every frame takes its time on the line (0:
    /// unpaced).
    #[arg(long, default_value_t = 115_200, value_parser = crate::baud_rate)]
    baud: u32,
    /// Once ticks have started, hold the safe action when the host is silent this long, ms.
    #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(1..))]
    watchdog_ms: u64,
    /// A file standing for the board's flash: a committed blob survives a restart of this
    /// process, as a board's does across a reset.
    #[arg(long)]
    flash_file: Option<PathBuf>,
    /// Flash budget for the blob, KiB, 1 to 16384 (16 MiB, more than a microcontroller has).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u64).range(1..=16384))]
    flash_kib: u64,
    /// RAM budget for the application, KiB, 1 to 16384.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u64).range(1..=16384))]
    ram_kib: u64,
}

/// Run `firmware-sim device` until killed.
pub(crate) fn device_cmd(a: DeviceArgs) -> Result<()> {
    let config = BoardConfig {
        device: DeviceConfig {
            flash_bytes: a.flash_kib as usize * 1024,
            ram_bytes: a.ram_kib as usize * 1024,
        },
        watchdog: Duration::from_millis(a.watchdog_ms),
        flash_file: a.flash_file.clone(),
    };
    // The other end of a pseudo-terminal stays open here, so a host that closes its end does
    // not hang this one up.
    let (mut wire, _keep) = match (&a.port, &a.pty) {
        (Some(port), _) => (serial::Wire::open(&port.to_string_lossy(), a.baud)?, None),
        (None, Some(link)) => {
            let (wire, other, path) = serial::pty(link, a.baud)?;
            println!("pty {} -> {}", link.display(), path.display());
            (wire, Some(other))
        }
        (None, None) => unreachable!("clap requires one of --port and --pty"),
    };
    eprintln!(
        "device: serving on {} at {} baud; watchdog {} ms; flash {} KiB, RAM {} KiB",
        wire.name(),
        a.baud,
        a.watchdog_ms,
        a.flash_kib,
        a.ram_kib
    );
    serial::board::serve(&mut wire, &config, &|| false, &mut |e| {
        let line = match e {
            BoardEvent::Booted(Some((len, crc))) => {
                format!("booted; flash holds a {len} B blob (CRC-32 {crc:08x})")
            }
            BoardEvent::Booted(None) => "booted; flash is empty".into(),
            BoardEvent::Committed(len, crc) => {
                format!("blob committed: {len} B, CRC-32 {crc:08x}")
            }
            BoardEvent::Flash(why) => format!("flash file: {why}"),
            BoardEvent::Refused(reason) => format!("refused a message: {reason:?}"),
            BoardEvent::Taught(n) => format!("context taught from {n} transitions; z fixed"),
            BoardEvent::Watchdog(silent) => format!(
                "watchdog: no tick for {} ms; holding the safe action",
                silent.as_millis()
            ),
            BoardEvent::Resumed(tick) => format!("ticks resumed at tick {tick}"),
            BoardEvent::Greeted => "greeted a host".into(),
        };
        eprintln!("device: {line}");
    })
    .context("the device stopped")
}

/// Arguments of `firmware-sim host`.
#[derive(Args, Debug)]
pub(crate) struct HostArgs {
    /// The device's serial port (what `firmware-sim device --pty` linked, or a board's).
    #[arg(long)]
    port: PathBuf,
    /// Line rate in baud, 1200 to 12,000,000 (0: unpaced); the device's must match on a
    /// real line.
    #[arg(long, default_value_t = 115_200, value_parser = crate::baud_rate)]
    baud: u32,
    /// Wait for one upload or teach answer this long before resending, ms [default: two
    /// longest frames on the line plus 100 ms].
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    reply_timeout_ms: Option<u64>,
    /// Declare the device gone after this many unanswered ticks in a row, then hold the safe
    /// action and reconnect.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    lost_after: u32,
    /// Give the run up when a lost device is not back within this many seconds.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..))]
    reconnect_s: u64,
    /// Run the plant this many times faster than real time: ticks come every
    /// 1 / (rate x speedup) s of wall clock, so a loop can be timed past the plant's own rate
    /// (0.01 to 1000).
    #[arg(long, default_value_t = 1.0, value_parser = crate::speedup_factor)]
    speedup: f32,
    /// The largest share of ticks, 0 to 1, that may hold the safe action for the run to count
    /// as a result: past it the metric is the safe action's more than the policy's, so the
    /// run's files are written and the command exits 1, saying so.
    #[arg(long, default_value_t = 0.25, value_parser = crate::fraction)]
    max_held_safe: f32,
    #[command(flatten)]
    plant: PlantArgs,
}

/// What `host` writes as `hil.json`.
#[derive(Debug, Serialize)]
struct HilReport {
    port: String,
    baud: u32,
    rate_hz: f32,
    speedup: f32,
    /// Ticks run; none when the host gave up.
    ticks: Option<usize>,
    /// The family's metric; none when the host gave up.
    metric: Option<f32>,
    /// Why the host gave the run up (the device not back in time); none for a finished run.
    gave_up: Option<String>,
    deadline_misses: usize,
    late_starts: usize,
    held_safe: usize,
    faults: usize,
    round_trip_us: Percentiles,
    device_compute_us: Percentiles,
    uploads: usize,
    reconnects: usize,
    link: firmware_sim::serial::LinkCounters,
    wire: firmware_sim::serial::WireStats,
    events: Vec<firmware_sim::serial::LinkEvent>,
}

/// Median, p99 and max, microseconds.
#[derive(Debug, Serialize)]
struct Percentiles {
    median: f64,
    p99: f64,
    max: f64,
}

fn percentiles(mut v: Vec<f64>) -> Percentiles {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| {
        v.get(((v.len().max(1) - 1) as f64 * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    Percentiles {
        median: at(0.5),
        p99: at(0.99),
        max: v.last().copied().unwrap_or(0.0),
    }
}

/// Run `firmware-sim host`.
pub(crate) fn host_cmd(a: HostArgs) -> Result<()> {
    let p = &a.plant;
    let prep = prepare(p)?;
    let context = prep.context(p);
    let config = plant_config(p, prep.physics);
    let family = prep.task.family();
    let mut plant = sim::make_env(family, config.plant)?;
    let rate = p.rate.unwrap_or(1.0 / plant.control_dt());
    let link = open_link(&a)?;
    eprintln!(
        "host: uploading {} B and teaching {} demo(s) over {} at {} baud (about {:.1} s on the line)",
        prep.blob.len(),
        context.len(),
        a.port.display(),
        a.baud,
        serial::line_time(prep.blob.len() * 103 / 100, a.baud).as_secs_f64()
    );
    let mut remote = RemoteDevice::new(link, &prep.blob, context, rate * a.speedup)?;
    let started = remote.start();
    for e in &remote.events {
        eprintln!("host: tick {}: {}", e.tick, e.what);
    }
    if let Err(e) = started {
        return Err(gave_up(
            &a,
            rate,
            &remote,
            refusal_in_words(e, prep.blob.len()),
        )?);
    }
    let shown = remote.events.len();
    let run = firmware_sim::run(&mut remote, plant.as_mut(), &prep.task, &config.control);
    for e in &remote.events[shown..] {
        eprintln!("host: tick {}: {}", e.tick, e.what);
    }
    let report = match run {
        Ok(report) => report,
        Err(e) => return Err(gave_up(&a, rate, &remote, anyhow::Error::new(e))?),
    };
    if let Some(warning) = &prep.provenance {
        eprintln!("{warning}");
    }
    write_trace(&p.out, &report, &[])?;
    let hil = hil_report(&a, rate, Some(&report), &remote);
    firmware_sim::write_atomic(
        &p.out.join("hil.json"),
        serde_json::to_string_pretty(&hil)?.as_bytes(),
    )?;
    let summary = summary(&hil, &report);
    firmware_sim::write_atomic(&p.out.join("summary.txt"), summary.as_bytes())?;
    print!("{summary}");
    println!(
        "wrote {}/{{trace.csv, plot.svg, summary.txt, hil.json}}",
        p.out.display()
    );
    let share = hil.held_safe as f32 / report.records.len().max(1) as f32;
    if share > a.max_held_safe {
        anyhow::bail!(
            "{} of {} ticks ({:.0}%) held the safe action, more than --max-held-safe {}: the \
             metric {:.4} is the safe action's more than the policy's, not a result (the events \
             are in {})",
            hil.held_safe,
            report.records.len(),
            100.0 * share,
            a.max_held_safe,
            report.metric,
            p.out.join("hil.json").display()
        );
    }
    Ok(())
}

/// A run given up (the device never brought up, or lost past `--reconnect-s`): what happened
/// up to the end still goes to `hil.json`, the events saying why; the error names the file.
fn gave_up(
    a: &HostArgs,
    rate: f32,
    remote: &RemoteDevice<'_>,
    e: anyhow::Error,
) -> Result<anyhow::Error> {
    let out = &a.plant.out;
    let mut hil = hil_report(a, rate, None, remote);
    hil.gave_up = Some(format!("{e:#}"));
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("hil.json");
    firmware_sim::write_atomic(&path, serde_json::to_string_pretty(&hil)?.as_bytes())?;
    Ok(e.context(format!(
        "the run was given up (its events: {})",
        path.display()
    )))
}

/// The serial link to the device at `--port`, with the host's timeouts and injected faults.
fn open_link(a: &HostArgs) -> Result<serial::SerialLink> {
    let p = &a.plant;
    let mut serial_config = SerialConfig::new(a.port.clone(), a.baud);
    if let Some(ms) = a.reply_timeout_ms {
        serial_config.reply_timeout = Duration::from_millis(ms);
    }
    serial_config.lost_after = a.lost_after;
    serial_config.reconnect_for = Duration::from_secs(a.reconnect_s);
    serial_config.faults = Faults {
        corrupt: p.link_corrupt,
        drop: p.link_drop,
        seed: p.seed,
    };
    serial::SerialLink::open(serial_config).with_context(|| {
        format!(
            "opening --port {} (is the device running? `firmware-sim device --pty {}` makes one)",
            a.port.display(),
            a.port.display()
        )
    })
}

/// What `hil.json` records of the run over the serial link.
fn hil_report(
    a: &HostArgs,
    rate: f32,
    report: Option<&firmware_sim::RunReport>,
    remote: &RemoteDevice,
) -> HilReport {
    let (counters, wire) = remote.counters();
    HilReport {
        port: a.port.display().to_string(),
        baud: a.baud,
        rate_hz: rate,
        speedup: a.speedup,
        ticks: report.map(|r| r.records.len()),
        metric: report.map(|r| r.metric),
        gave_up: None,
        deadline_misses: remote.misses,
        late_starts: remote.late_starts,
        held_safe: remote.held_safe,
        faults: report.map_or(0, |r| r.faults),
        round_trip_us: percentiles(
            remote
                .round_trip_ns
                .iter()
                .map(|&n| n as f64 / 1e3)
                .collect(),
        ),
        device_compute_us: percentiles(
            remote
                .device_compute_us
                .iter()
                .map(|&u| f64::from(u))
                .collect(),
        ),
        uploads: remote.uploads,
        reconnects: remote.reconnects,
        link: counters,
        wire,
        events: remote.events.clone(),
    }
}

/// The run's summary in words (`summary.txt`, and what the command prints).
fn summary(hil: &HilReport, report: &firmware_sim::RunReport) -> String {
    let rate = hil.rate_hz;
    let head = format!(
        "task            {} ({})\nmetric          {:?} = {:.4}\nticks           {} ({} \
             plant steps each)\nfaults          {}",
        report.task.label(),
        report.task.family(),
        report.task.family().metric_kind(),
        report.metric,
        report.records.len(),
        report.steps_per_tick,
        report.faults
    );
    format!(
        "{}\nhil             {} ticks at {rate} Hz x {} over {} ({} baud): {} deadline misses, {} late \
         starts, {} ticks on the safe action, {} reconnects\nround trip      median {:.0} us, \
         p99 {:.0} us, max {:.0} us (device compute median {:.0} us)\nlink            {} \
         frames out, {} in; {} resends, {} damaged answers, {} stale; injected {} corrupt, {} \
         dropped\n",
        head,
        report.records.len(),
        hil.speedup,
        hil.port,
        hil.baud,
        hil.deadline_misses,
        hil.late_starts,
        hil.held_safe,
        hil.reconnects,
        hil.round_trip_us.median,
        hil.round_trip_us.p99,
        hil.round_trip_us.max,
        hil.device_compute_us.median,
        hil.wire.frames_out,
        hil.wire.frames_in,
        hil.link.retries,
        hil.link.bad_frames,
        hil.link.stale,
        hil.wire.injected_corrupt,
        hil.wire.injected_drop,
    )
}

/// A device refusal of the blob in words the person at the bench can act on.
fn refusal_in_words(e: firmware_sim::LoopError, bytes: usize) -> anyhow::Error {
    use firmware_sim::link::{LinkError, Refusal};
    let reason = match &e {
        firmware_sim::LoopError::Link(LinkError::Refused { reason, .. }) => match reason {
            Refusal::BlobTooLarge => format!(
                "the blob's {bytes} B do not fit the device's flash (see `firmware-sim device \
                 --flash-kib`)"
            ),
            Refusal::DoesNotFit => {
                "the model needs more RAM or wider layers than the device has".into()
            }
            Refusal::BadBlob => "the blob failed the device's checksum or validation".into(),
            other => format!("{other:?}"),
        },
        _ => return anyhow::Error::new(e),
    };
    anyhow::anyhow!("the device refused the blob: {reason}")
}
