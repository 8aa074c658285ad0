//! The device: `device-core`'s bootloader and application (one definition, run here and by
//! the Cortex-M4F firmware), with its flash region on the heap of this process.

pub use device_core::{CAPACITY, Controller, DeviceConfig, DeviceError, check_fits, ram_needed};

/// The simulated device: `device-core`'s bootloader over a flash region of this process.
pub type Device = device_core::Device<Box<[u8]>>;

/// A device with empty (erased) flash of `config.flash_bytes`.
pub fn erased(config: DeviceConfig) -> Device {
    Device::new(vec![0xFF; config.flash_bytes].into_boxed_slice(), config)
}
