//! Links infer-core's public API into a `#![no_std]` staticlib with no allocator.
#![no_std]

use core::panic::PanicInfo;
use infer_core::{Channel, ContextEncoder, Estimator, EstimatorConfig, Model, Policy};

#[panic_handler]
fn panic(_: &PanicInfo<'_>) -> ! {
    loop {}
}

/// Loads a blob, teaches it one transition and computes one action; returns 0 on success.
///
/// # Safety
/// `blob` must point to `len` readable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn smile_check(blob: *const u8, len: usize, out: *mut f32) -> i32 {
    // SAFETY: the caller promises `len` readable bytes at `blob`.
    let bytes = unsafe { core::slice::from_raw_parts(blob, len) };
    let Ok(model) = Model::from_bytes(bytes) else {
        return 1;
    };
    let Ok(mut encoder) = ContextEncoder::<64>::new(&model) else {
        return 2;
    };
    let Ok(mut policy) = Policy::<64>::new(&model) else {
        return 3;
    };
    let obs = [0.0f32; 20];
    if encoder.push(&obs, &[0.0; 6], &obs).is_err() {
        return 4;
    }
    encoder.end_trajectory();
    let mut z = [0.0f32; 16];
    if encoder.latent(&mut z).is_err() {
        return 5;
    }
    let mut action = [0.0f32; 6];
    if policy.act(&obs, &z, &mut action).is_err() {
        return 6;
    }
    // SAFETY: the caller provides room for 6 floats.
    unsafe { core::ptr::copy_nonoverlapping(action.as_ptr(), out, 6) };
    0
}

/// Runs the position-only state estimator (nalgebra, fixed-size) over `n` position readings
/// of one axis sampled every `dt` seconds; writes the last (position, rate) estimate to
/// `out`. Returns 0 on success.
///
/// # Safety
/// `readings` must point to `n` readable floats and `out` to room for 2.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn smile_estimate(
    readings: *const f32,
    n: usize,
    dt: f32,
    out: *mut f32,
) -> i32 {
    // SAFETY: the caller promises `n` readable floats.
    let readings = unsafe { core::slice::from_raw_parts(readings, n) };
    let channels = [Channel::Position, Channel::Rate { of: 0, scale: 1.0 }];
    let config = EstimatorConfig {
        dt,
        accel_std: 1.0,
        meas_std: 0.01,
        limit: 10.0,
        initial_rate_std: 1.0,
    };
    let Ok(mut estimator) = Estimator::<4>::new(&channels, config) else {
        return 1;
    };
    let mut obs = [0.0f32; 2];
    for y in readings {
        if estimator.step(core::slice::from_ref(y), &mut obs).is_err() {
            return 2;
        }
    }
    // SAFETY: the caller provides room for 2 floats.
    unsafe { core::ptr::copy_nonoverlapping(obs.as_ptr(), out, 2) };
    0
}
