#![no_std]
#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod board;
mod device;
mod wire;

pub use board::{BoardConfig, BoardError, BoardEvent, Port, serve};
pub use device::{CAPACITY, Controller, Device, DeviceConfig, DeviceError, check_fits, ram_needed};
pub use wire::{
    CHUNK_BYTES, Dedup, DeviceMessage, Endpoint, Floats, FrameError, FrameReader, HostMessage,
    MAX_DIM, MAX_FRAME, PROTOCOL_VERSION, Packet, Refusal, answer_frame, decode_frame,
    decode_message, encode_frame,
};
