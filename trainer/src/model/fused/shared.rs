//! A dense layer's products when some input columns repeat within groups of rows.
//!
//! SMILe's batches are task-major: a task's `z` is appended to each of the task's rows (the
//! SAC batch's `[norm(s), z]` and `[norm(s), z, a]`, the discriminator's `[x, z]`). The first
//! layer's `z` block, `z W_z`, is then the same for every row of a task; computed per row it is
//! about a tenth of SAC's products and a twentieth of the discriminator's at the authors'
//! shapes. Here it is computed once per group of rows, and `W_z`'s gradient from the group's
//! summed output gradient (`sum_r z^T g_r = z^T sum_r g_r`):
//!
//! ```text
//! y_r  = x_r,other W_other + (z_grp(r) W_z) + b
//! dW_other = X_other^T G,   dW_z = Z^T Gsum,   Gsum[grp] = sum_{r in grp} G[r]
//! ```
//!
//! The input gradient is the plain `G W^T` (every row's, `z`'s columns included).

use super::{Mat, gemm_new};

/// Columns `[start, start + len)` of a layer's input hold the same values in every row of each
/// group of `group_rows` consecutive rows (a task's `z` repeated over the task's rows).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SharedCols {
    /// First shared column.
    pub start: usize,
    /// Number of shared columns.
    pub len: usize,
    /// Rows per group; the input's rows are a whole number of groups.
    pub group_rows: usize,
}

impl SharedCols {
    /// The number of groups of an input of `rows x cols`, or why these columns do not fit it.
    pub(super) fn groups(&self, rows: usize, cols: usize) -> Result<usize, String> {
        if self.group_rows == 0 || !rows.is_multiple_of(self.group_rows) {
            return Err(format!(
                "{rows} rows are not whole groups of {} rows",
                self.group_rows
            ));
        }
        if self.start + self.len > cols {
            return Err(format!(
                "shared columns {}..{} outside an input of {cols} columns",
                self.start,
                self.start + self.len
            ));
        }
        Ok(rows / self.group_rows)
    }

    /// Whether every row of each group repeats the group's first row on the shared columns
    /// (checked in debug builds: a caller that broke the promise would get wrong values).
    pub(super) fn holds(&self, x: &[f32], cols: usize) -> bool {
        let (s, e) = (self.start, self.start + self.len);
        x.chunks_exact(self.group_rows * cols).all(|grp| {
            let first = &grp[s..e];
            grp.chunks_exact(cols).all(|row| &row[s..e] == first)
        })
    }

    /// `Z`, the groups' shared columns `(groups x len)`, read from each group's first row.
    fn z<'a>(&self, x: &'a [f32], cols: usize) -> Mat<'a> {
        Mat {
            v: &x[self.start..],
            rs: self.group_rows * cols,
            cs: 1,
        }
    }

    /// The forward products of `x (rows x cols) W (cols x out)`: the other columns' product
    /// `(rows x out)` and the shared block's, once per group `(groups x out)`; the caller adds
    /// the group's row of the second to each row of the first.
    pub(super) fn forward(
        &self,
        x: &[f32],
        rows: usize,
        cols: usize,
        w: &[f32],
        out: usize,
    ) -> (Vec<f32>, Vec<f32>) {
        let (s, e) = (self.start, self.start + self.len);
        // The other columns' product, one call: when they lie on both sides of the block they
        // are gathered first (with W's rows likewise), which costs a copy of `rows x (cols -
        // len)` values where a second, accumulating product would read and write all of y.
        let y = if s > 0 && e < cols {
            let (xo, wo) = (self.gather_cols(x, cols), self.gather_rows(w, out));
            let k = cols - self.len;
            gemm_new(rows, out, k, Mat::rows(&xo, k), Mat::rows(&wo, out))
        } else {
            // one contiguous range of columns (a product over none of them writes zeros)
            let (c0, k) = if s > 0 { (0, s) } else { (e, cols - e) };
            let xo = Mat {
                v: &x[c0..],
                rs: cols,
                cs: 1,
            };
            gemm_new(rows, out, k, xo, Mat::rows(&w[c0 * out..], out))
        };
        let groups = rows / self.group_rows;
        let zw = gemm_new(
            groups,
            out,
            self.len,
            self.z(x, cols),
            Mat::rows(&w[s * out..], out),
        );
        (y, zw)
    }

    /// `dW (cols x out)` from the input `x (rows x cols)`, the layer's output gradient
    /// `g (rows x out)` and its per-group sums `gsum (groups x out)`.
    pub(super) fn weight_grad(
        &self,
        x: &[f32],
        rows: usize,
        cols: usize,
        g: &[f32],
        gsum: &[f32],
        out: usize,
    ) -> Vec<f32> {
        let (s, e) = (self.start, self.start + self.len);
        let groups = rows / self.group_rows;
        // Z^T Gsum (len x out); Z^T[i][grp] = x[grp * group_rows * cols + start + i]
        let zt = Mat {
            v: &x[s..],
            rs: 1,
            cs: self.group_rows * cols,
        };
        let dwz = gemm_new(self.len, out, groups, zt, Mat::rows(gsum, out));
        // X_other^T G ((cols - len) x out), one product over the other columns (gathered when
        // they lie on both sides of the block, as in `forward`); X^T[i][r] = x[r * cols + i]
        let k = cols - self.len;
        let dwo = if s > 0 && e < cols {
            let xo = self.gather_cols(x, cols);
            gemm_new(k, out, rows, Mat::t(&xo, k), Mat::rows(g, out))
        } else {
            let c0 = if s > 0 { 0 } else { e };
            let xt = Mat {
                v: &x[c0..],
                rs: 1,
                cs: cols,
            };
            gemm_new(k, out, rows, xt, Mat::rows(g, out))
        };
        // dW's rows in input order: the other columns before the block, the block, the rest.
        let mut dw = Vec::with_capacity(cols * out);
        dw.extend_from_slice(&dwo[..s * out]);
        dw.extend_from_slice(&dwz);
        dw.extend_from_slice(&dwo[s * out..]);
        dw
    }

    /// The columns outside the block, gathered row by row: `rows x (cols - len)`.
    fn gather_cols(&self, x: &[f32], cols: usize) -> Vec<f32> {
        let (s, e) = (self.start, self.start + self.len);
        let mut xo = Vec::with_capacity(x.len() / cols * (cols - self.len));
        for row in x.chunks_exact(cols) {
            xo.extend_from_slice(&row[..s]);
            xo.extend_from_slice(&row[e..]);
        }
        xo
    }

    /// W's rows outside the block (`W` is `cols x out`): `(cols - len) x out`.
    fn gather_rows(&self, w: &[f32], out: usize) -> Vec<f32> {
        let (s, e) = (self.start * out, (self.start + self.len) * out);
        [&w[..s], &w[e..]].concat()
    }
}
