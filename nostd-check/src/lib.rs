//! Links infer-core's public API into a `#![no_std]` staticlib with no allocator.
#![no_std]

use core::panic::PanicInfo;
use infer_core::{ContextEncoder, Model, Policy};

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
    let Ok(model) = Model::from_bytes(bytes) else { return 1 };
    let Ok(mut encoder) = ContextEncoder::<64>::new(&model) else { return 2 };
    let Ok(mut policy) = Policy::<64>::new(&model) else { return 3 };
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
