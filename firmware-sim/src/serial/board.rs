//! The device as its own process behind a serial port: the bootloader and the application of
//! [`crate::device`] serving frames from a [`Wire`], with the watchdog a board has. What runs
//! here is what a microcontroller runs: infer-core, the protocol and fixed buffers; nothing in
//! the tick path allocates.
//!
//! ```text
//! boot ─► bootloader ── a Teach or Tick with a blob committed ─► application
//!            ▲                                                       │
//!            └──────────────── a BlobBegin (re-flash) ◄──────────────┘
//! ```

use std::path::PathBuf;
use std::time::{Duration, Instant};

use infer_core::Model;

use super::wire::Wire;
use crate::device::{Controller, Device, DeviceConfig, DeviceError};
use crate::link::{
    Dedup, DeviceMessage, HostMessage, LinkError, MAX_DIM, MAX_FRAME, PROTOCOL_VERSION, Packet,
    Refusal, decode_frame, decode_message, encode_frame,
};

/// How the board runs.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardConfig {
    /// Flash and RAM budgets.
    pub device: DeviceConfig,
    /// The host must send a tick this often once ticks have started; past it the board holds
    /// the safe action until ticks come back.
    pub watchdog: Duration,
    /// A file standing for the board's flash: a committed blob is written there and read at
    /// boot, so a reset board keeps its blob as a real one does. `None`: flash is lost with the
    /// process.
    pub flash_file: Option<PathBuf>,
}

impl Default for BoardConfig {
    fn default() -> Self {
        Self {
            device: DeviceConfig::default(),
            watchdog: Duration::from_millis(500),
            flash_file: None,
        }
    }
}

/// What the board reports (its serial console, on a real bench).
#[derive(Debug, Clone, PartialEq)]
pub enum BoardEvent {
    /// Booted; the blob found in flash, if any (bytes, CRC-32).
    Booted(Option<(usize, u32)>),
    /// A blob arrived, verified and was committed to flash.
    Committed(usize, u32),
    /// The flash file could not be read or written (the board runs on without it).
    Flash(String),
    /// A message was refused.
    Refused(Refusal),
    /// A context was taught (z fixed).
    Taught,
    /// The host was silent past the watchdog: the safe action is held.
    Watchdog(Duration),
    /// Ticks came back after a watchdog trip.
    Resumed(u32),
}

/// Why the board stopped.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// The port failed for good.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The committed blob cannot run (a bug: it was checked when committed).
    #[error(transparent)]
    Device(#[from] DeviceError),
}

/// Board state that outlives one application phase.
struct Board<'c> {
    config: &'c BoardConfig,
    dedup: Dedup,
    watchdog_trips: u32,
    reply: [u8; MAX_FRAME],
}

impl Board<'_> {
    /// Answers `seq` with the recorded answer if it is a resend, else with `apply`'s.
    fn answer(
        &mut self,
        seq: u16,
        apply: impl FnOnce(&mut Self) -> Result<Option<DeviceMessage>, Refusal>,
    ) -> DeviceMessage {
        if let Some(answer) = self.dedup.seen(seq) {
            return answer;
        }
        let answer = match apply(self) {
            Ok(None) => DeviceMessage::Ack { seq },
            Ok(Some(answer)) => answer,
            Err(reason) => DeviceMessage::Refused { seq, reason },
        };
        self.dedup.record(seq, answer)
    }

    fn reply(&mut self, wire: &mut Wire, answer: &DeviceMessage) -> Result<(), LinkError> {
        let n = encode_frame(answer, &mut self.reply)?;
        let frame = self.reply;
        wire.send(&frame[..n])
    }

    fn status(&self, seq: u16, device: &Device, taught: bool) -> DeviceMessage {
        let (blob_len, blob_crc) = blob_id(device).unwrap_or((0, 0));
        DeviceMessage::Status {
            seq,
            version: PROTOCOL_VERSION,
            blob_len: blob_len as u32,
            blob_crc,
            taught,
            watchdog_trips: self.watchdog_trips,
        }
    }
}

/// The committed blob's length and CRC-32.
fn blob_id(device: &Device) -> Option<(usize, u32)> {
    device.blob().ok().map(|b| (b.len(), infer_core::crc32(b)))
}

/// A frame's packet, or `None` for a damaged one (not answered: the host resends).
fn packet<'s>(frame: &[u8], scratch: &'s mut [u8; MAX_FRAME]) -> Option<Packet<HostMessage<'s>>> {
    let payload = decode_frame(frame, scratch).ok()?;
    decode_message(payload).ok()
}

/// Whether the application handles `message` (the bootloader hands these over).
fn for_application(message: &HostMessage<'_>) -> bool {
    matches!(
        message,
        HostMessage::TeachBegin
            | HostMessage::Transition { .. }
            | HostMessage::EndTrajectory
            | HostMessage::TeachEnd
            | HostMessage::Tick { .. }
    )
}

/// Runs the board on `wire` until `stop` says so (a process runs until it is killed).
pub fn serve(
    wire: &mut Wire,
    config: &BoardConfig,
    stop: &dyn Fn() -> bool,
    on: &mut dyn FnMut(BoardEvent),
) -> Result<(), BoardError> {
    let mut device = Device::new(config.device);
    if let Some(path) = config.flash_file.as_ref().filter(|p| p.exists()) {
        match std::fs::read(path) {
            Ok(bytes) => {
                if let Err(e) = device.restore(&bytes) {
                    on(BoardEvent::Flash(format!("{}: {e}", path.display())));
                }
            }
            Err(e) => on(BoardEvent::Flash(format!("{}: {e}", path.display()))),
        }
    }
    on(BoardEvent::Booted(blob_id(&device)));
    let mut board = Board {
        config,
        dedup: Dedup::default(),
        watchdog_trips: 0,
        reply: [0; MAX_FRAME],
    };
    let mut handover: Option<([u8; MAX_FRAME], usize)> = None;
    loop {
        let Some((frame, len)) = bootloader(wire, &mut board, &mut device, handover, stop, on)?
        else {
            return Ok(());
        };
        let model = Model::from_bytes(device.blob()?).map_err(DeviceError::from)?;
        let mut app = Controller::new(&model, config.device)?;
        handover = application(wire, &mut board, &device, &mut app, (frame, len), stop, on)?;
        if handover.is_none() {
            return Ok(());
        }
    }
}

/// The bootloader: flashes blobs and answers `Hello` until a committed blob and a message for
/// the application are there; returns that message's frame (`None`: stopped).
fn bootloader(
    wire: &mut Wire,
    board: &mut Board<'_>,
    device: &mut Device,
    handover: Option<([u8; MAX_FRAME], usize)>,
    stop: &dyn Fn() -> bool,
    on: &mut dyn FnMut(BoardEvent),
) -> Result<Option<([u8; MAX_FRAME], usize)>, BoardError> {
    let (mut buf, mut pending) = match handover {
        Some((frame, len)) => (frame, Some(len)),
        None => ([0u8; MAX_FRAME], None),
    };
    loop {
        let Some(len) = next_frame(wire, &mut buf, &mut pending, Duration::from_millis(50))? else {
            if stop() {
                return Ok(None);
            }
            continue;
        };
        let mut scratch = [0u8; MAX_FRAME];
        let Some(p) = packet(&buf[..len], &mut scratch) else {
            continue;
        };
        let fresh = board.dedup.seen(p.seq).is_none();
        if fresh && for_application(&p.message) && device.blob().is_ok() {
            return Ok(Some((buf, len)));
        }
        let answer = board.answer(p.seq, |b| match &p.message {
            HostMessage::Hello { .. } => Ok(Some(b.status(p.seq, device, false))),
            m => device.apply(m).map(|()| None),
        });
        if let DeviceMessage::Refused { reason, .. } = answer {
            on(BoardEvent::Refused(reason));
        }
        board.reply(wire, &answer)?;
        let committed = matches!(p.message, HostMessage::BlobEnd)
            && matches!(answer, DeviceMessage::Ack { .. });
        if let Some((len, crc)) = blob_id(device).filter(|_| fresh && committed) {
            on(BoardEvent::Committed(len, crc));
            persist(board.config, device, on);
        }
    }
}

/// The next frame into `buf`: the one `pending` names (already in `buf`), else one read within
/// `wait`; `None` when none came.
fn next_frame(
    wire: &mut Wire,
    buf: &mut [u8; MAX_FRAME],
    pending: &mut Option<usize>,
    wait: Duration,
) -> Result<Option<usize>, LinkError> {
    if let Some(len) = pending.take() {
        return Ok(Some(len));
    }
    Ok(wire.receive(Instant::now() + wait)?.map(|frame| {
        buf[..frame.len()].copy_from_slice(frame);
        frame.len()
    }))
}

/// Writes the committed blob to the flash file, if there is one.
fn persist(config: &BoardConfig, device: &Device, on: &mut dyn FnMut(BoardEvent)) {
    if let (Some(path), Ok(blob)) = (&config.flash_file, device.blob())
        && let Err(e) = crate::files::write_atomic(path, blob)
    {
        on(BoardEvent::Flash(e.to_string()));
    }
}

/// The application: teaches, ticks and answers `Hello`, with the watchdog, until a new blob
/// upload begins; returns that message's frame for the bootloader (`None`: stopped).
fn application(
    wire: &mut Wire,
    board: &mut Board<'_>,
    device: &Device,
    app: &mut Controller<'_, '_>,
    first: ([u8; MAX_FRAME], usize),
    stop: &dyn Fn() -> bool,
    on: &mut dyn FnMut(BoardEvent),
) -> Result<Option<([u8; MAX_FRAME], usize)>, BoardError> {
    let mut buf = first.0;
    let mut pending = Some(first.1);
    let mut actuators = [0f32; MAX_DIM];
    let act_dim = app.act_dim();
    // The last tick's time while ticks flow; `None` before the first and after a trip.
    let mut last_tick: Option<Instant> = None;
    let mut holding = false;
    loop {
        let Some(len) = next_frame(wire, &mut buf, &mut pending, Duration::from_millis(20))? else {
            if let Some(t) = last_tick.filter(|t| t.elapsed() > board.config.watchdog) {
                // The host went silent: hold the safe action until it comes back.
                app.safe_action(&mut actuators[..act_dim]);
                board.watchdog_trips += 1;
                holding = true;
                last_tick = None;
                on(BoardEvent::Watchdog(t.elapsed()));
            }
            if stop() {
                return Ok(None);
            }
            continue;
        };
        let mut scratch = [0u8; MAX_FRAME];
        let Some(p) = packet(&buf[..len], &mut scratch) else {
            continue;
        };
        let fresh = board.dedup.seen(p.seq).is_none();
        if fresh && !for_application(&p.message) && !matches!(p.message, HostMessage::Hello { .. })
        {
            return Ok(Some((buf, len)));
        }
        let answer = board.answer(p.seq, |b| match &p.message {
            HostMessage::Hello { .. } => Ok(Some(b.status(p.seq, device, app.z().is_some()))),
            HostMessage::Tick { tick, obs } => {
                let start = Instant::now();
                let mut action = crate::link::Floats::new();
                let _ = action.resize(act_dim, 0.0);
                // Untaught (no z yet): not ready; a bad reading: the safe action, a fault.
                let fault = app
                    .act(obs, &mut action)
                    .map_err(|_| Refusal::NotReady)?
                    .is_err();
                actuators[..act_dim].copy_from_slice(&action);
                Ok(Some(DeviceMessage::Action {
                    seq: p.seq,
                    tick: *tick,
                    action,
                    fault,
                    compute_us: start.elapsed().as_micros().min(u32::MAX as u128) as u32,
                }))
            }
            m => app.apply(m).map(|()| None),
        });
        match &answer {
            _ if !fresh => {}
            DeviceMessage::Refused { reason, .. } => on(BoardEvent::Refused(*reason)),
            DeviceMessage::Action { tick, .. } => {
                if holding {
                    holding = false;
                    on(BoardEvent::Resumed(*tick));
                }
                last_tick = Some(Instant::now());
            }
            DeviceMessage::Ack { .. } if matches!(p.message, HostMessage::TeachEnd) => {
                on(BoardEvent::Taught);
                last_tick = None;
            }
            _ => {}
        }
        board.reply(wire, &answer)?;
    }
}
