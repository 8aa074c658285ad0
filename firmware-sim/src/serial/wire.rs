//! One end of a serial line: frames out and in over an OS serial device, paced at the baud
//! rate, with optional fault injection (the host's `--link-corrupt` / `--link-drop`).
//!
//! Fixed buffers only: the device's receive path allocates nothing.

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::link::{LinkError, MAX_FRAME};

/// Bits on the line per byte: 8N1 (a start bit, 8 data bits, a stop bit).
const BITS_PER_BYTE: u64 = 10;

/// How long `bytes` take on the line at `baud` (0: no pacing, an unlimited line).
pub fn line_time(bytes: usize, baud: u32) -> Duration {
    if baud == 0 {
        return Duration::ZERO;
    }
    Duration::from_nanos(bytes as u64 * BITS_PER_BYTE * 1_000_000_000 / u64::from(baud))
}

/// Faults injected on frames crossing this end, both directions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Faults {
    /// Probability that a frame arrives with one bit flipped.
    pub corrupt: f64,
    /// Probability that a frame is lost.
    pub drop: f64,
    /// Seed of the draws.
    pub seed: u64,
}

/// What crossed this end of the line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct WireStats {
    /// Frames written.
    pub frames_out: u64,
    /// Complete frames read.
    pub frames_in: u64,
    /// Bytes written.
    pub bytes_out: u64,
    /// Bytes read.
    pub bytes_in: u64,
    /// Frames this end corrupted on purpose (fault injection).
    pub injected_corrupt: u64,
    /// Frames this end dropped on purpose (fault injection).
    pub injected_drop: u64,
    /// Runs of bytes longer than a frame with no delimiter (line noise), discarded.
    pub overflows: u64,
}

/// One end of a serial line.
pub struct Wire {
    /// `None` once closed (before a reopen: the port is held exclusively, so the old handle
    /// must go before a new one can open it).
    port: Option<Box<dyn serialport::SerialPort>>,
    name: String,
    baud: u32,
    faults: Option<(Faults, ChaCha8Rng)>,
    rx: [u8; 256],
    rx_pos: usize,
    rx_end: usize,
    reader: device_core::FrameReader,
    frame: [u8; MAX_FRAME],
    /// Counters.
    pub stats: WireStats,
}

impl std::fmt::Debug for Wire {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Wire")
            .field("port", &self.name)
            .field("baud", &self.baud)
            .field("stats", &self.stats)
            .finish()
    }
}

/// The error of a closed port.
fn closed(name: &str) -> LinkError {
    port_error(name, "closed by this end (reopening)")
}

/// A port error, naming the port.
pub(crate) fn port_error(name: &str, reason: impl std::fmt::Display) -> LinkError {
    LinkError::Port {
        port: name.to_string(),
        reason: reason.to_string(),
    }
}

impl Wire {
    /// Opens the serial device at `path` in raw mode (8N1, no flow control) at `baud` (0: no
    /// pacing; a pseudo-terminal ignores the rate, so the pacing here is what makes it one).
    pub fn open(path: &str, baud: u32) -> Result<Self, LinkError> {
        let port = serialport::new(path, baud.max(1))
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(|e| port_error(path, e))?;
        Ok(Self::from_port(port, path, baud))
    }

    /// Wraps an open port (e.g. the master side of a pseudo-terminal pair).
    pub fn from_port(port: Box<dyn serialport::SerialPort>, name: &str, baud: u32) -> Self {
        Self {
            port: Some(port),
            name: name.to_string(),
            baud,
            faults: None,
            rx: [0; 256],
            rx_pos: 0,
            rx_end: 0,
            reader: device_core::FrameReader::default(),
            frame: [0; MAX_FRAME],
            stats: WireStats::default(),
        }
    }

    /// Injects `faults` on every frame from now on.
    pub fn with_faults(mut self, faults: Faults) -> Self {
        if faults.corrupt > 0.0 || faults.drop > 0.0 {
            self.faults = Some((faults, ChaCha8Rng::seed_from_u64(faults.seed)));
        }
        self
    }

    /// The port's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The line rate (0: unpaced).
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// Whether the next frame is dropped, and which bit of it flips (fault injection).
    fn fault(&mut self, len: usize) -> (bool, Option<(usize, u8)>) {
        let Some((f, rng)) = self.faults.as_mut() else {
            return (false, None);
        };
        if rng.random::<f64>() < f.drop {
            self.stats.injected_drop += 1;
            return (true, None);
        }
        if len > 1 && rng.random::<f64>() < f.corrupt {
            self.stats.injected_corrupt += 1;
            // Never the delimiter: a flipped payload byte is what a CRC is for.
            return (
                false,
                Some((rng.random_range(0..len - 1), rng.random_range(0..8))),
            );
        }
        (false, None)
    }

    /// Puts one frame on the line. On a paced line the frame becomes readable at the other
    /// end only after its last byte would have arrived (its line time is waited first), as a
    /// receiver on a real UART sees a frame complete only then.
    pub fn send(&mut self, frame: &[u8]) -> Result<(), LinkError> {
        let wait = line_time(frame.len(), self.baud);
        if !wait.is_zero() {
            std::thread::sleep(wait);
        }
        let (dropped, flip) = self.fault(frame.len());
        self.stats.frames_out += 1;
        self.stats.bytes_out += frame.len() as u64;
        if !dropped {
            let mut out = [0u8; MAX_FRAME];
            let out = &mut out[..frame.len()];
            out.copy_from_slice(frame);
            if let Some((i, bit)) = flip {
                out[i] ^= 1 << bit;
            }
            let port = self.port.as_mut().ok_or_else(|| closed(&self.name))?;
            port.write_all(out)
                .and_then(|()| port.flush())
                .map_err(|e| port_error(&self.name, e))?;
        }
        Ok(())
    }

    /// The next complete frame (its bytes, delimiter included) read before `until`, or `None`
    /// when none arrived in time. A frame that fault injection drops is read and discarded.
    pub fn receive(&mut self, until: Instant) -> Result<Option<&[u8]>, LinkError> {
        loop {
            while self.rx_pos < self.rx_end {
                let byte = self.rx[self.rx_pos];
                self.rx_pos += 1;
                let overflows = self.reader.overflows;
                let got = self.reader.push(byte).map(|f| {
                    self.frame[..f.len()].copy_from_slice(f);
                    f.len()
                });
                self.stats.overflows += self.reader.overflows - overflows;
                if let Some(len) = got {
                    self.stats.frames_in += 1;
                    match self.fault(len) {
                        (true, _) => continue,
                        (false, Some((i, bit))) => self.frame[i] ^= 1 << bit,
                        (false, None) => {}
                    }
                    return Ok(Some(&self.frame[..len]));
                }
            }
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            let wait = (until - now).min(Duration::from_millis(20));
            let port = self.port.as_mut().ok_or_else(|| closed(&self.name))?;
            port.set_timeout(wait.max(Duration::from_millis(1)))
                .map_err(|e| port_error(&self.name, e))?;
            match port.read(&mut self.rx) {
                Ok(0) => return Err(port_error(&self.name, "closed by the other end")),
                Ok(n) => {
                    self.rx_pos = 0;
                    self.rx_end = n;
                    self.stats.bytes_in += n as u64;
                }
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(port_error(&self.name, e)),
            }
        }
    }

    /// Closes the port (this end lets go of it; a reopen can then take it).
    pub fn close(&mut self) {
        self.port = None;
    }

    /// Discards whatever is waiting to be read (after a reconnect).
    pub fn clear(&mut self) {
        if let Some(port) = self.port.as_mut() {
            let _ = port.clear(serialport::ClearBuffer::All);
        }
        self.rx_pos = 0;
        self.rx_end = 0;
        self.reader.clear();
    }
}
