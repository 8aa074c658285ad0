//! The device as its own process behind a serial port: `device-core`'s board (the bootloader,
//! the application and the watchdog, the same state machine the Cortex-M4F firmware runs)
//! serving frames from a [`Wire`]. Nothing in the tick path allocates.
//!
//! ```text
//! boot ─► bootloader ── a Teach or Tick with a blob committed ─► application
//!            ▲                                                       │
//!            └──────────────── a BlobBegin (re-flash) ◄──────────────┘
//! ```

use std::path::PathBuf;
use std::time::{Duration, Instant};

use device_core::Port;

use super::wire::Wire;
use crate::device::{DeviceConfig, DeviceError};
use crate::link::{LinkError, MAX_FRAME, Refusal};

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
    /// A context was taught (z fixed) from this many transitions.
    Taught(u32),
    /// The host was silent past the watchdog: the safe action is held.
    Watchdog(Duration),
    /// Ticks came back after a watchdog trip.
    Resumed(u32),
    /// A host's `Hello` was answered (a bring-up begins: the upload, if any, comes next).
    Greeted,
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

impl From<device_core::BoardError<LinkError>> for BoardError {
    fn from(e: device_core::BoardError<LinkError>) -> Self {
        match e {
            device_core::BoardError::Port(e) => Self::Link(e),
            device_core::BoardError::Device(e) => Self::Device(e),
            device_core::BoardError::Frame(e) => Self::Link(e.into()),
            _ => Self::Link(LinkError::FrameTooLarge),
        }
    }
}

/// The board's port: a [`Wire`] and this process's clock.
struct WirePort<'w> {
    wire: &'w mut Wire,
    boot: Instant,
    stop: &'w dyn Fn() -> bool,
}

impl Port for WirePort<'_> {
    type Error = LinkError;

    fn receive(
        &mut self,
        frame: &mut [u8; MAX_FRAME],
        wait: Duration,
    ) -> Result<Option<usize>, LinkError> {
        Ok(self.wire.receive(Instant::now() + wait)?.map(|got| {
            frame[..got.len()].copy_from_slice(got);
            got.len()
        }))
    }

    fn send(&mut self, frame: &[u8]) -> Result<(), LinkError> {
        self.wire.send(frame)
    }

    fn now(&self) -> Duration {
        self.boot.elapsed()
    }

    fn stop(&self) -> bool {
        (self.stop)()
    }
}

/// Runs the board on `wire` until `stop` says so (a process runs until it is killed).
pub fn serve(
    wire: &mut Wire,
    config: &BoardConfig,
    stop: &dyn Fn() -> bool,
    on: &mut dyn FnMut(BoardEvent),
) -> Result<(), BoardError> {
    let mut device = crate::device::erased(config.device);
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
    let core_config = device_core::BoardConfig {
        device: config.device,
        watchdog: config.watchdog,
    };
    let mut port = WirePort {
        wire,
        boot: Instant::now(),
        stop,
    };
    device_core::serve(&mut port, &mut device, &core_config, &mut |e| match e {
        device_core::BoardEvent::Booted(id) => on(BoardEvent::Booted(id)),
        device_core::BoardEvent::Committed { blob, crc } => {
            on(BoardEvent::Committed(blob.len(), crc));
            // The flash file stands for the board's flash: a committed blob survives a restart.
            if let Some(path) = &config.flash_file
                && let Err(e) = crate::files::write_atomic(path, blob)
            {
                on(BoardEvent::Flash(e.to_string()));
            }
        }
        device_core::BoardEvent::Refused(reason) => on(BoardEvent::Refused(reason)),
        device_core::BoardEvent::Taught { transitions, .. } => on(BoardEvent::Taught(transitions)),
        device_core::BoardEvent::Watchdog(silent) => on(BoardEvent::Watchdog(silent)),
        device_core::BoardEvent::Resumed(tick) => on(BoardEvent::Resumed(tick)),
        device_core::BoardEvent::Greeted => on(BoardEvent::Greeted),
        _ => {}
    })?;
    Ok(())
}
