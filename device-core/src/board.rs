//! The board: the bootloader and the application of [`crate::device`] serving frames from a
//! [`Port`], with the watchdog a board has. One state machine, run by a PC process over an OS
//! serial device and by the firmware over its UART.
//!
//! ```text
//! boot ─► bootloader ── a Teach or Tick with a blob committed ─► application
//!            ▲                                                       │
//!            └──────────────── a BlobBegin (re-flash) ◄──────────────┘
//! ```

use core::time::Duration;

use infer_core::Model;

use crate::device::{Controller, Device, DeviceConfig, DeviceError};
use crate::wire::{
    Dedup, DeviceMessage, FrameError, HostMessage, MAX_DIM, MAX_FRAME, PROTOCOL_VERSION, Packet,
    Refusal, decode_frame, decode_message, encode_frame,
};

/// What carries the board's frames, and its clock.
pub trait Port {
    /// Why the port failed for good.
    type Error;

    /// The next complete frame (delimiter included) received within `wait`, copied into
    /// `frame`; its length, or `None` when none came.
    fn receive(
        &mut self,
        frame: &mut [u8; MAX_FRAME],
        wait: Duration,
    ) -> Result<Option<usize>, Self::Error>;

    /// Puts one frame on the line.
    fn send(&mut self, frame: &[u8]) -> Result<(), Self::Error>;

    /// Time since boot, monotonic.
    fn now(&self) -> Duration;

    /// Whether to stop serving (a process being shut down; a board never stops).
    fn stop(&self) -> bool {
        false
    }
}

/// How the board runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardConfig {
    /// Flash and RAM budgets.
    pub device: DeviceConfig,
    /// The host must send a tick this often once ticks have started; past it the board holds
    /// the safe action until ticks come back.
    pub watchdog: Duration,
}

impl Default for BoardConfig {
    fn default() -> Self {
        Self {
            device: DeviceConfig::default(),
            watchdog: Duration::from_millis(500),
        }
    }
}

/// What the board reports (its console).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum BoardEvent<'b> {
    /// Booted; the blob found in flash, if any (bytes, CRC-32).
    Booted(Option<(usize, u32)>),
    /// A blob arrived, verified and was committed to flash.
    Committed {
        /// The committed blob.
        blob: &'b [u8],
        /// Its CRC-32.
        crc: u32,
    },
    /// A message was refused.
    Refused(Refusal),
    /// A context was taught (z fixed).
    Taught {
        /// Transitions the encoder folded in.
        transitions: u32,
        /// Time spent in the encoder's pushes (the device's compute, not the line's).
        push_time: Duration,
    },
    /// A `Hello` was answered (a board may report its health here).
    Greeted,
    /// The host was silent past the watchdog: the safe action is held.
    Watchdog(Duration),
    /// Ticks came back after a watchdog trip.
    Resumed(u32),
}

/// Why the board stopped.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum BoardError<E> {
    /// The port failed for good.
    Port(E),
    /// An answer could not be framed (a bug: every answer fits a frame).
    Frame(FrameError),
    /// The committed blob cannot run (a bug: it was checked when committed).
    Device(DeviceError),
}

impl<E: core::fmt::Display> core::fmt::Display for BoardError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Port(e) => e.fmt(f),
            Self::Frame(e) => write!(f, "an answer could not be framed: {e}"),
            Self::Device(e) => e.fmt(f),
        }
    }
}

impl<E: core::fmt::Debug + core::fmt::Display> core::error::Error for BoardError<E> {}

/// Board state that outlives one application phase.
struct Board<'c, P> {
    port: &'c mut P,
    config: &'c BoardConfig,
    dedup: Dedup,
    watchdog_trips: u32,
}

/// A frame held for the other phase: the message that made the bootloader hand over to the
/// application, or the application back to the bootloader.
type Handover = Option<([u8; MAX_FRAME], usize)>;

impl<P: Port> Board<'_, P> {
    fn reply(&mut self, answer: &DeviceMessage) -> Result<(), BoardError<P::Error>> {
        let mut out = [0u8; MAX_FRAME];
        let n = encode_frame(answer, &mut out).map_err(BoardError::Frame)?;
        self.port.send(&out[..n]).map_err(BoardError::Port)
    }

    fn status(&self, seq: u16, blob: Option<(usize, u32)>, taught: bool) -> DeviceMessage {
        let (blob_len, blob_crc) = blob.unwrap_or((0, 0));
        DeviceMessage::Status {
            seq,
            version: PROTOCOL_VERSION,
            blob_len: blob_len as u32,
            blob_crc,
            taught,
            watchdog_trips: self.watchdog_trips,
        }
    }

    /// The next frame into `buf`: the one `pending` names (already in `buf`), else one read
    /// within `wait`; `None` when none came.
    fn next_frame(
        &mut self,
        buf: &mut [u8; MAX_FRAME],
        pending: &mut Option<usize>,
        wait: Duration,
    ) -> Result<Option<usize>, BoardError<P::Error>> {
        if let Some(len) = pending.take() {
            return Ok(Some(len));
        }
        self.port.receive(buf, wait).map_err(BoardError::Port)
    }
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
            | HostMessage::Latent
    )
}

/// Runs the board on `port` with `device`'s flash until the port says stop (a board runs
/// until it is reset). `on` hears every [`BoardEvent`].
pub fn serve<P: Port, F: AsRef<[u8]> + AsMut<[u8]>>(
    port: &mut P,
    device: &mut Device<F>,
    config: &BoardConfig,
    on: &mut dyn FnMut(BoardEvent<'_>),
) -> Result<(), BoardError<P::Error>> {
    on(BoardEvent::Booted(device.blob_id()));
    let mut board = Board {
        port,
        config,
        dedup: Dedup::default(),
        watchdog_trips: 0,
    };
    let mut handover: Handover = None;
    loop {
        let Some((frame, len)) = bootloader(&mut board, device, handover, on)? else {
            return Ok(());
        };
        let blob = device.blob().map_err(BoardError::Device)?;
        // The model and the controller are used where their `Result`s were built: moved out
        // of them, each would be held twice in this frame (the controller's scratch is 2.4 KB).
        let parsed = Model::from_bytes(blob);
        let model = match &parsed {
            Ok(model) => model,
            Err(e) => return Err(BoardError::Device(DeviceError::Blob(*e))),
        };
        let mut built = Controller::new(model, config.device);
        let app = match &mut built {
            Ok(app) => app,
            Err(e) => return Err(BoardError::Device(e.clone())),
        };
        handover = application(&mut board, device.blob_id(), app, (frame, len), on)?;
        if handover.is_none() {
            return Ok(());
        }
    }
}

/// What a phase does after a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    /// Read on.
    Stay,
    /// The packet is the other phase's: hand its frame over.
    HandOver,
}

/// The loop both phases run: reads frames (a handed-over one first, `first.1` naming its
/// length), passes over damaged ones, and gives `step` each packet with whether it is fresh
/// (not a resend), or `None` when nothing came within `wait`; after that the port is asked
/// whether to stop. Returns the frame `step` hands over (`None`: stopped).
fn phase<'c, P: Port>(
    board: &mut Board<'c, P>,
    first: ([u8; MAX_FRAME], Option<usize>),
    wait: Duration,
    mut step: impl FnMut(
        &mut Board<'c, P>,
        Option<(Packet<HostMessage<'_>>, bool)>,
    ) -> Result<Step, BoardError<P::Error>>,
) -> Result<Handover, BoardError<P::Error>> {
    let (mut buf, mut pending) = first;
    loop {
        let Some(len) = board.next_frame(&mut buf, &mut pending, wait)? else {
            step(board, None)?;
            if board.port.stop() {
                return Ok(None);
            }
            continue;
        };
        let mut scratch = [0u8; MAX_FRAME];
        let Some(p) = packet(&buf[..len], &mut scratch) else {
            continue;
        };
        let fresh = !board.dedup.is_resend(p.seq);
        if step(board, Some((p, fresh)))? == Step::HandOver {
            return Ok(Some((buf, len)));
        }
    }
}

/// The bootloader: flashes blobs and answers `Hello` until a committed blob and a message for
/// the application are there; returns that message's frame (`None`: stopped).
fn bootloader<P: Port, F: AsRef<[u8]> + AsMut<[u8]>>(
    board: &mut Board<'_, P>,
    device: &mut Device<F>,
    handover: Handover,
    on: &mut dyn FnMut(BoardEvent<'_>),
) -> Result<Handover, BoardError<P::Error>> {
    let first = match handover {
        Some((frame, len)) => (frame, Some(len)),
        None => ([0u8; MAX_FRAME], None),
    };
    phase(board, first, Duration::from_millis(50), |board, read| {
        let Some((p, fresh)) = read else {
            return Ok(Step::Stay);
        };
        if fresh && for_application(&p.message) && device.blob().is_ok() {
            return Ok(Step::HandOver);
        }
        let status = board.status(p.seq, device.blob_id(), false);
        let answer = board.dedup.answer(p.seq, || match &p.message {
            HostMessage::Hello { .. } => Ok(Some(status)),
            m => device.apply(m).map(|()| None),
        });
        if let DeviceMessage::Refused { reason, .. } = answer {
            on(BoardEvent::Refused(reason));
        }
        board.reply(&answer)?;
        let committed = matches!(p.message, HostMessage::BlobEnd)
            && matches!(answer, DeviceMessage::Ack { .. });
        if fresh && matches!(p.message, HostMessage::Hello { .. }) {
            on(BoardEvent::Greeted);
        }
        if let (true, Some((_, crc)), Ok(blob)) =
            (fresh && committed, device.blob_id(), device.blob())
        {
            on(BoardEvent::Committed { blob, crc });
        }
        Ok(Step::Stay)
    })
}

/// The application's watchdog: the last tick's time while ticks flow.
struct Watchdog {
    last_tick: Option<Duration>,
    holding: bool,
}

/// The application: teaches, ticks and answers `Hello`, with the watchdog, until a new blob
/// upload begins; returns that message's frame for the bootloader (`None`: stopped).
fn application<P: Port>(
    board: &mut Board<'_, P>,
    blob: Option<(usize, u32)>,
    app: &mut Controller<'_, '_>,
    first: ([u8; MAX_FRAME], usize),
    on: &mut dyn FnMut(BoardEvent<'_>),
) -> Result<Handover, BoardError<P::Error>> {
    let mut actuators = [0f32; MAX_DIM];
    let act_dim = app.act_dim();
    let mut dog = Watchdog {
        last_tick: None,
        holding: false,
    };
    let (mut transitions, mut push_time) = (0u32, Duration::ZERO);
    let first = (first.0, Some(first.1));
    phase(board, first, Duration::from_millis(20), |board, read| {
        let Some((p, fresh)) = read else {
            let now = board.port.now();
            if let Some(t) = dog
                .last_tick
                .filter(|&t| now.saturating_sub(t) > board.config.watchdog)
            {
                // The host went silent: hold the safe action until it comes back.
                app.safe_action(&mut actuators[..act_dim]);
                board.watchdog_trips += 1;
                dog.holding = true;
                dog.last_tick = None;
                on(BoardEvent::Watchdog(now.saturating_sub(t)));
            }
            return Ok(Step::Stay);
        };
        let hello = matches!(p.message, HostMessage::Hello { .. });
        if fresh && !for_application(&p.message) && !hello {
            return Ok(Step::HandOver);
        }
        let status = board.status(p.seq, blob, app.z().is_some());
        let port = &*board.port;
        let answer = board.dedup.answer(p.seq, || match &p.message {
            HostMessage::Hello { .. } => Ok(Some(status)),
            HostMessage::Latent => app.latent_answer(p.seq).map(Some),
            HostMessage::Tick { tick, obs } => {
                let start = port.now();
                let mut action = crate::wire::Floats::new();
                let _ = action.resize(act_dim, 0.0);
                // Untaught (no z yet): not ready; a bad reading: the safe action, a fault.
                let fault = app
                    .act(obs, &mut action)
                    .map_err(|_| Refusal::NotReady)?
                    .is_err();
                actuators[..act_dim].copy_from_slice(&action);
                let micros = port.now().saturating_sub(start).as_micros();
                Ok(Some(DeviceMessage::Action {
                    seq: p.seq,
                    tick: *tick,
                    action,
                    fault,
                    compute_us: micros.min(u32::MAX as u128) as u32,
                }))
            }
            m => {
                let start = port.now();
                let applied = app.apply(m);
                if matches!(m, HostMessage::TeachBegin) {
                    (transitions, push_time) = (0, Duration::ZERO);
                }
                if matches!(m, HostMessage::Transition { .. }) && applied.is_ok() {
                    transitions += 1;
                    push_time += port.now().saturating_sub(start);
                }
                applied.map(|()| None)
            }
        });
        if fresh {
            match &answer {
                DeviceMessage::Refused { reason, .. } => on(BoardEvent::Refused(*reason)),
                DeviceMessage::Action { tick, .. } => {
                    if dog.holding {
                        dog.holding = false;
                        on(BoardEvent::Resumed(*tick));
                    }
                    dog.last_tick = Some(board.port.now());
                }
                DeviceMessage::Ack { .. } if matches!(p.message, HostMessage::TeachEnd) => {
                    on(BoardEvent::Taught {
                        transitions,
                        push_time,
                    });
                    dog.last_tick = None;
                }
                DeviceMessage::Status { .. } => on(BoardEvent::Greeted),
                _ => {}
            }
        }
        board.reply(&answer)?;
        Ok(Step::Stay)
    })
}
