//! The input is a whole blob (most mutations stop at the CRC check; see `payload`).
#![no_main]

#[path = "exercise.rs"]
mod exercise;

libfuzzer_sys::fuzz_target!(|data: &[u8]| exercise::exercise(data));
