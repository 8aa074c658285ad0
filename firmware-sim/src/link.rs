//! The serial link between host and device: postcard messages, a CRC-32 per frame, COBS
//! framing (a zero byte ends every frame), and stop-and-wait retransmission.
//!
//! The messages and the device side of the framing are `device-core`'s (one definition, run
//! by this crate and by the firmware); the host side and the simulated wire ([`SimLink`]) may
//! allocate.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use device_core::{
    CHUNK_BYTES, DeviceMessage, Endpoint, Floats, FrameError, HostMessage, MAX_DIM, MAX_FRAME,
    PROTOCOL_VERSION, Packet, Refusal, decode_frame, decode_message, encode_frame,
};

/// Link-level failures.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinkError {
    /// A message does not fit one frame.
    #[error("message too large for one {MAX_FRAME}-byte frame")]
    FrameTooLarge,
    /// COBS decoding failed: bytes were lost or damaged.
    #[error("frame damaged (COBS)")]
    Cobs,
    /// The frame's CRC-32 does not match.
    #[error("frame checksum mismatch")]
    Checksum,
    /// The frame's content is not a valid message.
    #[error("frame does not decode as a message")]
    Decode,
    /// No acknowledgement after all retries.
    #[error("message {seq} not acknowledged after {attempts} attempts (link too lossy)")]
    RetriesExhausted {
        /// Sequence number.
        seq: u16,
        /// Attempts made.
        attempts: u32,
    },
    /// The serial port failed (closed, unplugged, the device process gone).
    #[error("serial port {port}: {reason}")]
    Port {
        /// The port's path.
        port: String,
        /// The OS's words.
        reason: String,
    },
    /// The device speaks another protocol version.
    #[error(
        "the device speaks protocol version {device}, this host {host}: flash a matching \
             firmware or use a matching firmware-sim"
    )]
    Version {
        /// The device's version.
        device: u16,
        /// Ours.
        host: u16,
    },
    /// The device answered with something the message does not call for.
    #[error("message {seq}: unexpected answer from the device")]
    Unexpected {
        /// Sequence number.
        seq: u16,
    },
    /// The device refused a message.
    #[error("device refused message {seq}: {reason:?}")]
    Refused {
        /// Sequence number.
        seq: u16,
        /// Why.
        reason: Refusal,
    },
}

impl From<FrameError> for LinkError {
    fn from(e: FrameError) -> Self {
        match e {
            FrameError::Cobs => Self::Cobs,
            FrameError::Checksum => Self::Checksum,
            FrameError::Decode => Self::Decode,
            _ => Self::FrameTooLarge,
        }
    }
}

/// Fault injection of the simulated wire.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkConfig {
    /// Probability that a frame arrives with one byte flipped.
    pub corrupt_probability: f64,
    /// Probability that a frame is lost.
    pub drop_probability: f64,
    /// Retransmissions per message before giving up.
    pub max_retries: u32,
    /// Seed of the fault draws.
    pub seed: u64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            corrupt_probability: 0.0,
            drop_probability: 0.0,
            max_retries: 8,
            seed: 0,
        }
    }
}

/// Counters of what happened on the wire.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames put on the wire (both directions).
    pub frames: u64,
    /// Frames damaged in transit.
    pub corrupted: u64,
    /// Frames lost in transit.
    pub dropped: u64,
    /// Retransmissions by the host.
    pub retries: u64,
    /// Payload bytes on the wire.
    pub bytes: u64,
}

/// The host end of a simulated, possibly lossy serial wire.
#[derive(Debug)]
pub struct SimLink {
    config: LinkConfig,
    rng: ChaCha8Rng,
    seq: u16,
    /// What happened so far.
    pub stats: LinkStats,
}

impl SimLink {
    /// A wire with the given faults.
    pub fn new(config: LinkConfig) -> Self {
        Self {
            config,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            seq: 0,
            stats: LinkStats::default(),
        }
    }

    /// Carries one frame across the wire: maybe dropped, maybe one byte flipped.
    fn carry(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        self.stats.frames += 1;
        self.stats.bytes += frame.len() as u64;
        if self.rng.random::<f64>() < self.config.drop_probability {
            self.stats.dropped += 1;
            return None;
        }
        let mut bytes = frame.to_vec();
        if self.rng.random::<f64>() < self.config.corrupt_probability {
            self.stats.corrupted += 1;
            let i = self.rng.random_range(0..bytes.len());
            bytes[i] ^= 1 << self.rng.random_range(0..8);
        }
        Some(bytes)
    }

    /// Sends one message and waits for its acknowledgement, resending on loss or damage.
    pub fn send(
        &mut self,
        device: &mut dyn Endpoint,
        message: &HostMessage<'_>,
    ) -> Result<(), LinkError> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let mut frame = [0u8; MAX_FRAME];
        let len = encode_frame(&Packet { seq, message }, &mut frame)?;
        let attempts = self.config.max_retries + 1;
        for attempt in 0..attempts {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            let Some(received) = self.carry(&frame[..len]) else {
                continue;
            };
            let mut reply = [0u8; MAX_FRAME];
            let Some(reply_len) = device.receive(&received, &mut reply) else {
                continue;
            };
            let Some(back) = self.carry(&reply[..reply_len]) else {
                continue;
            };
            let mut scratch = [0u8; MAX_FRAME];
            let Ok(payload) = decode_frame(&back, &mut scratch) else {
                continue;
            };
            match decode_message::<DeviceMessage>(payload) {
                Ok(DeviceMessage::Ack { seq: s }) if s == seq => return Ok(()),
                Ok(DeviceMessage::Refused { seq: s, reason }) if s == seq => {
                    return Err(LinkError::Refused { seq, reason });
                }
                _ => continue,
            }
        }
        Err(LinkError::RetriesExhausted { seq, attempts })
    }
}

#[cfg(test)]
mod golden {
    //! The worked examples of `docs/PROTOCOL.md`, byte for byte: a board written from that page
    //! speaks to this code.
    use super::*;
    use serde::Serialize;

    fn hex(bytes: &[u8]) -> String {
        bytes
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    fn frame<T: Serialize>(value: &T) -> String {
        let mut out = [0u8; MAX_FRAME];
        let n = encode_frame(value, &mut out).unwrap();
        hex(&out[..n])
    }

    fn floats(v: &[f32]) -> Floats {
        Floats::from_slice(v).unwrap()
    }

    #[test]
    fn the_protocol_pages_examples_are_these_bytes() {
        let hello = Packet {
            seq: 1,
            message: HostMessage::Hello { version: 2 },
        };
        assert_eq!(frame(&hello), "08 01 07 02 ce 44 cc 5f 00");
        let status = DeviceMessage::Status {
            seq: 1,
            version: 2,
            blob_len: 0,
            blob_crc: 0,
            taught: false,
            watchdog_trips: 0,
        };
        assert_eq!(frame(&status), "04 02 01 02 01 01 01 05 92 4e 6f bb 00");
        let tick = Packet {
            seq: 5,
            message: HostMessage::Tick {
                tick: 3,
                obs: floats(&[0.5, -1.0]),
            },
        };
        assert_eq!(
            frame(&tick),
            "05 05 08 03 02 01 01 02 3f 01 07 80 bf be da 58 df 00"
        );
        let action = DeviceMessage::Action {
            seq: 5,
            tick: 3,
            action: floats(&[0.25, 0.0]),
            fault: false,
            compute_us: 4,
        };
        assert_eq!(
            frame(&action),
            "05 03 05 03 02 01 03 80 3e 01 01 01 01 06 04 f2 1b 0d 33 00"
        );
        let page = include_str!("../../docs/PROTOCOL.md");
        for example in [
            "08 01 07 02 ce 44 cc 5f 00",
            "04 02 01 02 01 01 01 05 92 4e 6f bb 00",
            "05 05 08 03 02 01 01 02 3f 01 07 80 bf be da 58 df 00",
            "05 03 05 03 02 01 03 80 3e 01 01 01 01 06 04 f2 1b 0d 33 00",
        ] {
            assert!(page.contains(example), "docs/PROTOCOL.md lacks {example}");
        }
    }
}
