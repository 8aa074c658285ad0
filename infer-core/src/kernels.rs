//! Dense-layer kernels for the three quantization schemes.
//!
//! Bit-exactness by construction: every floating-point sum has a fixed association order
//! (eight interleaved partial sums combined pairwise), Rust never contracts `a * b + c` into
//! an FMA on its own, and the transcendental functions come from `libm`, so the same blob and
//! inputs give the same bits on every build for a given target.

use crate::format::{LayerRecord, Quant};
use crate::model::F32s;

/// Lanes of the fixed-order float reduction; 8 lets the compiler keep one AVX register.
const LANES: usize = 8;

#[inline]
fn reduce(acc: [f32; LANES]) -> f32 {
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
}

/// `sum_i w[i] * x[i]` with `f32` weights stored little-endian.
#[inline]
fn dot_f32(w: &[u8], x: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let (w4, _) = w.as_chunks::<4>();
    let (w_chunks, w_rest) = w4.as_chunks::<LANES>();
    let (x_chunks, x_rest) = x.as_chunks::<LANES>();
    for (wc, xc) in w_chunks.iter().zip(x_chunks) {
        let mut wf = [0.0f32; LANES];
        for k in 0..LANES {
            wf[k] = f32::from_le_bytes(wc[k]);
        }
        for k in 0..LANES {
            acc[k] += wf[k] * xc[k];
        }
    }
    for (k, (b, xv)) in w_rest.iter().zip(x_rest).enumerate() {
        acc[k] += f32::from_le_bytes(*b) * xv;
    }
    reduce(acc)
}

/// `sum_i w[i] * x[i]` with `i8` weights and `f32` inputs.
#[inline]
fn dot_i8_f32(w: &[u8], x: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let (w_chunks, w_rest) = w.as_chunks::<LANES>();
    let (x_chunks, x_rest) = x.as_chunks::<LANES>();
    for (wc, xc) in w_chunks.iter().zip(x_chunks) {
        let mut wf = [0.0f32; LANES];
        for k in 0..LANES {
            wf[k] = (wc[k] as i8) as f32;
        }
        for k in 0..LANES {
            acc[k] += wf[k] * xc[k];
        }
    }
    for (k, (&wv, xv)) in w_rest.iter().zip(x_rest).enumerate() {
        acc[k] += (wv as i8) as f32 * xv;
    }
    reduce(acc)
}

/// Integer lanes: 16 int8 products per step map onto one `pmaddwd`-style instruction pair.
const INT_LANES: usize = 16;

/// `sum_i w[i] * x[i]` in exact integer arithmetic (order-free, so it vectorises freely):
/// `i8` weights, inputs read as `i8` (`SIGNED`) or as unsigned 8-bit values. Every product
/// fits an `i16` (`|w x| <= 127 * 255`) before widening.
#[inline]
fn dot_i8<const SIGNED: bool>(w: &[u8], x: &[u8]) -> i32 {
    let input = |v: u8| if SIGNED { v as i8 as i16 } else { v as i16 };
    let mut acc = [0i32; INT_LANES];
    let (w_chunks, w_rest) = w.as_chunks::<INT_LANES>();
    let (x_chunks, x_rest) = x.as_chunks::<INT_LANES>();
    for (wc, xc) in w_chunks.iter().zip(x_chunks) {
        for k in 0..INT_LANES {
            acc[k] += (wc[k] as i8 as i16 * input(xc[k])) as i32;
        }
    }
    let tail: i32 = w_rest
        .iter()
        .zip(x_rest)
        .map(|(&wv, &xv)| (wv as i8) as i32 * input(xv) as i32)
        .sum();
    acc.iter().sum::<i32>() + tail
}

/// [`dot_i8`] with `i8` inputs stored as their bytes.
#[inline]
fn dot_i8_i8(w: &[u8], x: &[u8]) -> i32 {
    dot_i8::<true>(w, x)
}

/// [`dot_i8`] with unsigned 8-bit inputs.
#[inline]
fn dot_i8_u8(w: &[u8], x: &[u8]) -> i32 {
    dot_i8::<false>(w, x)
}

/// Unsigned 8-bit quantization of one non-negative activation: `x / scale` clamped to
/// `0..=255` and rounded half up (a negative input, impossible after a ReLU, becomes 0).
#[inline]
pub(crate) fn quantize_u8(x: f32, scale: f32) -> u8 {
    ((x / scale).clamp(0.0, 255.0) + 0.5) as u8
}

/// Symmetric int8 quantization of one activation: `x / scale` clamped to +-127 and rounded
/// half away from zero (the cast truncates toward zero; clamping first keeps it in range).
#[inline]
pub(crate) fn quantize(x: f32, scale: f32) -> i8 {
    let v = (x / scale).clamp(-127.0, 127.0);
    (v + 0.5f32.copysign(v)) as i8
}

/// One dense layer: `y = act(W x + b)`. `x` has `in_dim` values, `y` gets `out_dim`;
/// `q` is scratch for the quantized input (W8A8 only). Shapes were validated at load time.
pub(crate) fn dense(layer: &LayerRecord<'_>, x: &[f32], y: &mut [f32], q: &mut [u8]) {
    let (n_in, n_out) = (layer.in_dim as usize, layer.out_dim as usize);
    let x = &x[..n_in];
    let bias = F32s(layer.bias.0);
    let w = layer.weights.0;
    match layer.quant {
        Quant::F32 => {
            for (o, y_o) in y[..n_out].iter_mut().enumerate() {
                let row = &w[4 * o * n_in..4 * (o + 1) * n_in];
                *y_o = layer.activation.apply(dot_f32(row, x) + bias.get(o));
            }
        }
        Quant::W8A32 => {
            let scale = F32s(layer.weight_scale.0);
            for (o, y_o) in y[..n_out].iter_mut().enumerate() {
                let row = &w[o * n_in..(o + 1) * n_in];
                *y_o = layer
                    .activation
                    .apply(dot_i8_f32(row, x) * scale.get(o) + bias.get(o));
            }
        }
        Quant::W8A8 => {
            // One scale per input channel, or one for the whole input (a single value).
            let s_in = F32s(layer.input_scale.0);
            let per_channel = s_in.len() > 1;
            let scale_of = |i: usize| s_in.get(if per_channel { i } else { 0 });
            let q = &mut q[..n_in];
            if layer.unsigned_input {
                for (i, (qv, &xv)) in q.iter_mut().zip(x).enumerate() {
                    *qv = quantize_u8(xv, scale_of(i));
                }
            } else {
                for (i, (qv, &xv)) in q.iter_mut().zip(x).enumerate() {
                    *qv = quantize(xv, scale_of(i)) as u8;
                }
            }
            let scale = F32s(layer.weight_scale.0);
            for (o, y_o) in y[..n_out].iter_mut().enumerate() {
                let row = &w[o * n_in..(o + 1) * n_in];
                let acc = if layer.unsigned_input {
                    dot_i8_u8(row, q)
                } else {
                    dot_i8_i8(row, q)
                };
                *y_o = layer
                    .activation
                    .apply(acc as f32 * scale.get(o) + bias.get(o));
            }
        }
    }
}

/// Runs a whole MLP. The input is in `a[..in_dim]`; returns which buffer holds the output
/// (`false`: `a`, `true`: `b`) so callers avoid a copy.
pub(crate) fn mlp(layers: &[LayerRecord<'_>], a: &mut [f32], b: &mut [f32], q: &mut [u8]) -> bool {
    let mut in_b = false;
    for layer in layers {
        if in_b {
            dense(layer, b, a, q);
        } else {
            dense(layer, a, b, q);
        }
        in_b = !in_b;
    }
    in_b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsigned_quantization_rounds_half_up_and_clamps() {
        assert_eq!(quantize_u8(0.0, 0.5), 0);
        assert_eq!(quantize_u8(0.24, 0.5), 0);
        assert_eq!(quantize_u8(0.25, 0.5), 1);
        assert_eq!(quantize_u8(127.4, 0.5), 255);
        assert_eq!(quantize_u8(1e9, 0.5), 255);
        assert_eq!(quantize_u8(-3.0, 0.5), 0);
    }

    #[test]
    fn integer_dots_are_exact_at_the_extremes() {
        // 40 products of -127 * 255 (tail included): no i16 overflow, exact i32 sum.
        let w = [(-127i8) as u8; 40];
        let x = [255u8; 40];
        assert_eq!(dot_i8_u8(&w, &x), -127 * 255 * 40);
        let xs = [(-127i8) as u8; 40];
        assert_eq!(dot_i8_i8(&w, &xs), 127 * 127 * 40);
        // Unsigned bytes above 127 are not read as negative.
        let w1 = [1u8; 3];
        assert_eq!(dot_i8_u8(&w1, &[200, 128, 0]), 328);
        assert_eq!(dot_i8_i8(&w1, &[200, 128, 0]), -56 - 128);
    }
}
