//! The bootloader ([`Device`]: a flash region a blob is written into, verified and committed)
//! and the application ([`Controller`]: teach the context encoder, fix `z`, act), in fixed-size
//! state.

use core::mem::size_of;

use infer_core::{ContextEncoder, Model, Policy};

use crate::wire::{
    Dedup, DeviceMessage, Endpoint, Floats, HostMessage, MAX_DIM, MAX_FRAME, Refusal, answer_frame,
};

/// Widest layer the firmware is compiled for (hidden 128 fits; 256 does not).
pub const CAPACITY: usize = 128;

/// Memory budgets of the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceConfig {
    /// Flash bytes available for the policy blob.
    pub flash_bytes: usize,
    /// RAM bytes available for the model descriptors, encoder state, scratch and buffers.
    pub ram_bytes: usize,
}

impl Default for DeviceConfig {
    fn default() -> Self {
        Self {
            flash_bytes: 64 * 1024,
            ram_bytes: 16 * 1024,
        }
    }
}

/// Why the device will not run.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum DeviceError {
    /// No complete, verified blob in flash.
    NoBlob,
    /// The blob failed validation.
    Blob(infer_core::Error),
    /// The blob is larger than the flash region.
    FlashBudget {
        /// The blob's bytes.
        needed: usize,
        /// The flash region's bytes.
        budget: usize,
    },
    /// The application needs more RAM than the budget.
    RamBudget {
        /// Bytes the application state needs.
        needed: usize,
        /// The configured budget.
        budget: usize,
    },
    /// A model dimension exceeds what a link message carries.
    DimTooLarge {
        /// The offending dimension.
        dim: usize,
    },
    /// Control was asked for before a context was taught.
    NotTaught,
}

impl core::fmt::Display for DeviceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NoBlob => {
                f.write_str("no verified blob in flash: a partial or corrupt blob is never run")
            }
            Self::Blob(e) => write!(f, "blob rejected: {e}"),
            Self::FlashBudget { needed, budget } => {
                write!(f, "the blob is {needed} B, the flash region {budget} B")
            }
            Self::RamBudget { needed, budget } => {
                write!(f, "model needs {needed} B of RAM, budget is {budget} B")
            }
            Self::DimTooLarge { dim } => {
                write!(f, "model dimension {dim} exceeds the link's {MAX_DIM}")
            }
            Self::NotTaught => f.write_str("no context taught yet: teach a demo before running"),
        }
    }
}

impl core::error::Error for DeviceError {}

impl From<infer_core::Error> for DeviceError {
    fn from(e: infer_core::Error) -> Self {
        Self::Blob(e)
    }
}

/// The device's flash region and its bootloader state. `F` is the region: a boxed slice in a
/// PC process, a `&'static mut [u8]` in a linker section on a board.
#[derive(Debug)]
pub struct Device<F> {
    config: DeviceConfig,
    flash: F,
    announced: Option<(usize, u32)>,
    received: usize,
    committed: Option<(usize, u32)>,
    dedup: Dedup,
}

impl<F: AsRef<[u8]> + AsMut<[u8]>> Device<F> {
    /// A device over the flash region `flash` (its length is the flash budget; `config`'s
    /// `flash_bytes` is set from it), nothing committed.
    pub fn new(flash: F, config: DeviceConfig) -> Self {
        let config = DeviceConfig {
            flash_bytes: flash.as_ref().len(),
            ..config
        };
        Self {
            config,
            flash,
            announced: None,
            received: 0,
            committed: None,
            dedup: Dedup::default(),
        }
    }

    /// The budgets.
    pub fn config(&self) -> DeviceConfig {
        self.config
    }

    /// The committed blob, if a complete and verified one is in flash.
    pub fn blob(&self) -> Result<&[u8], DeviceError> {
        self.committed
            .map(|(len, _)| &self.flash.as_ref()[..len])
            .ok_or(DeviceError::NoBlob)
    }

    /// The committed blob's length and CRC-32.
    pub fn blob_id(&self) -> Option<(usize, u32)> {
        self.committed
    }

    /// Boots with `blob` already in flash (a board's flash survives a reset): committed only
    /// if it verifies and fits as an upload would.
    pub fn restore(&mut self, blob: &[u8]) -> Result<(), DeviceError> {
        let budget = self.flash.as_ref().len();
        if blob.len() > budget {
            return Err(DeviceError::FlashBudget {
                needed: blob.len(),
                budget,
            });
        }
        let model = Model::from_bytes(blob)?;
        check_fits(&model, self.config)?;
        self.flash.as_mut()[..blob.len()].copy_from_slice(blob);
        self.committed = Some((blob.len(), infer_core::crc32(blob)));
        Ok(())
    }

    /// The bootloader's handling of one message.
    pub fn apply(&mut self, message: &HostMessage<'_>) -> Result<(), Refusal> {
        match *message {
            HostMessage::BlobBegin { len, crc } => {
                let len = len as usize;
                if len > self.flash.as_ref().len() {
                    return Err(Refusal::BlobTooLarge);
                }
                // Erase first: from here on the old blob is gone and nothing runs until the
                // new one is complete and verified.
                self.committed = None;
                self.announced = Some((len, crc));
                self.received = 0;
                Ok(())
            }
            HostMessage::BlobChunk { offset, data } => {
                let (len, _) = self.announced.ok_or(Refusal::NotReady)?;
                if offset as usize != self.received || self.received + data.len() > len {
                    return Err(Refusal::OutOfOrder);
                }
                self.flash.as_mut()[self.received..self.received + data.len()]
                    .copy_from_slice(data);
                self.received += data.len();
                Ok(())
            }
            HostMessage::BlobEnd => {
                let (len, crc) = self.announced.take().ok_or(Refusal::NotReady)?;
                let blob = &self.flash.as_ref()[..self.received];
                if self.received != len || infer_core::crc32(blob) != crc {
                    return Err(Refusal::BadBlob);
                }
                let model = Model::from_bytes(blob).map_err(|_| Refusal::BadBlob)?;
                // A blob the application could not run is never committed.
                check_fits(&model, self.config).map_err(|_| Refusal::DoesNotFit)?;
                self.committed = Some((len, crc));
                Ok(())
            }
            _ => Err(Refusal::NotReady),
        }
    }
}

impl<F: AsRef<[u8]> + AsMut<[u8]>> Endpoint for Device<F> {
    fn receive(&mut self, frame: &[u8], reply: &mut [u8]) -> Option<usize> {
        let mut dedup = core::mem::take(&mut self.dedup);
        let n = answer_frame(frame, reply, &mut dedup, |m| self.apply(m).map(|()| None));
        self.dedup = dedup;
        n
    }
}

/// RAM the application needs while running: the controller (encoder state, scratch, z,
/// buffers), the parsed model descriptors and the link's receive buffers.
pub fn ram_needed() -> usize {
    size_of::<Controller<'static, 'static>>() + size_of::<Model<'static>>() + 2 * MAX_FRAME
}

/// Whether the application can run `model` on a device with `config`: every dimension a link
/// message carries, the RAM budget, and layer widths within [`CAPACITY`]. The bootloader
/// refuses a blob that fails this ([`Refusal::DoesNotFit`]) and [`Controller::new`] checks
/// the same, so the host can name the reason of a refusal.
pub fn check_fits(model: &Model<'_>, config: DeviceConfig) -> Result<(), DeviceError> {
    let h = model.header();
    for dim in [h.obs_dim, h.act_dim, h.z_dim] {
        if dim as usize > MAX_DIM {
            return Err(DeviceError::DimTooLarge { dim: dim as usize });
        }
    }
    let needed = ram_needed();
    if needed > config.ram_bytes {
        return Err(DeviceError::RamBudget {
            needed,
            budget: config.ram_bytes,
        });
    }
    ContextEncoder::<CAPACITY>::new(model)?;
    Policy::<CAPACITY>::new(model)?;
    Ok(())
}

/// The application: teaches the context encoder from link messages and runs the policy.
#[derive(Debug)]
pub struct Controller<'m, 'a> {
    model: &'m Model<'a>,
    encoder: ContextEncoder<'m, 'a, CAPACITY>,
    policy: Policy<'m, 'a, CAPACITY>,
    z: [f32; MAX_DIM],
    taught: bool,
    dedup: Dedup,
}

impl<'m, 'a> Controller<'m, 'a> {
    /// Checks that `model` fits the device and builds the application state.
    pub fn new(model: &'m Model<'a>, config: DeviceConfig) -> Result<Self, DeviceError> {
        check_fits(model, config)?;
        Ok(Self {
            model,
            encoder: ContextEncoder::new(model)?,
            policy: Policy::new(model)?,
            z: [0.0; MAX_DIM],
            taught: false,
            dedup: Dedup::default(),
        })
    }

    /// The latent fixed by the last completed teach phase.
    pub fn z(&self) -> Option<&[f32]> {
        self.taught
            .then(|| &self.z[..self.model.header().z_dim as usize])
    }

    /// One control step: action for the sensed observation. On a non-finite observation the
    /// safe action is written and the error returned (counted as a fault by the loop).
    pub fn act(
        &mut self,
        obs: &[f32],
        action: &mut [f32],
    ) -> Result<Result<(), infer_core::Error>, DeviceError> {
        if !self.taught {
            return Err(DeviceError::NotTaught);
        }
        let z_dim = self.model.header().z_dim as usize;
        Ok(self.policy.act(obs, &self.z[..z_dim], action))
    }

    /// The action sent when nothing better is known.
    pub fn safe_action(&self, action: &mut [f32]) {
        self.policy.safe_action(action);
    }

    /// The model's action dimension.
    pub fn act_dim(&self) -> usize {
        self.model.header().act_dim as usize
    }

    /// The answer to a `Latent` query: the taught `z`, or not ready.
    pub fn latent_answer(&self, seq: u16) -> Result<DeviceMessage, Refusal> {
        let z = self.z().ok_or(Refusal::NotReady)?;
        let z = Floats::from_slice(z).map_err(|_| Refusal::NotReady)?;
        Ok(DeviceMessage::Latent { seq, z })
    }

    /// The application's handling of one teaching message.
    pub fn apply(&mut self, message: &HostMessage<'_>) -> Result<(), Refusal> {
        match message {
            HostMessage::TeachBegin => {
                self.encoder.reset();
                Ok(())
            }
            HostMessage::Transition {
                obs,
                action,
                next_obs,
            } => self
                .encoder
                .push(obs, action, next_obs)
                .map_err(|_| Refusal::BadTransition),
            HostMessage::EndTrajectory => {
                self.encoder.end_trajectory();
                Ok(())
            }
            HostMessage::TeachEnd => {
                self.encoder.end_trajectory();
                let z_dim = self.model.header().z_dim as usize;
                self.encoder
                    .latent(&mut self.z[..z_dim])
                    .map_err(|_| Refusal::BadTransition)?;
                self.taught = true;
                Ok(())
            }
            _ => Err(Refusal::NotReady),
        }
    }
}

impl Endpoint for Controller<'_, '_> {
    fn receive(&mut self, frame: &[u8], reply: &mut [u8]) -> Option<usize> {
        let mut dedup = core::mem::take(&mut self.dedup);
        let n = answer_frame(frame, reply, &mut dedup, |m| self.apply(m).map(|()| None));
        self.dedup = dedup;
        n
    }
}
