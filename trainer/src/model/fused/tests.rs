//! Tests of the fused layers: products split across threads, the layer against plain candle,
//! shared columns.
use super::*;
use candle_core::backprop::GradStore;
use candle_core::{Device, Var};

/// The gradients of `sum(y * weights)`, `weights` broadcast over the rows.
fn weighted_backward(y: &Tensor, weights: &Tensor) -> GradStore {
    y.broadcast_mul(weights)
        .unwrap()
        .sum_all()
        .unwrap()
        .backward()
        .unwrap()
}

/// A product split into row or column blocks across a pool of any size equals the product
/// computed in one call, bit for bit (what makes runs independent of the thread count).
#[test]
fn split_products_are_bit_identical() {
    let vals = |n: usize, s: f32| -> Vec<f32> {
        (0..n).map(|i| (i as f32 * 0.61 + s).sin() * 3.0).collect()
    };
    // (m, n, k, a transposed): rows split (C 300 x 200); columns split (C 40 x 700, the
    // shape of a first layer's weight gradient, A read transposed).
    for (m, n, k, a_t) in [(300usize, 200usize, 150usize, false), (40, 700, 300, true)] {
        assert!(2.0 * (m * n * k) as f64 >= SPLIT_MIN_FLOPS);
        let (a, b) = (vals(m * k, 0.3), vals(k * n, 1.7));
        let a_mat = if a_t { Mat::t(&a, m) } else { Mat::rows(&a, k) };
        let run = |threads: usize, accumulate: bool| -> Vec<f32> {
            let mut c = vals(m * n, 2.9);
            crate::threads::LearnerPool::new(threads)
                .unwrap()
                .install(|| gemm_into(m, n, k, &mut c, accumulate, a_mat, Mat::rows(&b, n)));
            c
        };
        let fresh = |threads: usize| -> Vec<f32> {
            crate::threads::LearnerPool::new(threads)
                .unwrap()
                .install(|| gemm_new(m, n, k, a_mat, Mat::rows(&b, n)))
        };
        for threads in [1, 2, 3] {
            let (new, into) = (fresh(threads), run(threads, false));
            assert!(
                new.iter()
                    .zip(&into)
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
                "gemm_new {m}x{n}x{k}, {threads} threads"
            );
        }
        for accumulate in [false, true] {
            let one = run(1, accumulate);
            for threads in [2, 3, 4, 7] {
                let split = run(threads, accumulate);
                assert!(
                    one.iter()
                        .zip(&split)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{m}x{n}x{k}, {threads} threads, accumulate {accumulate}"
                );
            }
        }
    }
}

/// A fresh product writes every element even with no inner dimension (what makes its
/// unfilled buffer sound).
#[test]
fn a_fresh_product_with_no_inner_dimension_is_zero() {
    assert_eq!(
        gemm_new(3, 4, 0, Mat::rows(&[], 0), Mat::rows(&[], 4)),
        vec![0.0f32; 12]
    );
}

/// The fused op's values and gradients equal plain candle's.
#[test]
fn matches_plain_candle() {
    let dev = &Device::Cpu;
    let mk =
        |n: usize, s: f32| -> Vec<f32> { (0..n).map(|i| (i as f32 * 0.37 + s).sin()).collect() };
    let x = Var::from_vec(mk(5 * 3, 0.1), (5, 3), dev).unwrap();
    let w = Var::from_vec(mk(3 * 4, 0.7), (3, 4), dev).unwrap();
    let b = Var::from_vec(mk(4, 1.3), (1, 4), dev).unwrap();
    for relu in [false, true] {
        let fused = linear(&x, &w, &b, relu).unwrap();
        let mut plain = x.matmul(&w).unwrap().broadcast_add(&b).unwrap();
        if relu {
            plain = plain.relu().unwrap();
        }
        let close = |a: &Tensor, b: &Tensor| {
            let d = (a - b).unwrap().abs().unwrap().max_all().unwrap();
            d.to_vec0::<f32>().unwrap() < 1e-5
        };
        assert!(close(&fused, &plain));
        let weights = Tensor::new(&[1.0f32, -2.0, 0.5, 3.0], dev).unwrap();
        let gf = weighted_backward(&fused, &weights);
        let gp = weighted_backward(&plain, &weights);
        for v in [&x, &w, &b] {
            assert!(close(gf.get(v).unwrap(), gp.get(v).unwrap()), "relu {relu}");
        }
    }
    // Detached weights: no weight gradients are produced, and the input's gradient (the
    // mask-only path of the backward pass) is still plain candle's.
    let (wd, bd) = (w.as_tensor().detach(), b.as_tensor().detach());
    let weights = Tensor::new(&[1.0f32, -2.0, 0.5, 3.0], dev).unwrap();
    for relu in [false, true] {
        let y = linear(&x, &wd, &bd, relu).unwrap();
        let mut plain = x.matmul(&wd).unwrap().broadcast_add(&bd).unwrap();
        if relu {
            plain = plain.relu().unwrap();
        }
        let g = weighted_backward(&y, &weights);
        assert!(g.get(&w).is_none() && g.get(&b).is_none());
        let (gx, px) = (g.get(&x).unwrap(), weighted_backward(&plain, &weights));
        let d = (gx - px.get(&x).unwrap()).unwrap().abs().unwrap();
        assert!(
            d.max_all().unwrap().to_vec0::<f32>().unwrap() < 1e-5,
            "relu {relu}"
        );
    }
}

/// A layer on an input with shared columns (before, inside or after the other columns;
/// with and without ReLU; input tracked or not) has plain candle's values and gradients,
/// on one learner thread and split across three (bit-identical between the two).
#[test]
fn shared_columns_match_plain_candle() {
    let dev = &Device::Cpu;
    let mk =
        |n: usize, s: f32| -> Vec<f32> { (0..n).map(|i| (i as f32 * 0.37 + s).sin()).collect() };
    let (groups, group_rows, d_in, d_out) = (3usize, 40usize, 7usize, 90usize);
    let rows = groups * group_rows;
    for start in [0usize, 2, 4] {
        let len = 3;
        // x with columns [start, start + len) equal within each group of rows
        let mut xv = mk(rows * d_in, 0.1);
        for r in 0..rows {
            for c in start..start + len {
                xv[r * d_in + c] = ((r / group_rows) as f32 * 0.9 + c as f32).cos();
            }
        }
        let sc = SharedCols {
            start,
            len,
            group_rows,
        };
        let x = Var::from_vec(xv, (rows, d_in), dev).unwrap();
        let w = Var::from_vec(mk(d_in * d_out, 0.7), (d_in, d_out), dev).unwrap();
        let b = Var::from_vec(mk(d_out, 1.3), (1, d_out), dev).unwrap();
        let weights = Tensor::new(mk(d_out, 2.1), dev).unwrap();
        for relu in [false, true] {
            for track_x in [false, true] {
                let xin = if track_x {
                    x.as_tensor().clone()
                } else {
                    x.as_tensor().detach()
                };
                let run = |threads: usize| {
                    crate::threads::LearnerPool::new(threads)
                        .unwrap()
                        .install(|| {
                            let y = linear_shared(&xin, &w, &b, relu, Some(sc)).unwrap();
                            let g = weighted_backward(&y, &weights);
                            (y, g)
                        })
                };
                let (y, g) = run(1);
                let mut plain = xin.matmul(&w).unwrap().broadcast_add(&b).unwrap();
                if relu {
                    plain = plain.relu().unwrap();
                }
                let gp = weighted_backward(&plain, &weights);
                // Relative to the largest value: a weight gradient sums 120 rows, and the
                // shared block's sums run in another order than the plain product's.
                let close = |a: &Tensor, b: &Tensor| {
                    let max = |t: Tensor| t.abs().unwrap().max_all().unwrap();
                    let d = max((a - b).unwrap()).to_vec0::<f32>().unwrap();
                    d <= 1e-5 * (1.0 + max(b.clone()).to_vec0::<f32>().unwrap())
                };
                let what = format!("start {start} relu {relu} track_x {track_x}");
                assert!(close(&y, &plain), "{what}");
                for v in [&w, &b] {
                    assert!(close(g.get(v).unwrap(), gp.get(v).unwrap()), "{what}");
                }
                assert_eq!(g.get(&x).is_some(), track_x, "{what}");
                if track_x {
                    assert!(close(g.get(&x).unwrap(), gp.get(&x).unwrap()), "{what}");
                }
                let (y3, g3) = run(3);
                let bits = |t: &Tensor| {
                    t.flatten_all()
                        .unwrap()
                        .to_vec1::<f32>()
                        .unwrap()
                        .iter()
                        .map(|v| v.to_bits())
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&y), bits(&y3), "{what}");
                assert_eq!(
                    bits(g.get(&w).unwrap()),
                    bits(g3.get(&w).unwrap()),
                    "{what}"
                );
            }
        }
    }
}

/// Shared columns that do not fit the input are an error, not a wrong answer.
#[test]
fn shared_columns_that_do_not_fit_are_refused() {
    let dev = &Device::Cpu;
    let x = Tensor::zeros((10, 4), candle_core::DType::F32, dev).unwrap();
    let w = Tensor::zeros((4, 3), candle_core::DType::F32, dev).unwrap();
    let b = Tensor::zeros((1, 3), candle_core::DType::F32, dev).unwrap();
    let sc = |start, len, group_rows| {
        Some(SharedCols {
            start,
            len,
            group_rows,
        })
    };
    assert!(linear_shared(&x, &w, &b, true, sc(2, 2, 5)).is_ok());
    assert!(linear_shared(&x, &w, &b, true, sc(2, 2, 3)).is_err()); // 10 rows, groups of 3
    assert!(linear_shared(&x, &w, &b, true, sc(3, 2, 5)).is_err()); // past the last column
    assert!(linear_shared(&x, &w, &b, true, sc(0, 1, 0)).is_err());
}
