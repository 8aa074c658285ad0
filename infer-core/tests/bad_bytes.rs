//! Any byte string given to `Model::from_bytes` returns an error or a valid model, never a
//! panic: random bytes, and valid blobs flipped, truncated, extended, or corrupted behind a
//! re-computed checksum (so the decoder and validator, not just the CRC, see the damage).

mod common;

use infer_core::{ContextEncoder, Error, Model, ModelKind, Policy, Quant, write_blob};
use infer_core::{ENVELOPE_LEN, crc32};
use proptest::prelude::*;

fn blob(quant: Quant) -> Vec<u8> {
    let float = common::model(ModelKind::StateAction, 16, 5);
    let calib = common::calibration(&mut common::Rng(3), &float);
    write_blob(&float, quant, &calib).unwrap()
}

/// If a damaged blob still loads, it must also run without panicking.
fn exercise(bytes: &[u8]) {
    let Ok(model) = Model::from_bytes(bytes) else {
        return;
    };
    let h = *model.header();
    let (Ok(mut enc), Ok(mut policy)) = (
        ContextEncoder::<256>::new(&model),
        Policy::<256>::new(&model),
    ) else {
        return;
    };
    let obs = vec![0.5f32; h.obs_dim as usize];
    let act = vec![0.1f32; h.act_dim as usize];
    let _ = enc.push(&obs, &act, &obs);
    let mut z = vec![0.0f32; h.z_dim as usize];
    let _ = enc.latent(&mut z);
    let mut action = vec![0.0f32; h.act_dim as usize];
    let _ = policy.act(&obs, &z, &mut action);
    assert!(
        action.iter().all(|a| a.is_finite()),
        "a loaded blob produced a non-finite action"
    );
}

fn refresh_checksum(bytes: &mut [u8]) {
    if bytes.len() >= ENVELOPE_LEN {
        let len = (bytes.len() - ENVELOPE_LEN) as u32;
        bytes[6..10].copy_from_slice(&len.to_le_bytes());
        let crc = crc32(&bytes[ENVELOPE_LEN..]);
        bytes[10..14].copy_from_slice(&crc.to_le_bytes());
    }
}

fn quant() -> impl Strategy<Value = Quant> {
    prop_oneof![Just(Quant::F32), Just(Quant::W8A32), Just(Quant::W8A8)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        exercise(&bytes);
    }

    #[test]
    fn random_payload_behind_a_valid_envelope_never_panics(payload in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let mut bytes = b"SMLB\x01\x00".to_vec();
        bytes.extend_from_slice(&[0; 8]);
        bytes.extend_from_slice(&payload);
        refresh_checksum(&mut bytes);
        exercise(&bytes);
    }

    #[test]
    fn flipped_bytes_are_detected(q in quant(), at in any::<prop::sample::Index>(), mask in 1u8..=255) {
        let mut bytes = blob(q);
        let i = at.index(bytes.len());
        bytes[i] ^= mask;
        prop_assert!(Model::from_bytes(&bytes).is_err(), "flip at {} went unnoticed", i);
    }

    #[test]
    fn flips_behind_a_recomputed_checksum_never_panic(q in quant(), at in any::<prop::sample::Index>(), mask in 1u8..=255) {
        let mut bytes = blob(q);
        let i = ENVELOPE_LEN + at.index(bytes.len() - ENVELOPE_LEN);
        bytes[i] ^= mask;
        refresh_checksum(&mut bytes);
        exercise(&bytes);
    }

    #[test]
    fn truncated_blobs_are_refused(q in quant(), at in any::<prop::sample::Index>()) {
        let bytes = blob(q);
        let cut = at.index(bytes.len());
        prop_assert!(Model::from_bytes(&bytes[..cut]).is_err());
        // Even with the envelope patched to match, a cut payload must not decode as valid.
        let mut patched = bytes[..cut].to_vec();
        refresh_checksum(&mut patched);
        exercise(&patched);
    }

    #[test]
    fn extended_blobs_are_refused(q in quant(), extra in proptest::collection::vec(any::<u8>(), 1..64)) {
        let mut bytes = blob(q);
        bytes.extend_from_slice(&extra);
        let is_length_mismatch = matches!(Model::from_bytes(&bytes), Err(Error::LengthMismatch { .. }));
        prop_assert!(is_length_mismatch);
        // With the envelope patched, postcard would silently ignore the tail: we must not.
        refresh_checksum(&mut bytes);
        prop_assert_eq!(Model::from_bytes(&bytes).err(), Some(Error::TrailingBytes));
    }
}

#[test]
fn each_envelope_error_is_named() {
    let good = blob(Quant::W8A8);
    assert!(Model::from_bytes(&good).is_ok());
    assert_eq!(
        Model::from_bytes(&good[..3]).err(),
        Some(Error::TooShort { len: 3 })
    );
    let mut bad = good.clone();
    bad[0] = b'X';
    assert_eq!(Model::from_bytes(&bad).err(), Some(Error::BadMagic));
    let mut bad = good.clone();
    bad[4] = 4;
    assert_eq!(
        Model::from_bytes(&bad).err(),
        Some(Error::UnsupportedVersion { found: 4 })
    );
    // A v1 blob (per-layer activation scales) is refused by name, with what to do.
    let mut old = good.clone();
    old[4] = 1;
    let e = Model::from_bytes(&old).unwrap_err();
    assert_eq!(e, Error::OutdatedVersion { found: 1 });
    assert!(e.to_string().contains("re-export"), "{e}");
    // The same for a real v1 blob, kept from the v1 golden vectors.
    let v1 = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/v1-w8a8.blob"
    ))
    .unwrap();
    assert_eq!(
        Model::from_bytes(&v1).err(),
        Some(Error::OutdatedVersion { found: 1 })
    );
    // And a real v2 blob (one quantization for every layer), kept from the v2 golden vectors:
    // its layer records lack the v3 per-layer quantization, so it is refused by version,
    // before its bytes are misread.
    let v2 = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/v2-w8a8.blob"
    ))
    .unwrap();
    assert_eq!(
        Model::from_bytes(&v2).err(),
        Some(Error::OutdatedVersion { found: 2 })
    );
    let mut bad = good.clone();
    let last = bad.len() - 1;
    bad[last] ^= 1;
    assert!(matches!(
        Model::from_bytes(&bad),
        Err(Error::ChecksumMismatch { .. })
    ));
    let msg = Model::from_bytes(&bad).unwrap_err().to_string();
    assert!(msg.contains("corrupt"), "{msg}");
}
