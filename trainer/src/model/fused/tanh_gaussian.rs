//! The fused tanh-Gaussian head of SAC's policy (one autograd node for squash and
//! log-density).

use candle_core::{CpuStorage, Layout, Shape, Tensor};

use super::{f32_slice, msg};

/// `0.5 * ln(2 pi)`, in the Gaussian log-density (here, below the policy that uses the head:
/// the policy imports it, not the other way round).
pub(crate) const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// Fused tanh-Gaussian head (see `model::policy`): from the policy network's output
/// `h = [mu, raw log sigma]` `(B, 2A)` and noise `eps` `(B, A)` to `(B, A + 1)` holding
/// `a = tanh(mu + exp(clamp(raw)) eps)` and, in the last column,
/// `log pi(a|s) = sum_i [-eps_i^2/2 - log sigma_i - ln(2 pi)/2 - log(1 - a_i^2)]`
/// with `log(1 - tanh(u)^2) = 2 (ln 2 - u - softplus(-2u))`.
///
/// Backward (`g_a`, `g_l` the incoming gradients of the action columns and of log pi):
/// `dL/du = g_a (1 - a^2) + 2 a g_l`, `dL/dmu = dL/du`,
/// `dL/draw = (dL/du sigma eps - g_l) 1[lo < raw < hi]`.
#[derive(Debug, Clone, Copy)]
pub struct TanhGaussian {
    /// Lower clamp of log sigma.
    pub lo: f32,
    /// Upper clamp of log sigma.
    pub hi: f32,
}

impl candle_core::CustomOp2 for TanhGaussian {
    fn name(&self) -> &'static str {
        "tanh-gaussian"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (rows, two_a) = l1.shape().dims2()?;
        let a_dim = two_a / 2;
        if l2.shape().dims2()? != (rows, a_dim) || two_a % 2 != 0 {
            return Err(msg("tanh-gaussian: shape mismatch"));
        }
        let (h, eps) = (f32_slice(s1, l1)?, f32_slice(s2, l2)?);
        let mut out = vec![0.0f32; rows * (a_dim + 1)];
        for r in 0..rows {
            let (hr, er) = (
                &h[r * two_a..(r + 1) * two_a],
                &eps[r * a_dim..(r + 1) * a_dim],
            );
            let o = &mut out[r * (a_dim + 1)..(r + 1) * (a_dim + 1)];
            let mut logp = 0.0f32;
            for i in 0..a_dim {
                let ls = hr[a_dim + i].clamp(self.lo, self.hi);
                let e = er[i];
                let u = hr[i] + ls.exp() * e;
                // One exp serves both: t = e^{-2|u|}, tanh|u| = (1 - t) / (1 + t),
                // softplus(-2u) = max(-2u, 0) + ln(1 + t). (libm tanhf + a second exp cost
                // ~10% of a whole H=64 update.)
                let t = (-2.0 * u.abs()).exp();
                o[i] = ((1.0 - t) / (1.0 + t)).copysign(u);
                let softplus_m2u = (-2.0 * u).max(0.0) + t.ln_1p();
                let squash = 2.0 * (std::f32::consts::LN_2 - u - softplus_m2u);
                logp += -0.5 * e * e - ls - HALF_LN_2PI as f32 - squash;
            }
            o[a_dim] = logp;
        }
        Ok((CpuStorage::F32(out), Shape::from((rows, a_dim + 1))))
    }

    fn bwd(
        &self,
        h: &Tensor,
        eps: &Tensor,
        res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        if !h.track_op() {
            return Ok((None, None));
        }
        let (rows, two_a) = h.dims2()?;
        let a_dim = two_a / 2;
        let (h, eps, res, g) = (
            h.contiguous()?,
            eps.contiguous()?,
            res.contiguous()?,
            grad_res.contiguous()?,
        );
        let read = |t: &Tensor| -> candle_core::Result<Vec<f32>> { t.flatten_all()?.to_vec1() };
        let (h, eps, res, g) = (read(&h)?, read(&eps)?, read(&res)?, read(&g)?);
        let mut dh = vec![0.0f32; rows * two_a];
        let w = a_dim + 1;
        for r in 0..rows {
            let gl = g[r * w + a_dim];
            for i in 0..a_dim {
                let a = res[r * w + i];
                let raw = h[r * two_a + a_dim + i];
                let e = eps[r * a_dim + i];
                let du = g[r * w + i] * (1.0 - a * a) + 2.0 * a * gl;
                dh[r * two_a + i] = du;
                if raw > self.lo && raw < self.hi {
                    dh[r * two_a + a_dim + i] = du * raw.exp() * e - gl;
                }
            }
        }
        Ok((
            Some(Tensor::from_vec(
                dh,
                (rows, two_a),
                &candle_core::Device::Cpu,
            )?),
            None,
        ))
    }
}
