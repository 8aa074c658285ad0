//! Fused dense layer as a candle `CustomOp3`: `y = act(x W + b)` in one op, forward and backward.
//!
//! Why (profiled, see docs/BENCHMARKS.md): with plain candle ops a layer is three graph nodes
//! (matmul, broadcast-add, relu), and candle's matmul backward always computes *both* operand
//! gradients, even for a detached operand; the SAC actor loss therefore paid for critic weight
//! gradients it then threw away, and every data-fed first layer for an input gradient. This op
//! makes one node per layer and computes only the gradients autograd needs:
//!
//! * `g  = dL/dy * 1[y > 0]` (ReLU mask from the saved output)
//! * `dx = g W^T`            only if `x` is tracked
//! * `dW = x^T g`, `db = 1^T g` only if `W` is tracked (a `Var`, not detached)
//!
//! The matrix products call the same `gemm` crate candle uses, one block per call; inside a
//! learner thread pool large products are split across its threads ([`gemm_into`]). Where some
//! input columns repeat within groups of rows (a task's `z` on each of its rows, module
//! `shared`), their product is computed once per group.

use std::mem::MaybeUninit;

use candle_core::{CpuStorage, CustomOp3, InplaceOp2, Layout, Shape, Tensor};

mod shared;
pub use shared::SharedCols;

fn msg(m: &str) -> candle_core::Error {
    candle_core::Error::Msg(format!("fused linear: {m}"))
}

/// Contiguous f32 slice of a CPU tensor storage.
fn f32_slice<'a>(s: &'a CpuStorage, l: &Layout) -> candle_core::Result<&'a [f32]> {
    let (a, b) = l
        .contiguous_offsets()
        .ok_or_else(|| msg("non-contiguous input"))?;
    match s {
        CpuStorage::F32(v) => Ok(&v[a..b]),
        _ => Err(msg("f32 only")),
    }
}

/// Mutable [`f32_slice`].
fn f32_slice_mut<'a>(s: &'a mut CpuStorage, l: &Layout) -> candle_core::Result<&'a mut [f32]> {
    let (a, b) = l
        .contiguous_offsets()
        .ok_or_else(|| msg("non-contiguous input"))?;
    match s {
        CpuStorage::F32(v) => Ok(&mut v[a..b]),
        _ => Err(msg("f32 only")),
    }
}

/// An in-place update of one CPU tensor's f32 values from another's (the MLP's Polyak step,
/// the optimiser's Adam step). [`OnSlices`] makes it a candle `InplaceOp2`, so that each
/// update states only its arithmetic and the storage unpacking stands in one place.
pub(crate) trait SliceUpdate {
    /// The op's name in candle's errors.
    const NAME: &'static str;

    /// Updates `dst` from `src` (each a tensor's contiguous values).
    fn apply(&self, dst: &mut [f32], src: &[f32]) -> candle_core::Result<()>;
}

/// A [`SliceUpdate`] as a candle `InplaceOp2` on contiguous f32 CPU tensors (other devices
/// keep candle's refusal).
pub(crate) struct OnSlices<U>(pub U);

impl<U: SliceUpdate> InplaceOp2 for OnSlices<U> {
    fn name(&self) -> &'static str {
        U::NAME
    }

    fn cpu_fwd(
        &self,
        s1: &mut CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<()> {
        self.0.apply(f32_slice_mut(s1, l1)?, f32_slice(s2, l2)?)
    }
}

/// A fused op of three f32 CPU tensors, as its arithmetic alone: [`OnValues3`] makes it a
/// candle `CustomOp3`, so that the storage unpacking and candle's signatures stand in one place
/// (as [`OnSlices`] does for in-place updates).
pub(crate) trait Fused3 {
    /// The op's name in candle's errors.
    fn name(&self) -> &'static str;

    /// The output's values and shape from the inputs' contiguous values and shapes.
    fn forward(&self, inputs: [(&[f32], &Shape); 3]) -> candle_core::Result<(Vec<f32>, Shape)>;

    /// The gradients of the inputs from the output `res` and its gradient `grad`, each only
    /// where autograd wants it (`None` elsewhere).
    fn backward(&self, inputs: [&Tensor; 3], res: &Tensor, grad: &Tensor) -> Grads3;
}

/// What [`Fused3::backward`] returns: one gradient per input.
pub(crate) type Grads3 = candle_core::Result<[Option<Tensor>; 3]>;

/// A [`Fused3`] as a candle `CustomOp3` on contiguous f32 CPU tensors (other devices keep
/// candle's refusal).
pub(crate) struct OnValues3<F>(pub F);

impl<F: Fused3 + Send + Sync> CustomOp3 for OnValues3<F> {
    fn name(&self) -> &'static str {
        self.0.name()
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let inputs = [values(s1, l1)?, values(s2, l2)?, values(s3, l3)?];
        let (out, shape) = self.0.forward(inputs)?;
        Ok((CpuStorage::F32(out), shape))
    }

    fn bwd(
        &self,
        a: &Tensor,
        b: &Tensor,
        c: &Tensor,
        res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let [da, db, dc] = self.0.backward([a, b, c], res, grad_res)?;
        Ok((da, db, dc))
    }
}

/// A CPU storage's contiguous f32 values with its shape.
fn values<'a>(s: &'a CpuStorage, l: &'a Layout) -> candle_core::Result<(&'a [f32], &'a Shape)> {
    Ok((f32_slice(s, l)?, l.shape()))
}

/// Runs `f` on a CPU tensor's values in place (made contiguous first; no copy when it is).
fn with_values<R>(
    t: &Tensor,
    f: impl FnOnce(&[f32]) -> candle_core::Result<R>,
) -> candle_core::Result<R> {
    let t = t.contiguous()?;
    let (s, l) = t.storage_and_layout();
    match &*s {
        candle_core::Storage::Cpu(s) => f(f32_slice(s, l)?),
        _ => Err(msg("cpu only")),
    }
}

/// Row-major `C (m x n) [+]= A (m x k) B (k x n)` where A and B are [`Mat`]s read through strides
/// (row stride, column stride), so transposes are free.
///
/// Inside a learner thread pool of N > 1 threads ([`crate::threads::LearnerPool`]) a product
/// of at least [`SPLIT_MIN_FLOPS`] is cut into N blocks of rows of `C` (of columns when `C` has
/// too few rows) and the blocks run through `rayon::join`: a core that is free steals a block,
/// a busy pool runs them one after the other on the calling thread. Each element of `C` is the
/// same sum in the same order whichever block and thread computes it (the blocks only change
/// which rows or columns a call covers, not the loop over `k`), so results do not depend on the
/// thread count (tested: `split_products_are_bit_identical`).
///
/// (The layers call [`gemm_new`]; this entry, with accumulation, is kept for the tests of the
/// splitting.)
#[cfg(test)]
pub(crate) fn gemm_into(
    m: usize,
    n: usize,
    k: usize,
    c: &mut [f32],
    accumulate: bool,
    a: Mat<'_>,
    b: Mat<'_>,
) {
    debug_assert!(c.len() >= m * n);
    // SAFETY: `MaybeUninit<f32>` has the layout of `f32`, and the product only writes
    // initialised values (finite or not) into `c`, so `c` stays initialised.
    let c = unsafe { &mut *(&mut c[..m * n] as *mut [f32] as *mut [MaybeUninit<f32>]) };
    gemm_uninit(m, n, k, c, accumulate, a, b);
}

/// `A B` (`m x n`, row-major) in a new buffer; as [`gemm_into`] without accumulating, but the
/// buffer is not zero-filled first (a non-accumulating product writes every element of `C`
/// and reads none, so the fill was a wasted pass over the output: about 1% of an update pair
/// at the SMILe authors' shapes).
pub(crate) fn gemm_new(m: usize, n: usize, k: usize, a: Mat<'_>, b: Mat<'_>) -> Vec<f32> {
    let mut c = Vec::with_capacity(m * n);
    gemm_uninit(m, n, k, &mut c.spare_capacity_mut()[..m * n], false, a, b);
    // SAFETY: a non-accumulating product writes all `m x n` elements (gemm writes
    // `0 * C + A B`, or zeros when `k == 0`, without reading `C`; split products write every
    // row or column block), so the first `m n` elements are initialised.
    unsafe { c.set_len(m * n) };
    c
}

/// A matrix operand read through strides, so a transpose is free: element `(i, j)` is
/// `v[i * rs + j * cs]`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Mat<'a> {
    v: &'a [f32],
    rs: usize,
    cs: usize,
}

impl<'a> Mat<'a> {
    /// A row-major matrix of `cols` columns.
    pub(crate) fn rows(v: &'a [f32], cols: usize) -> Self {
        Self { v, rs: cols, cs: 1 }
    }

    /// The transpose of a row-major matrix of `cols` columns (no copy).
    pub(crate) fn t(v: &'a [f32], cols: usize) -> Self {
        Self { v, rs: 1, cs: cols }
    }

    /// Whether `rows x cols` elements at these strides lie inside the slice.
    fn covers(&self, rows: usize, cols: usize) -> bool {
        rows == 0 || cols == 0 || self.v.len() > (rows - 1) * self.rs + (cols - 1) * self.cs
    }
}

/// [`gemm_into`] on an output that may be uninitialised when `!accumulate`.
fn gemm_uninit(
    m: usize,
    n: usize,
    k: usize,
    c: &mut [MaybeUninit<f32>],
    accumulate: bool,
    a: Mat<'_>,
    b: Mat<'_>,
) {
    debug_assert!(c.len() >= m * n);
    debug_assert!(a.covers(m, k) && b.covers(k, n));
    let parts =
        if rayon::current_thread_index().is_some() && 2.0 * (m * n * k) as f64 >= SPLIT_MIN_FLOPS {
            rayon::current_num_threads()
        } else {
            1
        };
    let p = Product {
        n,
        k,
        a,
        b,
        accumulate,
    };
    if parts > 1 && m >= 2 * SPLIT_MIN_ROWS {
        p.rows(m, &mut c[..m * n], parts);
    } else if parts > 1 && n >= 2 * SPLIT_MIN_ROWS && !accumulate {
        // Columns of a row-major C are not contiguous: each block writes its own (m x cols)
        // buffer, copied into C afterwards. (Products with few rows and many columns are the
        // first layers' weight gradients, never accumulated; an accumulated product would add
        // the blocks in another order than one call does, so it is not split this way.)
        p.cols(m, &mut c[..m * n], parts);
    } else {
        p.call(m, n, c, n, 0);
    }
}

/// Products smaller than this many floating-point operations stay on one thread (a block
/// handed to another core costs a few microseconds; 4 MFLOP take about 50 us on one core).
pub(crate) const SPLIT_MIN_FLOPS: f64 = 4e6;

/// A block of a split product has at least this many rows (or columns).
const SPLIT_MIN_ROWS: usize = 32;

/// The operands of one `C [+]= A B` (see [`gemm_into`]), split into blocks.
#[derive(Clone, Copy)]
struct Product<'a> {
    n: usize,
    k: usize,
    a: Mat<'a>,
    b: Mat<'a>,
    accumulate: bool,
}

impl Product<'_> {
    /// Rows `[0, m)` of `C` (`c` holds exactly them), in `parts` blocks of rows.
    fn rows(&self, m: usize, c: &mut [MaybeUninit<f32>], parts: usize) {
        if parts <= 1 || m < 2 * SPLIT_MIN_ROWS {
            return self.call(m, self.n, c, self.n, 0);
        }
        let (lo_parts, hi_parts) = (parts / 2, parts - parts / 2);
        let m_lo = m * lo_parts / parts;
        let (c_lo, c_hi) = c.split_at_mut(m_lo * self.n);
        let hi = Product {
            a: Mat {
                v: &self.a.v[m_lo * self.a.rs..],
                ..self.a
            },
            ..*self
        };
        rayon::join(
            || self.rows(m_lo, c_lo, lo_parts),
            || hi.rows(m - m_lo, c_hi, hi_parts),
        );
    }

    /// All of `C` (`m x n`, not accumulated) in `parts` blocks of columns.
    fn cols(&self, m: usize, c: &mut [MaybeUninit<f32>], parts: usize) {
        debug_assert!(!self.accumulate);
        for (j0, cols, block) in self.col_blocks(m, 0, self.n, parts) {
            for r in 0..m {
                let row = &mut c[r * self.n + j0..r * self.n + j0 + cols];
                for (d, v) in row.iter_mut().zip(&block[r * cols..(r + 1) * cols]) {
                    d.write(*v);
                }
            }
        }
    }

    /// Columns `[j0, j0 + cols)` of `A B` as `(j0, cols, m x cols block)`s, `parts` of them.
    fn col_blocks(
        &self,
        m: usize,
        j0: usize,
        cols: usize,
        parts: usize,
    ) -> Vec<(usize, usize, Vec<f32>)> {
        if parts <= 1 || cols < 2 * SPLIT_MIN_ROWS {
            let mut block = Vec::with_capacity(m * cols);
            self.call(
                m,
                cols,
                &mut block.spare_capacity_mut()[..m * cols],
                cols,
                j0,
            );
            // SAFETY: not accumulating (see `cols`), the call wrote all `m x cols` elements.
            unsafe { block.set_len(m * cols) };
            return vec![(j0, cols, block)];
        }
        let lo_parts = parts / 2;
        let c_lo = cols * lo_parts / parts;
        let (mut lo, hi) = rayon::join(
            || self.col_blocks(m, j0, c_lo, lo_parts),
            || self.col_blocks(m, j0 + c_lo, cols - c_lo, parts - lo_parts),
        );
        lo.extend(hi);
        lo
    }

    /// `C[.., j0..j0+cols] [+]= A B[.., j0..j0+cols]` into `c` with row stride `ldc`.
    fn call(&self, m: usize, cols: usize, c: &mut [MaybeUninit<f32>], ldc: usize, j0: usize) {
        if m == 0 || cols == 0 {
            return;
        }
        debug_assert!(c.len() >= (m - 1) * ldc + cols);
        // SAFETY: the slices cover every element addressed by (m, cols, k) and the strides
        // (checked in debug builds in `gemm_uninit`, and by construction from the tensors'
        // shapes at every call site); `c` does not alias `a` or `b` (distinct allocations);
        // without `accumulate` gemm does not read `c`, which may be uninitialised then.
        unsafe {
            gemm::gemm(
                m,
                cols,
                self.k,
                c.as_mut_ptr().cast::<f32>(),
                1,
                ldc as isize,
                self.accumulate,
                self.a.v.as_ptr(),
                self.a.cs as isize,
                self.a.rs as isize,
                self.b.v.as_ptr().add(j0 * self.b.cs),
                self.b.cs as isize,
                self.b.rs as isize,
                if self.accumulate { 1.0 } else { 0.0 },
                1.0,
                false,
                false,
                false,
                gemm::Parallelism::None,
            )
        }
    }
}

/// `g` where the ReLU output `y` is positive, else `+0.0` (`if y > 0 { g } else { 0 }`),
/// without a branch: the mask is about half ones on random rows, and a branch on it was
/// mispredicted so often that the backward pass's masking took 9% of an update pair.
#[inline(always)]
fn relu_mask(g: f32, y: f32) -> f32 {
    f32::from_bits(g.to_bits() & ((y > 0.0) as u32).wrapping_neg())
}

/// The op: `x (B, in)`, `w (in, out)`, `b (1, out)` -> `y (B, out)`.
#[derive(Debug, Clone, Copy)]
pub struct Linear {
    /// Apply ReLU to the output.
    pub relu: bool,
    /// Input columns that repeat within groups of rows: their product is computed once per
    /// group (module `shared`).
    pub shared: Option<SharedCols>,
}

impl Fused3 for Linear {
    fn name(&self) -> &'static str {
        if self.relu { "linear-relu" } else { "linear" }
    }

    fn forward(&self, [x, w, b]: [(&[f32], &Shape); 3]) -> candle_core::Result<(Vec<f32>, Shape)> {
        let (rows, d_in) = x.1.dims2()?;
        let (w_in, d_out) = w.1.dims2()?;
        if w_in != d_in || b.1.elem_count() != d_out {
            return Err(msg("shape mismatch"));
        }
        let (x, w, b) = (x.0, w.0, b.0);
        // x W into a fresh buffer, then bias and ReLU in one pass over it (a bias-filled
        // buffer accumulated into, then a ReLU pass, went over the output three times).
        let Some(sc) = self.shared else {
            let mut y = gemm_new(rows, d_out, d_in, Mat::rows(x, d_in), Mat::rows(w, d_out));
            for row in y.chunks_exact_mut(d_out) {
                bias_act(row, b, self.relu);
            }
            return Ok((y, Shape::from((rows, d_out))));
        };
        sc.groups(rows, d_in).map_err(|e| msg(&e))?;
        debug_assert!(sc.holds(x, d_in), "shared columns differ within a group");
        // The shared block's product once per group, added with the bias in the same pass.
        let (mut y, zw) = sc.forward(x, rows, d_in, w, d_out);
        for (grp, zrow) in y
            .chunks_mut(sc.group_rows * d_out)
            .zip(zw.chunks_exact(d_out))
        {
            let zb: Vec<f32> = zrow.iter().zip(b).map(|(z, b)| z + b).collect();
            for row in grp.chunks_exact_mut(d_out) {
                bias_act(row, &zb, self.relu);
            }
        }
        Ok((y, Shape::from((rows, d_out))))
    }

    fn backward(&self, [x, w, _b]: [&Tensor; 3], res: &Tensor, grad_res: &Tensor) -> Grads3 {
        let (rows, d_in) = x.dims2()?;
        let d_out = w.dim(1)?;
        let (want_dx, want_dw) = (x.track_op(), w.track_op());
        if !want_dx && !want_dw {
            return Ok([None, None, None]);
        }
        // g = dL/dy * 1[y > 0], and (for dW) its column sums in the same pass over the rows (only a
        // ReLU layer needs g as a buffer of its own; without ReLU g is dL/dy as it is). The
        // sums are per group of rows where the input has shared columns (their weights'
        // gradient needs them; db is then the groups' total), else db = 1^T g directly.
        let shared = self.shared.filter(|_| want_dw);
        let group_rows = shared.map_or(rows.max(1), |sc| sc.group_rows);
        let mut sums = vec![0.0f32; rows.div_ceil(group_rows).max(1) * d_out];
        let masked: Option<Vec<f32>> = with_values(grad_res, |gs| {
            if self.relu {
                with_values(res, |ys| {
                    // Row by row over equal-length slices, so the loop vectorises.
                    let mut g = Vec::with_capacity(gs.len());
                    let rows_out = g.spare_capacity_mut()[..gs.len()].chunks_exact_mut(d_out);
                    let rows_in = rows_out
                        .zip(gs.chunks_exact(d_out))
                        .zip(ys.chunks_exact(d_out));
                    if want_dw {
                        for (r, ((out, gr), yr)) in rows_in.enumerate() {
                            let acc = &mut sums[(r / group_rows) * d_out..][..d_out];
                            for (((o, g_o), y_o), d) in out.iter_mut().zip(gr).zip(yr).zip(acc) {
                                let v = relu_mask(*g_o, *y_o);
                                o.write(v);
                                *d += v;
                            }
                        }
                    } else {
                        // No weight gradient, so no bias gradient: the mask alone (the SAC
                        // actor's loss through the critics, whose weights are constants there).
                        for ((out, gr), yr) in rows_in {
                            for ((o, g_o), y_o) in out.iter_mut().zip(gr).zip(yr) {
                                o.write(relu_mask(*g_o, *y_o));
                            }
                        }
                    }
                    // SAFETY: the loop wrote all `gs.len()` elements (`gs` and `ys` are
                    // `rows x d_out`, checked by the tensors' shapes).
                    unsafe { g.set_len(gs.len()) };
                    Ok(Some(g))
                })
            } else {
                if want_dw {
                    for (r, gr) in gs.chunks_exact(d_out).enumerate() {
                        let acc = &mut sums[(r / group_rows) * d_out..][..d_out];
                        acc.iter_mut().zip(gr).for_each(|(d, g)| *d += g);
                    }
                }
                Ok(None)
            }
        })?;
        let mut db = vec![0.0f32; d_out];
        for s in sums.chunks_exact(d_out) {
            db.iter_mut().zip(s).for_each(|(d, s)| *d += s);
        }
        let dev = x.device();
        with_values(grad_res, |gs| {
            let g: &[f32] = masked.as_deref().unwrap_or(gs);
            let dx = if want_dx {
                // dx (rows x in) = g (rows x out) W^T (out x in); W^T[o][i] = W[i * out + o]
                let dx = with_values(w, |ws| {
                    Ok(gemm_new(
                        rows,
                        d_in,
                        d_out,
                        Mat::rows(g, d_out),
                        Mat::t(ws, d_out),
                    ))
                })?;
                Some(Tensor::from_vec(dx, (rows, d_in), dev)?)
            } else {
                None
            };
            let (dw, db) = if want_dw {
                // dW (in x out) = x^T (in x rows) g (rows x out); x^T[i][r] = x[r * in + i]
                let dw = with_values(x, |xs| {
                    Ok(match shared {
                        Some(sc) => sc.weight_grad(xs, rows, d_in, g, &sums, d_out),
                        None => gemm_new(d_in, d_out, rows, Mat::t(xs, d_in), Mat::rows(g, d_out)),
                    })
                })?;
                (
                    Some(Tensor::from_vec(dw, (d_in, d_out), dev)?),
                    Some(Tensor::from_vec(std::mem::take(&mut db), (1, d_out), dev)?),
                )
            } else {
                (None, None)
            };
            Ok([dx, dw, db])
        })
    }
}

/// `row + b`, then ReLU when `relu`, in one pass.
#[inline]
fn bias_act(row: &mut [f32], b: &[f32], relu: bool) {
    if relu {
        row.iter_mut()
            .zip(b)
            .for_each(|(v, b)| *v = (*v + b).max(0.0));
    } else {
        row.iter_mut().zip(b).for_each(|(v, b)| *v += b);
    }
}

/// `act(x W + b)` as one autograd node.
#[cfg(test)]
pub fn linear(x: &Tensor, w: &Tensor, b: &Tensor, relu: bool) -> candle_core::Result<Tensor> {
    linear_shared(x, w, b, relu, None)
}

/// [`linear`] on an input whose `shared` columns repeat within groups of rows (module
/// `shared`): the same values up to rounding, with the shared block's products once per group.
pub fn linear_shared(
    x: &Tensor,
    w: &Tensor,
    b: &Tensor,
    relu: bool,
    shared: Option<SharedCols>,
) -> candle_core::Result<Tensor> {
    x.contiguous()?
        .apply_op3(w, b, OnValues3(Linear { relu, shared }))
}

/// One step of the gradient penalty's input-gradient chain as one autograd node (see the
/// discriminator's `input_gradient_first_cols`): from `g (B, out)`, the layer's ReLU
/// output `y (B, out)` (a constant) and its weight `w (in, out)`,
/// `out = (g . 1[y > 0]) W^T`  `(B, in)`. Backward, with `G = g . 1[y > 0]`:
/// `dg = (dout W) . 1[y > 0]` and `dW = dout^T G`, each only if autograd wants it. (As plain
/// candle ops this was a mask, a multiply and a matmul whose backward ran outside the pool's
/// product splitting.)
#[derive(Debug, Clone, Copy)]
pub struct MaskedMatmulT;

impl Fused3 for MaskedMatmulT {
    fn name(&self) -> &'static str {
        "masked-matmul-t"
    }

    fn forward(&self, [g, y, w]: [(&[f32], &Shape); 3]) -> candle_core::Result<(Vec<f32>, Shape)> {
        let (rows, d_out) = g.1.dims2()?;
        let (d_in, w_out) = w.1.dims2()?;
        if y.1.dims2()? != (rows, d_out) || w_out != d_out {
            return Err(msg("masked matmul: shape mismatch"));
        }
        let (g, y, w) = (g.0, y.0, w.0);
        let masked: Vec<f32> = g.iter().zip(y).map(|(g, y)| relu_mask(*g, *y)).collect();
        // out (rows x in) = G (rows x out) W^T (out x in); W^T[o][i] = W[i * out + o]
        let out = gemm_new(
            rows,
            d_in,
            d_out,
            Mat::rows(&masked, d_out),
            Mat::t(w, d_out),
        );
        Ok((out, Shape::from((rows, d_in))))
    }

    fn backward(&self, [g, y, w]: [&Tensor; 3], _res: &Tensor, grad_res: &Tensor) -> Grads3 {
        let (rows, d_out) = g.dims2()?;
        let d_in = w.dim(0)?;
        let (want_dg, want_dw) = (g.track_op(), w.track_op());
        if !want_dg && !want_dw {
            return Ok([None, None, None]);
        }
        let dev = g.device();
        let (dg, dw) = with_values(grad_res, |dout| {
            with_values(y, |y| {
                let dg = if want_dg {
                    // dG (rows x out) = dout (rows x in) W (in x out), then the mask
                    let mut dg = with_values(w, |w| {
                        Ok(gemm_new(
                            rows,
                            d_out,
                            d_in,
                            Mat::rows(dout, d_in),
                            Mat::rows(w, d_out),
                        ))
                    })?;
                    dg.iter_mut()
                        .zip(y)
                        .for_each(|(d, y)| *d = relu_mask(*d, *y));
                    Some(Tensor::from_vec(dg, (rows, d_out), dev)?)
                } else {
                    None
                };
                let dw = if want_dw {
                    let masked: Vec<f32> = with_values(g, |g| {
                        Ok(g.iter().zip(y).map(|(g, y)| relu_mask(*g, *y)).collect())
                    })?;
                    // dW (in x out) = dout^T (in x rows) G (rows x out); dout^T[i][r] =
                    // dout[r * in + i]
                    let dw = gemm_new(
                        d_in,
                        d_out,
                        rows,
                        Mat::t(dout, d_in),
                        Mat::rows(&masked, d_out),
                    );
                    Some(Tensor::from_vec(dw, (d_in, d_out), dev)?)
                } else {
                    None
                };
                Ok((dg, dw))
            })
        })?;
        Ok([dg, None, dw])
    }
}

/// `(g . 1[y > 0]) W^T` as one autograd node ([`MaskedMatmulT`]); `y` is not differentiated.
pub fn masked_matmul_t(g: &Tensor, y: &Tensor, w: &Tensor) -> candle_core::Result<Tensor> {
    g.contiguous()?
        .apply_op3(&y.detach().contiguous()?, w, OnValues3(MaskedMatmulT))
}

mod tanh_gaussian;
pub(crate) use tanh_gaussian::HALF_LN_2PI;
pub use tanh_gaussian::TanhGaussian;

#[cfg(test)]
mod tests;
