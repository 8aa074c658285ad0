//! The wire protocol's device side (`docs/PROTOCOL.md`): the messages, their frames (postcard,
//! CRC-32, COBS, a zero delimiter), a byte-at-a-time frame reader for a UART, and the duplicate
//! filter. Fixed buffers only.

use heapless::Vec as HVec;
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
    /// Which latent did the teach fix? Answered with [`DeviceMessage::Latent`] once a context
    /// is taught (`Refused(NotReady)` before): the host checks the device's `z` against its
    /// own, bit for bit.
    Latent,
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
    /// The answer to [`HostMessage::Latent`].
    Latent {
        /// Sequence number answered.
        seq: u16,
        /// The latent the last teach fixed.
        z: Floats,
    },
}

impl DeviceMessage {
    /// The sequence number this answers.
    pub fn seq(&self) -> u16 {
        match self {
            Self::Ack { seq }
            | Self::Refused { seq, .. }
            | Self::Status { seq, .. }
            | Self::Action { seq, .. }
            | Self::Latent { seq, .. } => *seq,
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

/// Why a frame could not be made or read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameError {
    /// A message does not fit one frame.
    TooLarge,
    /// COBS decoding failed: bytes were lost or damaged.
    Cobs,
    /// The frame's CRC-32 does not match.
    Checksum,
    /// The frame's content is not a valid message (or has trailing bytes).
    Decode,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::TooLarge => "message too large for one 400-byte frame",
            Self::Cobs => "frame damaged (COBS)",
            Self::Checksum => "frame checksum mismatch",
            Self::Decode => "frame does not decode as a message",
        })
    }
}

impl core::error::Error for FrameError {}

/// Serialises `value`, appends its CRC-32 and COBS-encodes it into `out` with a trailing
/// zero delimiter; returns the frame length.
pub fn encode_frame<T: Serialize>(value: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_FRAME];
    let n = postcard::to_slice(value, &mut raw[..MAX_FRAME - 8])
        .map_err(|_| FrameError::TooLarge)?
        .len();
    let crc = infer_core::crc32(&raw[..n]);
    raw[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    let m = cobs::try_encode(&raw[..n + 4], out).map_err(|_| FrameError::TooLarge)?;
    *out.get_mut(m).ok_or(FrameError::TooLarge)? = 0;
    Ok(m + 1)
}

/// Undoes [`encode_frame`] into `scratch`; returns the verified message bytes.
pub fn decode_frame<'s>(frame: &[u8], scratch: &'s mut [u8]) -> Result<&'s [u8], FrameError> {
    let body = frame.strip_suffix(&[0]).unwrap_or(frame);
    let n = cobs::decode(body, scratch).map_err(|_| FrameError::Cobs)?;
    if n < 4 {
        return Err(FrameError::Checksum);
    }
    let (payload, crc) = scratch[..n].split_at(n - 4);
    if infer_core::crc32(payload).to_le_bytes() != crc {
        return Err(FrameError::Checksum);
    }
    Ok(payload)
}

/// Decodes a whole message from verified bytes, refusing trailing bytes.
pub fn decode_message<'a, T: Deserialize<'a>>(payload: &'a [u8]) -> Result<T, FrameError> {
    match postcard::take_from_bytes(payload) {
        Ok((value, [])) => Ok(value),
        _ => Err(FrameError::Decode),
    }
}

/// Assembles frames from a byte stream, one byte at a time (a UART's receive register): a
/// frame ends at a zero byte; a run of [`MAX_FRAME`] bytes without one is line noise and is
/// discarded up to the next zero.
#[derive(Debug, Clone)]
pub struct FrameReader {
    frame: [u8; MAX_FRAME],
    len: usize,
    skipping: bool,
    /// Runs of bytes longer than a frame with no delimiter, discarded.
    pub overflows: u64,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self {
            frame: [0; MAX_FRAME],
            len: 0,
            skipping: false,
            overflows: 0,
        }
    }
}

impl FrameReader {
    /// Adds one byte; returns the completed frame (delimiter included) when it ended one.
    pub fn push(&mut self, byte: u8) -> Option<&mut [u8]> {
        if byte == 0 {
            let complete = !self.skipping && self.len > 0;
            self.skipping = false;
            let len = core::mem::take(&mut self.len);
            if complete {
                self.frame[len] = 0;
                return Some(&mut self.frame[..len + 1]);
            }
            return None;
        }
        if self.skipping {
            return None;
        }
        if self.len + 1 >= MAX_FRAME {
            // No delimiter where one must be: line noise; wait for the next delimiter.
            self.overflows += 1;
            self.skipping = true;
            self.len = 0;
            return None;
        }
        self.frame[self.len] = byte;
        self.len += 1;
        None
    }

    /// Forgets a partly received frame (after a reconnect).
    pub fn clear(&mut self) {
        self.len = 0;
        self.skipping = false;
    }
}

/// Device-side duplicate filter: a resent message (its answer was lost) is answered again
/// with the same answer but not applied twice.
#[derive(Debug, Clone, Default)]
pub struct Dedup {
    last: Option<(u16, DeviceMessage)>,
}

impl Dedup {
    /// The earlier answer if `seq` was the last message handled.
    pub fn seen(&self, seq: u16) -> Option<DeviceMessage> {
        self.last
            .as_ref()
            .filter(|(s, _)| *s == seq)
            .map(|(_, m)| m.clone())
    }

    /// Whether `seq` was the last message handled (a resend), without copying its answer.
    pub fn is_resend(&self, seq: u16) -> bool {
        matches!(&self.last, Some((s, _)) if *s == seq)
    }

    /// Records `answer` as the answer to `seq` and returns it.
    pub fn record(&mut self, seq: u16, answer: DeviceMessage) -> DeviceMessage {
        self.last = Some((seq, answer.clone()));
        answer
    }

    /// Answers `seq`: the recorded answer if it is a resend, else `apply`'s (`Ok(None)`: an
    /// acknowledgement), recorded.
    pub fn answer(
        &mut self,
        seq: u16,
        apply: impl FnOnce() -> Result<Option<DeviceMessage>, Refusal>,
    ) -> DeviceMessage {
        if let Some(answer) = self.seen(seq) {
            return answer;
        }
        let answer = match apply() {
            Ok(None) => DeviceMessage::Ack { seq },
            Ok(Some(answer)) => answer,
            Err(reason) => DeviceMessage::Refused { seq, reason },
        };
        self.record(seq, answer)
    }
}

/// Something that answers frames in process: the device's bootloader or its application.
pub trait Endpoint {
    /// Handles one received frame; writes a reply frame into `reply` and returns its length,
    /// or `None` when the frame was unreadable (the host then times out and resends).
    fn receive(&mut self, frame: &[u8], reply: &mut [u8]) -> Option<usize>;
}

/// Device-side frame handling: verify, decode, deduplicate, apply, answer. `apply` returns
/// the message's answer (`None`: a plain acknowledgement).
pub fn answer_frame(
    frame: &[u8],
    reply: &mut [u8],
    dedup: &mut Dedup,
    apply: impl FnOnce(&HostMessage<'_>) -> Result<Option<DeviceMessage>, Refusal>,
) -> Option<usize> {
    let mut scratch = [0u8; MAX_FRAME];
    let payload = decode_frame(frame, &mut scratch).ok()?;
    let packet: Packet<HostMessage<'_>> = decode_message(payload).ok()?;
    let answer = dedup.answer(packet.seq, || apply(&packet.message));
    encode_frame(&answer, reply).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reader_finds_frames_and_skips_line_noise() {
        let mut reader = FrameReader::default();
        let mut frame = [0u8; MAX_FRAME];
        let n = encode_frame(
            &Packet {
                seq: 1,
                message: HostMessage::Latent,
            },
            &mut frame,
        )
        .unwrap();
        // Noise longer than a frame with no delimiter, its delimiter, then a frame.
        let mut got = None;
        for &b in core::iter::repeat_n(&7u8, MAX_FRAME + 5)
            .chain(&[0])
            .chain(&frame[..n])
        {
            if let Some(f) = reader.push(b) {
                assert!(got.is_none(), "one frame only");
                got = Some(f.len());
            }
        }
        assert_eq!(reader.overflows, 1);
        assert_eq!(got, Some(n));
        let mut scratch = [0u8; MAX_FRAME];
        let payload = decode_frame(&frame[..n], &mut scratch).unwrap();
        let p: Packet<HostMessage<'_>> = decode_message(payload).unwrap();
        assert_eq!(p.message, HostMessage::Latent);
    }

    #[test]
    fn a_resend_gets_the_recorded_answer_without_applying_twice() {
        let mut dedup = Dedup::default();
        let mut applied = 0;
        for _ in 0..3 {
            let answer = dedup.answer(9, || {
                applied += 1;
                Err(Refusal::NotReady)
            });
            assert_eq!(
                answer,
                DeviceMessage::Refused {
                    seq: 9,
                    reason: Refusal::NotReady
                }
            );
        }
        assert_eq!(applied, 1);
        assert_eq!(
            dedup.answer(10, || Ok(None)),
            DeviceMessage::Ack { seq: 10 }
        );
    }
}
