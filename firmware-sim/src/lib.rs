//! A simulated microcontroller that runs an `infer-core` policy blob in a fixed-rate control
//! loop against a Rapier plant.
//!
//! The data path is the one a real device has: the host sends the blob to the
//! [`Device`]'s bootloader over a lossy serial [`link`] (postcard messages, CRC-32, COBS
//! framing, stop-and-wait retries) into a flash region; the application ([`Controller`])
//! parses the blob in place, streams a context demo into the encoder one transition at a time
//! ([`host::teach`]), fixes `z`, and then [`control::run`] ticks at the control rate: sensors
//! (noise, ADC quantisation) -> `act` -> actuators (saturation, optional one-tick latency),
//! with a compute budget and a fault counter. With position-only sensing
//! ([`Sensing::Positions`]) the sensors deliver positions only and infer-core's estimator
//! rebuilds the velocities on the device ([`estimation`]). Nothing in the control path allocates.
//!
//! The same device runs as its own process behind a real serial port ([`serial`]:
//! `firmware-sim device`), with the plant on the host driving it in real time
//! (`firmware-sim host`): the loop is the same ([`control::Brain`] is either the controller in
//! this process or [`serial::RemoteDevice`]), the wire protocol is `docs/PROTOCOL.md`.
//!
//! The device's logic itself (the link's device side, the bootloader, the controller, the
//! board's state machine and its watchdog) is `device-core`'s, the no_std crate the Cortex-M4F
//! firmware (`firmware/`) runs too: this crate gives it a flash region on the heap, an OS serial
//! port and a clock.
//!
//! This crate never depends on the trainer: a device holds no trainer.
#![warn(missing_docs)]

mod config;
pub mod control;
mod device;
pub mod estimation;
mod files;
pub mod host;
pub mod link;
pub mod reference;
pub mod serial;
pub mod session;
pub mod trace;

pub use control::{Brain, LoopConfig, LoopError, Outcome, RunReport, TickRecord, run};
pub use device::{
    CAPACITY, Controller, Device, DeviceConfig, DeviceError, check_fits, erased, ram_needed,
};
pub use estimation::Sensing;
pub use files::write_atomic;
pub use session::{Session, SessionConfig, SessionError, run_session};
