//! The host's side of a device on a serial port: stop-and-wait messages with timeouts for the
//! upload and the teach ([`SerialLink`]), and the control loop's [`Brain`] that sends each
//! tick's observation and waits for the action until the tick's deadline ([`RemoteDevice`]),
//! holding the safe action and reconnecting when the device goes away.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use sim::Trajectory;

use super::wire::{Faults, Wire, WireStats, line_time, port_error};
use crate::control::LoopError;
use crate::control::{Brain, Outcome};
use crate::host;
use crate::link::{
    DeviceMessage, HostMessage, LinkError, MAX_FRAME, PROTOCOL_VERSION, Packet, Refusal,
    decode_frame, decode_message, encode_frame,
};

/// How the host talks to the device.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialConfig {
    /// The serial device (a USB-serial adapter, or the pseudo-terminal `firmware-sim device
    /// --pty` links).
    pub port: PathBuf,
    /// Line rate; 0: unpaced.
    pub baud: u32,
    /// How long one message waits for its answer before it is sent again.
    pub reply_timeout: Duration,
    /// Resends of one upload or teach message before the link is declared dead.
    pub max_retries: u32,
    /// Missed ticks in a row after which the device counts as gone (the host then holds the
    /// safe action and reconnects).
    pub lost_after: u32,
    /// How long the host keeps trying to get a lost device back before it gives up the run.
    pub reconnect_for: Duration,
    /// Faults injected on the host's frames, both directions.
    pub faults: Faults,
}

impl SerialConfig {
    /// `port` at `baud` with the defaults: a reply timeout of two longest frames on the line
    /// plus 100 ms, 8 resends, lost after 5 silent ticks, reconnecting for 20 s.
    pub fn new(port: PathBuf, baud: u32) -> Self {
        Self {
            port,
            baud,
            reply_timeout: 2 * line_time(MAX_FRAME, baud) + Duration::from_millis(100),
            max_retries: 8,
            lost_after: 5,
            reconnect_for: Duration::from_secs(20),
            faults: Faults::default(),
        }
    }
}

/// The device's answer to `Hello`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceStatus {
    /// Bytes and CRC-32 of its committed blob, if any.
    pub blob: Option<(u32, u32)>,
    /// Whether it holds a taught context.
    pub taught: bool,
    /// Watchdog trips since it booted.
    pub watchdog_trips: u32,
}

/// Link counters of the host's side.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkCounters {
    /// Messages resent (no or a damaged answer in time).
    pub retries: u64,
    /// Answers that failed their checksum or did not decode.
    pub bad_frames: u64,
    /// Answers to another message than the one waited for (a late answer).
    pub stale: u64,
}

/// Stop-and-wait messages over a serial port, with timeouts on every wait.
#[derive(Debug)]
pub struct SerialLink {
    config: SerialConfig,
    wire: Wire,
    seq: u16,
    /// What the host's link saw.
    pub counters: LinkCounters,
}

impl SerialLink {
    /// Opens the port.
    pub fn open(config: SerialConfig) -> Result<Self, LinkError> {
        let wire = open_wire(&config)?;
        Ok(Self {
            config,
            wire,
            seq: 0,
            counters: LinkCounters::default(),
        })
    }

    /// Closes and opens the port again (the device process was restarted behind it).
    pub fn reopen(&mut self) -> Result<(), LinkError> {
        let stats = self.wire.stats;
        // Let go first: the port is opened exclusively, so a new handle beside the old one
        // fails ("Unable to acquire exclusive lock"), and every reconnect with it (issue 72).
        self.wire.close();
        self.wire = open_wire(&self.config)?;
        self.wire.stats = stats;
        self.wire.clear();
        Ok(())
    }

    /// The wire's counters.
    pub fn wire_stats(&self) -> WireStats {
        self.wire.stats
    }

    fn next_seq(&mut self) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        self.seq
    }

    /// Sends `message` once and returns the first well-formed answer to it before `until`.
    fn exchange(
        &mut self,
        seq: u16,
        message: &HostMessage<'_>,
        until: Instant,
    ) -> Result<Option<DeviceMessage>, LinkError> {
        let mut frame = [0u8; MAX_FRAME];
        let len = encode_frame(&Packet { seq, message }, &mut frame)?;
        self.wire.send(&frame[..len])?;
        while let Some(back) = self.wire.receive(until)? {
            let mut scratch = [0u8; MAX_FRAME];
            let answer = decode_frame(back, &mut scratch).and_then(decode_message::<DeviceMessage>);
            match answer {
                Ok(answer) if answer.seq() == seq => return Ok(Some(answer)),
                Ok(_) => self.counters.stale += 1,
                Err(_) => self.counters.bad_frames += 1,
            }
        }
        Ok(None)
    }

    /// Sends `message` until it is answered (resending on silence or damage), and returns
    /// the answer; a refusal is an error carrying the device's reason.
    pub fn request(&mut self, message: &HostMessage<'_>) -> Result<DeviceMessage, LinkError> {
        let seq = self.next_seq();
        let attempts = self.config.max_retries + 1;
        for attempt in 0..attempts {
            if attempt > 0 {
                self.counters.retries += 1;
            }
            let until = Instant::now() + self.config.reply_timeout;
            match self.exchange(seq, message, until)? {
                Some(DeviceMessage::Refused { reason, .. }) => {
                    return Err(LinkError::Refused { seq, reason });
                }
                Some(answer) => return Ok(answer),
                None => {}
            }
        }
        Err(LinkError::RetriesExhausted { seq, attempts })
    }

    /// Sends `message` and waits for its acknowledgement.
    pub fn send(&mut self, message: &HostMessage<'_>) -> Result<(), LinkError> {
        match self.request(message)? {
            DeviceMessage::Ack { .. } => Ok(()),
            other => Err(LinkError::Unexpected { seq: other.seq() }),
        }
    }

    /// Asks the device what it holds; refuses another protocol version.
    pub fn hello(&mut self) -> Result<DeviceStatus, LinkError> {
        let hello = HostMessage::Hello {
            version: PROTOCOL_VERSION,
        };
        match self.request(&hello)? {
            DeviceMessage::Status {
                version,
                blob_len,
                blob_crc,
                taught,
                watchdog_trips,
                ..
            } => {
                if version != PROTOCOL_VERSION {
                    return Err(LinkError::Version {
                        device: version,
                        host: PROTOCOL_VERSION,
                    });
                }
                Ok(DeviceStatus {
                    blob: (blob_len > 0).then_some((blob_len, blob_crc)),
                    taught,
                    watchdog_trips,
                })
            }
            other => Err(LinkError::Unexpected { seq: other.seq() }),
        }
    }

    /// The latent the device's last teach fixed (`Refused(NotReady)` before one): to check
    /// the device's `z` against the host's own, bit for bit.
    pub fn latent(&mut self) -> Result<Vec<f32>, LinkError> {
        match self.request(&HostMessage::Latent)? {
            DeviceMessage::Latent { z, .. } => Ok(z.to_vec()),
            other => Err(LinkError::Unexpected { seq: other.seq() }),
        }
    }

    /// One tick: the action answered before `deadline`, or `None`. A tick whose answer does
    /// not come within a round trip's time (the frame or its answer lost or damaged) is sent
    /// again while the deadline leaves room; the device answers a resend from its record
    /// without computing twice.
    pub fn tick(
        &mut self,
        tick: u32,
        obs: &[f32],
        deadline: Instant,
    ) -> Result<Option<(crate::link::Floats, bool, u32)>, LinkError> {
        let seq = self.next_seq();
        let message = HostMessage::Tick {
            tick,
            obs: host::floats(obs)?,
        };
        let round_trip = 2 * line_time(MAX_FRAME / 2, self.config.baud) + Duration::from_millis(5);
        let mut answer = None;
        for attempt in 0.. {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            if attempt > 0 {
                self.counters.retries += 1;
            }
            answer = self.exchange(seq, &message, deadline.min(now + round_trip))?;
            if answer.is_some() {
                break;
            }
        }
        match answer {
            Some(DeviceMessage::Action {
                tick: t,
                action,
                fault,
                compute_us,
                ..
            }) if t == tick => Ok(Some((action, fault, compute_us))),
            Some(DeviceMessage::Refused { reason, .. }) => Err(LinkError::Refused { seq, reason }),
            Some(_) => {
                self.counters.stale += 1;
                Ok(None)
            }
            None => Ok(None),
        }
    }
}

fn open_wire(config: &SerialConfig) -> Result<Wire, LinkError> {
    let name = config.port.to_string_lossy();
    Ok(Wire::open(&name, config.baud)?.with_faults(config.faults))
}

/// What happened on the link during a run, for the person watching and the report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LinkEvent {
    /// The tick it happened at.
    pub tick: usize,
    /// What happened.
    pub what: String,
}

/// The device behind a serial port as the control loop's [`Brain`]: real time at the control
/// rate, one tick message and one action per tick, a deadline per tick.
pub struct RemoteDevice<'a> {
    link: SerialLink,
    blob: &'a [u8],
    /// The blob's length and CRC-32, as the device's `Status` names a committed one.
    blob_id: (u32, u32),
    context: Vec<&'a Trajectory>,
    dims: (usize, usize),
    safe: Vec<f32>,
    period: Duration,
    schedule: Option<Instant>,
    tick_start: Instant,
    silent: u32,
    lost_since: Option<Instant>,
    next_try: Instant,
    /// Everything the host had to say about the link during the run.
    pub events: Vec<LinkEvent>,
    /// Ticks whose action did not come back by the deadline.
    pub misses: usize,
    /// Ticks that started late because the host itself fell behind the schedule.
    pub late_starts: usize,
    /// Ticks run on the safe action while the device was gone.
    pub held_safe: usize,
    /// Round trips of the answered ticks, nanoseconds.
    pub round_trip_ns: Vec<u64>,
    /// The device's own compute time of the answered ticks, microseconds.
    pub device_compute_us: Vec<u32>,
    /// Blob uploads (the first included).
    pub uploads: usize,
    /// Times the device came back after being lost.
    pub reconnects: usize,
}

impl std::fmt::Debug for RemoteDevice<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteDevice")
            .field("link", &self.link)
            .field("misses", &self.misses)
            .finish_non_exhaustive()
    }
}

impl<'a> RemoteDevice<'a> {
    /// The host's side of a device reached over `link`, nothing sent yet: checks that `blob`
    /// is a model and takes its dimensions and safe action. [`Self::start`] then brings the
    /// device up; ticks run at `rate_hz`.
    pub fn new(
        link: SerialLink,
        blob: &'a [u8],
        context: Vec<&'a Trajectory>,
        rate_hz: f32,
    ) -> Result<Self, LoopError> {
        let model =
            infer_core::Model::from_bytes(blob).map_err(crate::device::DeviceError::from)?;
        let h = *model.header();
        let dims = (h.obs_dim as usize, h.act_dim as usize);
        let policy = infer_core::Policy::<{ crate::device::CAPACITY }>::new(&model)
            .map_err(crate::device::DeviceError::from)?;
        let mut safe = vec![0.0; dims.1];
        policy.safe_action(&mut safe);
        let now = Instant::now();
        let remote = Self {
            link,
            blob,
            blob_id: (blob.len() as u32, infer_core::crc32(blob)),
            context,
            dims,
            safe,
            period: Duration::from_secs_f64(1.0 / f64::from(rate_hz)),
            schedule: None,
            tick_start: now,
            silent: 0,
            lost_since: None,
            next_try: now,
            events: Vec::new(),
            misses: 0,
            late_starts: 0,
            held_safe: 0,
            round_trip_ns: Vec::new(),
            device_compute_us: Vec::new(),
            uploads: 0,
            reconnects: 0,
        };
        Ok(remote)
    }

    /// Brings the device up: hello, the blob if it lacks it, the context. A line that fails
    /// on the way (a device killed or restarted during the upload, a port that went away) is
    /// reopened and the bring-up started over, every 200 ms for at most the link's
    /// `reconnect_for`; a refusal ends it at once. The events say what happened (written to
    /// `hil.json` by a host that gives up).
    pub fn start(&mut self) -> Result<(), LoopError> {
        let first = match self.bring_up(0) {
            Ok(()) => return Ok(()),
            Err(e @ LinkError::Refused { .. }) => return Err(LoopError::Link(e)),
            Err(e) => e,
        };
        self.note(0, format!("{first}: reopening the port and starting over"));
        let since = Instant::now();
        loop {
            std::thread::sleep(Duration::from_millis(200));
            match self.link.reopen().and_then(|()| self.bring_up(0)) {
                Ok(()) => {
                    self.reconnects += 1;
                    let took = since.elapsed().as_secs_f64();
                    self.note(0, format!("device back after {took:.1} s; brought up"));
                    return Ok(());
                }
                Err(e @ LinkError::Refused { .. }) => return Err(LoopError::Link(e)),
                Err(e) if since.elapsed() > self.link.config.reconnect_for => {
                    let port = self.link.config.port.to_string_lossy().into_owned();
                    let limit = self.link.config.reconnect_for.as_secs_f64();
                    let why = format!("the device did not come back within {limit:.0} s ({e})");
                    self.note(0, why.clone());
                    return Err(LoopError::Link(port_error(&port, why)));
                }
                Err(_) => {}
            }
        }
    }

    /// The link's counters.
    pub fn counters(&self) -> (LinkCounters, WireStats) {
        (self.link.counters, self.link.wire_stats())
    }

    fn note(&mut self, tick: usize, what: String) {
        self.events.push(LinkEvent { tick, what });
    }

    /// Hello, the blob if the device lacks it, the context.
    fn bring_up(&mut self, tick: usize) -> Result<(), LinkError> {
        let status = self.link.hello()?;
        if status.blob == Some(self.blob_id) {
            self.note(tick, "the device holds this blob already: no upload".into());
        } else {
            let start = Instant::now();
            let link = &mut self.link;
            host::upload_with(&mut |m| link.send(m), self.blob)?;
            self.uploads += 1;
            let took = start.elapsed();
            self.note(
                tick,
                format!(
                    "uploaded the blob ({} B) in {:.2} s",
                    self.blob.len(),
                    took.as_secs_f64()
                ),
            );
        }
        let (obs, act) = self.dims;
        let link = &mut self.link;
        host::teach_with(&mut |m| link.send(m), &self.context, obs, act)?;
        self.note(tick, format!("taught {} demo(s)", self.context.len()));
        Ok(())
    }

    /// While the device is gone: reopen the port and bring it up again, at most every 200 ms.
    fn try_recover(&mut self, tick: usize) -> Result<(), LoopError> {
        let since = self.lost_since.unwrap_or_else(Instant::now);
        if Instant::now() < self.next_try {
            return Ok(());
        }
        self.next_try = Instant::now() + Duration::from_millis(200);
        let recovered = self.link.reopen().and_then(|()| self.bring_up(tick));
        match recovered {
            Ok(()) => {
                self.reconnects += 1;
                self.lost_since = None;
                self.silent = 0;
                // The upload and teach took wall-clock time: the schedule starts again here.
                self.schedule = None;
                self.note(
                    tick,
                    format!(
                        "device back after {:.1} s; ticks resume",
                        since.elapsed().as_secs_f64()
                    ),
                );
                Ok(())
            }
            Err(e @ LinkError::Refused { .. }) => Err(LoopError::Link(e)),
            Err(e) if since.elapsed() > self.link.config.reconnect_for => {
                Err(LoopError::Link(port_error(
                    &self.link.config.port.to_string_lossy(),
                    format!(
                        "the device did not come back within {:.0} s ({e})",
                        self.link.config.reconnect_for.as_secs_f64()
                    ),
                )))
            }
            Err(_) => Ok(()),
        }
    }

    fn lose(&mut self, tick: usize, why: String) {
        if self.lost_since.is_none() {
            self.lost_since = Some(Instant::now());
            self.next_try = Instant::now();
            self.note(
                tick,
                format!("{why}: holding the safe action and reconnecting"),
            );
        }
    }
}

impl Brain for RemoteDevice<'_> {
    fn safe_action(&self, action: &mut [f32]) {
        action.copy_from_slice(&self.safe);
    }

    fn start_tick(&mut self, tick: usize) {
        let now = Instant::now();
        let offset = self.period.mul_f64(tick as f64);
        // The schedule (re)starts with this tick due now (the first tick, or after a reconnect).
        let base = *self.schedule.get_or_insert(now - offset);
        let due = base + offset;
        if now < due {
            std::thread::sleep(due - now);
        } else if now > due + self.period / 2 {
            self.late_starts += 1;
        }
        self.tick_start = Instant::now().max(due);
    }

    fn act(
        &mut self,
        tick: usize,
        sensed: &[f32],
        action: &mut [f32],
    ) -> Result<Outcome, LoopError> {
        if self.lost_since.is_some() {
            self.try_recover(tick)?;
        }
        if self.lost_since.is_some() {
            self.held_safe += 1;
            action.copy_from_slice(&self.safe);
            return Ok(Outcome {
                fault: true,
                late: Some(false),
            });
        }
        let deadline = self.tick_start + self.period;
        let start = Instant::now();
        let lost = match self.link.tick(tick as u32, sensed, deadline) {
            Ok(Some((answer, fault, compute_us))) => {
                self.round_trip_ns.push(start.elapsed().as_nanos() as u64);
                self.device_compute_us.push(compute_us);
                self.silent = 0;
                // An answer the plant cannot take (another action size, a non-finite value:
                // a device of another model, or a broken one) is never applied: the safe
                // action is held for the tick, counted and said (issue 72, item 3).
                if answer.len() != action.len() || answer.iter().any(|x| !x.is_finite()) {
                    self.held_safe += 1;
                    action.copy_from_slice(&self.safe);
                    let why = format!(
                        "the device answered tick {tick} with {:?} ({} values expected, all \
                         finite): holding the safe action",
                        answer.as_slice(),
                        action.len()
                    );
                    self.note(tick, why);
                    return Ok(Outcome {
                        fault: true,
                        late: Some(false),
                    });
                }
                action.copy_from_slice(&answer);
                return Ok(Outcome {
                    fault,
                    late: Some(false),
                });
            }
            Ok(None) => {
                self.silent += 1;
                (self.silent >= self.link.config.lost_after)
                    .then(|| format!("no answer to {} ticks in a row", self.silent))
            }
            // The device reset and lost its context (or its blob): bring it up again.
            Err(LinkError::Refused {
                reason: Refusal::NotReady,
                ..
            }) => Some("the device is not ready (it was reset)".into()),
            Err(e) => Some(e.to_string()),
        };
        // A miss: the loop holds the last applied action for this tick.
        self.misses += 1;
        if let Some(why) = lost {
            self.lose(tick, why);
        }
        Ok(Outcome {
            fault: false,
            late: Some(true),
        })
    }
}
