//! The fuzz input is the *payload*: it gets a valid envelope (magic, version, length, CRC-32)
//! so that mutations reach the postcard decoder and the validator instead of dying at the
//! checksum, which is where `from_bytes` stops almost every random input.
#![no_main]

use infer_core::format::{ENVELOPE_LEN, FORMAT_VERSION, MAGIC, crc32};
use infer_core::{ContextEncoder, Model, Policy};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|payload: &[u8]| {
    let mut blob = Vec::with_capacity(ENVELOPE_LEN + payload.len());
    blob.extend_from_slice(&MAGIC);
    blob.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    blob.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    blob.extend_from_slice(&crc32(payload).to_le_bytes());
    blob.extend_from_slice(payload);
    let Ok(model) = Model::from_bytes(&blob) else { return };
    let h = *model.header();
    let (Ok(mut encoder), Ok(mut policy)) = (ContextEncoder::<256>::new(&model), Policy::<256>::new(&model)) else {
        return;
    };
    let obs = vec![0.25f32; h.obs_dim as usize];
    let act = vec![-0.5f32; h.act_dim as usize];
    let _ = encoder.push(&obs, &act, &obs);
    let mut z = vec![0.0f32; h.z_dim as usize];
    let _ = encoder.latent(&mut z);
    let mut action = vec![0.0f32; h.act_dim as usize];
    let _ = policy.act(&obs, &z, &mut action);
    assert!(action.iter().all(|a| a.is_finite()));
});
