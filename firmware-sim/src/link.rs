//! The serial link between host and device: postcard messages, a CRC-32 per frame, COBS
//! framing (a zero byte ends every frame), and stop-and-wait retransmission.
//!
//! The device side (`decode_frame`, `encode_frame`) uses only fixed buffers; the host side
//! and the simulated wire ([`SimLink`]) may allocate.

use heapless::Vec as HVec;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Largest observation or action a transition message carries.
pub const MAX_DIM: usize = 64;
/// Blob bytes per chunk message.
pub const CHUNK_BYTES: usize = 192;
/// Largest encoded frame, COBS overhead and delimiter included.
pub const MAX_FRAME: usize = 400;
/// The wire protocol's version (`docs/PROTOCOL.md`): 1 was the in-process link (upload and
/// teach); 2 added `Hello`/`Status` and `Tick`/`Action` for a device on a serial port. A device
/// answers `Hello` with its own version and the host refuses a mismatch.
pub const PROTOCOL_VERSION: u16 = 2;

/// A vector of floats small enough for one frame.
pub type Floats = HVec<f32, MAX_DIM>;

/// What the host sends. Variants differ in size on purpose: messages live on the stack one
/// at a time, and boxing would put a heap into the device's receive path.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum HostMessage<'a> {
    /// A blob of `len` bytes with CRC-32 `crc` follows in chunks.
    BlobBegin {
        /// Total blob bytes.
        len: u32,
        /// CRC-32 of the whole blob.
        crc: u32,
    },
    /// Blob bytes at `offset`; chunks arrive in order.
    BlobChunk {
        /// Where these bytes go.
        offset: u32,
        /// The bytes.
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// All chunks sent: verify and commit the blob.
    BlobEnd,
    /// Forget the current context: a new demo follows.
    TeachBegin,
    /// One demo transition.
    Transition {
        /// State.
        obs: Floats,
        /// Expert action (ignored by state-only models).
        action: Floats,
        /// Next state.
        next_obs: Floats,
    },
    /// The current demo trajectory is complete.
    EndTrajectory,
    /// The context is complete: fix z.
    TeachEnd,
    /// Who are you and what do you hold? Answered with [`DeviceMessage::Status`] in any state
    /// (the host sends it first, and again after losing the device).
    Hello {
        /// The host's [`PROTOCOL_VERSION`].
        version: u16,
    },
    /// One control tick: the sensed observation; answered with [`DeviceMessage::Action`].
    Tick {
        /// Tick index (echoed in the answer, so a late answer is never taken for a newer one).
        tick: u32,
        /// The observation the sensors read.
        obs: Floats,
    },
}

/// Why the device refused a message (a corrupt frame is simply not answered).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Refusal {
    /// The blob does not fit the flash budget.
    BlobTooLarge,
    /// A chunk arrived out of order or beyond the announced length.
    OutOfOrder,
    /// The assembled blob fails its checksum or validation.
    BadBlob,
    /// A transition has wrong dimensions or non-finite values.
    BadTransition,
    /// The message does not fit the device's state (e.g. teaching before a blob).
    NotReady,
    /// The model needs more RAM than the budget or wider layers than compiled in.
    DoesNotFit,
}

/// What the device answers. Variants differ in size on purpose, as [`HostMessage`]'s: one
/// answer lives on the stack at a time, and boxing would put a heap into the device's reply path.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum DeviceMessage {
    /// Message `seq` applied (or already applied: duplicates are acknowledged, not re-applied).
    Ack {
        /// Sequence number acknowledged.
        seq: u16,
    },
    /// Message `seq` refused.
    Refused {
        /// Sequence number refused.
        seq: u16,
        /// Why.
        reason: Refusal,
    },
    /// The answer to [`HostMessage::Hello`].
    Status {
        /// Sequence number answered.
        seq: u16,
        /// The device's [`PROTOCOL_VERSION`].
        version: u16,
        /// Bytes of the committed blob in flash; 0: none.
        blob_len: u32,
        /// CRC-32 of the committed blob (0 without one): the host skips a re-upload of the
        /// same blob after a device reset.
        blob_crc: u32,
        /// Whether a context is taught (RAM: false after every reset).
        taught: bool,
        /// Times the watchdog found the host silent and held the safe action, since boot.
        watchdog_trips: u32,
    },
    /// The answer to [`HostMessage::Tick`].
    Action {
        /// Sequence number answered.
        seq: u16,
        /// The tick it answers.
        tick: u32,
        /// The action to apply.
        action: Floats,
        /// A non-finite reading or output was replaced by the safe action.
        fault: bool,
        /// The device's compute time for this tick, microseconds.
        compute_us: u32,
    },
}

impl DeviceMessage {
    /// The sequence number this answers.
    pub fn seq(&self) -> u16 {
        match self {
            Self::Ack { seq }
            | Self::Refused { seq, .. }
            | Self::Status { seq, .. }
            | Self::Action { seq, .. } => *seq,
        }
    }
}

/// A message with its sequence number, as framed on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Packet<M> {
    /// Sequence number (wraps).
    pub seq: u16,
    /// The message.
    pub message: M,
}

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

/// Serialises `value`, appends its CRC-32 and COBS-encodes it into `out` with a trailing
/// zero delimiter; returns the frame length.
pub fn encode_frame<T: Serialize>(value: &T, out: &mut [u8]) -> Result<usize, LinkError> {
    let mut raw = [0u8; MAX_FRAME];
    let n = postcard::to_slice(value, &mut raw[..MAX_FRAME - 8])
        .map_err(|_| LinkError::FrameTooLarge)?
        .len();
    let crc = infer_core::crc32(&raw[..n]);
    raw[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    let m = cobs::try_encode(&raw[..n + 4], out).map_err(|_| LinkError::FrameTooLarge)?;
    *out.get_mut(m).ok_or(LinkError::FrameTooLarge)? = 0;
    Ok(m + 1)
}

/// Undoes [`encode_frame`] into `scratch`; returns the verified message bytes.
pub fn decode_frame<'s>(frame: &[u8], scratch: &'s mut [u8]) -> Result<&'s [u8], LinkError> {
    let body = frame.strip_suffix(&[0]).unwrap_or(frame);
    let n = cobs::decode(body, scratch).map_err(|_| LinkError::Cobs)?;
    if n < 4 {
        return Err(LinkError::Checksum);
    }
    let (payload, crc) = scratch[..n].split_at(n - 4);
    if infer_core::crc32(payload).to_le_bytes() != crc {
        return Err(LinkError::Checksum);
    }
    Ok(payload)
}

/// Decodes a whole message from verified bytes, refusing trailing bytes.
pub fn decode_message<'a, T: Deserialize<'a>>(payload: &'a [u8]) -> Result<T, LinkError> {
    match postcard::take_from_bytes(payload) {
        Ok((value, [])) => Ok(value),
        _ => Err(LinkError::Decode),
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

/// Something that answers frames: the device's bootloader or its application.
pub trait Endpoint {
    /// Handles one received frame; writes a reply frame into `reply` and returns its length,
    /// or `None` when the frame was unreadable (the host then times out and resends).
    fn receive(&mut self, frame: &[u8], reply: &mut [u8]) -> Option<usize>;
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

/// Device-side duplicate filter: a resent message (its ack was lost) is acknowledged again
/// but not applied twice.
#[derive(Debug, Clone, Default)]
pub(crate) struct Dedup {
    last: Option<(u16, DeviceMessage)>,
}

impl Dedup {
    /// The earlier answer if `seq` was already handled.
    pub fn seen(&self, seq: u16) -> Option<DeviceMessage> {
        self.last
            .as_ref()
            .filter(|(s, _)| *s == seq)
            .map(|(_, m)| m.clone())
    }
    pub fn record(&mut self, seq: u16, answer: DeviceMessage) -> DeviceMessage {
        self.last = Some((seq, answer.clone()));
        answer
    }
}

/// Shared device-side frame handling: verify, decode, deduplicate, apply, answer. `apply`
/// gets the message's sequence number and returns its answer (`None`: a plain
/// acknowledgement).
pub(crate) fn serve(
    frame: &[u8],
    reply: &mut [u8],
    dedup: &mut Dedup,
    apply: impl FnOnce(u16, &HostMessage<'_>) -> Result<Option<DeviceMessage>, Refusal>,
) -> Option<usize> {
    let mut scratch = [0u8; MAX_FRAME];
    let payload = decode_frame(frame, &mut scratch).ok()?;
    let packet: Packet<HostMessage<'_>> = decode_message(payload).ok()?;
    let seq = packet.seq;
    let answer = match dedup.seen(seq) {
        Some(answer) => answer,
        None => {
            let answer = match apply(seq, &packet.message) {
                Ok(None) => DeviceMessage::Ack { seq },
                Ok(Some(answer)) => answer,
                Err(reason) => DeviceMessage::Refused { seq, reason },
            };
            dedup.record(seq, answer)
        }
    };
    encode_frame(&answer, reply).ok()
}

#[cfg(test)]
mod golden {
    //! The worked examples of `docs/PROTOCOL.md`, byte for byte: a board written from that page
    //! speaks to this code.
    use super::*;

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
