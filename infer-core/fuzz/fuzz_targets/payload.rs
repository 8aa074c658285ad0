//! The fuzz input is the *payload*: it gets a valid envelope (magic, version, length, CRC-32)
//! so that mutations reach the postcard decoder and the validator instead of dying at the
//! checksum, which is where `from_bytes` stops almost every random input.
#![no_main]

#[path = "exercise.rs"]
mod exercise;

use infer_core::{ENVELOPE_LEN, FORMAT_VERSION, MAGIC, crc32};

libfuzzer_sys::fuzz_target!(|payload: &[u8]| {
    let mut blob = Vec::with_capacity(ENVELOPE_LEN + payload.len());
    blob.extend_from_slice(&MAGIC);
    blob.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    blob.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    blob.extend_from_slice(&crc32(payload).to_le_bytes());
    blob.extend_from_slice(payload);
    exercise::exercise(&blob);
});
