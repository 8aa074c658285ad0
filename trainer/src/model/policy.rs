//! Tanh-squashed diagonal Gaussian policy (Haarnoja et al. 2018, appendix C).
//!
//! The network maps an observation to `(mu, log_sigma)`; an action is `a = tanh(u)` with
//! `u = mu + sigma * eps`, `eps ~ N(0, I)` (reparameterisation, so `a` is differentiable in the
//! policy weights). Its log-density, by the change of variables through tanh:
//!
//! `log pi(a|s) = sum_i [ log N(u_i; mu_i, sigma_i) - log(1 - tanh(u_i)^2) ]`
//!
//! with the numerically stable `log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u))`.

use candle_core::{Device, Tensor};
use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::Result;
use crate::model::fused::HALF_LN_2PI;
use crate::model::{Input, Mlp};

/// A tanh-squashed Gaussian policy; actions lie in `(-1, 1)^act_dim`.
#[derive(Debug, Clone)]
pub struct TanhGaussianPolicy {
    net: Mlp,
    act_dim: usize,
    log_std_min: f32,
    log_std_max: f32,
}

/// A reparameterised draw from the policy (all tensors keep their autograd graph).
#[derive(Debug, Clone)]
pub struct PolicySample {
    /// `tanh(u)`, shape `(B, act_dim)`.
    pub action: Tensor,
    /// `log pi(a|s)`, shape `(B, 1)`.
    pub log_prob: Tensor,
    /// Pre-squash mean `mu`, shape `(B, act_dim)`.
    pub mean: Tensor,
    /// Clamped `log sigma`, shape `(B, act_dim)`.
    pub log_std: Tensor,
}

/// Numerically stable `softplus(x) = ln(1 + e^x) = max(x, 0) + ln(1 + e^-|x|)`.
fn softplus(x: &Tensor) -> Result<Tensor> {
    Ok((x.relu()? + x.abs()?.neg()?.exp()?.affine(1.0, 1.0)?.log()?)?)
}

impl TanhGaussianPolicy {
    /// A policy `obs_dim -> hidden... -> 2 * act_dim`, log-sigma clamped to
    /// `[log_std_min, log_std_max]`.
    pub fn new(
        obs_dim: usize,
        act_dim: usize,
        hidden: &[usize],
        log_std_bounds: (f32, f32),
        rng: &mut impl Rng,
    ) -> Result<Self> {
        let mut widths = vec![obs_dim];
        widths.extend_from_slice(hidden);
        widths.push(2 * act_dim);
        Ok(Self {
            net: Mlp::new(&widths, rng)?,
            act_dim,
            log_std_min: log_std_bounds.0,
            log_std_max: log_std_bounds.1,
        })
    }

    /// A copy in separate storage (see [`Mlp::deep_copy`]): what a rollout on another thread
    /// acts with while the learner keeps training this one.
    pub fn deep_copy(&self) -> Result<Self> {
        Ok(Self {
            net: self.net.deep_copy()?,
            ..self.clone()
        })
    }

    /// The underlying network.
    pub fn net(&self) -> &Mlp {
        &self.net
    }

    /// Action dimension.
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Observation (input) dimension.
    pub fn obs_dim(&self) -> usize {
        self.net.widths()[0]
    }

    /// `(mu, clamp(log sigma))` for a batch of observations `(B, obs_dim)`.
    pub fn heads<'a>(&self, obs: impl Into<Input<'a>>) -> Result<(Tensor, Tensor)> {
        self.heads_impl(obs.into(), false)
    }

    fn heads_impl(&self, obs: Input<'_>, const_weights: bool) -> Result<(Tensor, Tensor)> {
        let out = if const_weights {
            self.net.forward_const_weights(obs)?
        } else {
            self.net.forward(obs)?
        };
        let mean = out.narrow(1, 0, self.act_dim)?;
        let log_std = out
            .narrow(1, self.act_dim, self.act_dim)?
            .clamp(self.log_std_min, self.log_std_max)?;
        Ok((mean, log_std))
    }

    /// Standard normal noise of shape `(rows, act_dim)` from `rng`.
    pub fn noise(&self, rows: usize, rng: &mut impl Rng) -> Result<Tensor> {
        let eps: Vec<f32> = (0..rows * self.act_dim)
            .map(|_| rng.sample::<f32, _>(StandardNormal))
            .collect();
        Ok(Tensor::from_vec(eps, (rows, self.act_dim), &Device::Cpu)?)
    }

    /// Reparameterised sample `a = tanh(mu + sigma * eps)` and its log-density, given `eps`.
    pub fn sample_with_noise<'a>(
        &self,
        obs: impl Into<Input<'a>>,
        eps: &Tensor,
    ) -> Result<PolicySample> {
        self.sample_impl(obs.into(), eps, false)
    }

    /// As [`TanhGaussianPolicy::sample`] with the weights treated as constants (no graph into
    /// the policy; used for the critic's bootstrap target).
    pub fn sample_const<'a>(
        &self,
        obs: impl Into<Input<'a>>,
        rng: &mut impl Rng,
    ) -> Result<PolicySample> {
        self.sample_fresh(obs.into(), rng, true)
    }

    /// A sample with fresh noise from `rng`; `const_w`: no graph into the weights.
    fn sample_fresh(
        &self,
        obs: Input<'_>,
        rng: &mut impl Rng,
        const_w: bool,
    ) -> Result<PolicySample> {
        let eps = self.noise(obs.x.dim(0)?, rng)?;
        self.sample_impl(obs, &eps, const_w)
    }

    fn sample_impl(&self, obs: Input<'_>, eps: &Tensor, const_w: bool) -> Result<PolicySample> {
        let out = if const_w {
            self.net.forward_const_weights(obs)?
        } else {
            self.net.forward(obs)?
        };
        let a = self.act_dim;
        // One fused node for squash + log-density (crate::model::TanhGaussian), equal to
        // `sample_reference` below.
        let op = crate::model::TanhGaussian {
            lo: self.log_std_min,
            hi: self.log_std_max,
        };
        let fused = out.apply_op2(eps, op)?;
        Ok(PolicySample {
            action: fused.narrow(1, 0, a)?,
            log_prob: fused.narrow(1, a, 1)?,
            mean: out.narrow(1, 0, a)?,
            log_std: out
                .narrow(1, a, a)?
                .clamp(self.log_std_min, self.log_std_max)?,
        })
    }

    /// The same sample written with plain candle ops (the equations of the module doc); kept
    /// as the reference the fused op is tested against.
    pub fn sample_reference(&self, obs: &Tensor, eps: &Tensor) -> Result<PolicySample> {
        let (mean, log_std) = self.heads(obs)?;
        let u = (&mean + (log_std.exp()? * eps)?)?;
        // log N(u; mu, sigma) = -eps^2/2 - log sigma - ln(2 pi)/2, summed over action dims
        let gauss = ((eps.sqr()? * -0.5)? - &log_std)?.affine(1.0, -HALF_LN_2PI)?;
        // log(1 - tanh(u)^2) = 2 (ln 2 - u - softplus(-2u))
        let squash = ((u.affine(-1.0, std::f64::consts::LN_2)? - softplus(&(&u * -2.0)?)?)? * 2.0)?;
        let log_prob = (gauss - squash)?.sum_keepdim(1)?;
        Ok(PolicySample {
            action: u.tanh()?,
            log_prob,
            mean,
            log_std,
        })
    }

    /// Reparameterised sample with fresh noise from `rng`.
    pub fn sample<'a>(
        &self,
        obs: impl Into<Input<'a>>,
        rng: &mut impl Rng,
    ) -> Result<PolicySample> {
        self.sample_fresh(obs.into(), rng, false)
    }

    /// The deterministic action `tanh(mu)` used for evaluation and demos.
    pub fn mean_action<'a>(&self, obs: impl Into<Input<'a>>) -> Result<Tensor> {
        let (mean, _) = self.heads(obs)?;
        Ok(mean.tanh()?)
    }

    /// One action for one observation (rollouts): `tanh(mu)` if `deterministic`, else a sample.
    pub fn act(&self, obs: &[f32], deterministic: bool, rng: &mut impl Rng) -> Result<Vec<f32>> {
        let o = Tensor::from_slice(obs, (1, obs.len()), &Device::Cpu)?;
        let a = if deterministic {
            self.heads_impl((&o).into(), true)?.0.tanh()?
        } else {
            self.sample_const(&o, rng)?.action
        };
        Ok(a.flatten_all()?.to_vec1::<f32>()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn log_prob_matches_closed_form() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pi = TanhGaussianPolicy::new(4, 2, &[8], (-20.0, 2.0), &mut rng).unwrap();
        let obs = Tensor::from_vec(vec![0.3f32, -1.0, 0.5, 2.0], (1, 4), &Device::Cpu).unwrap();
        let eps = Tensor::from_vec(vec![0.7f32, -1.3], (1, 2), &Device::Cpu).unwrap();
        let s = pi.sample_with_noise(&obs, &eps).unwrap();
        let mu = s.mean.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let ls = s.log_std.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let mut want = 0.0f64;
        for (i, e) in [0.7f64, -1.3].iter().enumerate() {
            let u = mu[i] as f64 + (ls[i] as f64).exp() * e;
            want += -0.5 * e * e - ls[i] as f64 - HALF_LN_2PI - (1.0 - u.tanh().powi(2)).ln();
        }
        let got = s.log_prob.flatten_all().unwrap().to_vec1::<f32>().unwrap()[0] as f64;
        assert!((got - want).abs() < 1e-4, "{got} vs {want}");
    }

    #[test]
    fn fused_sample_matches_reference_with_gradients() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let pi = TanhGaussianPolicy::new(3, 2, &[8], (-1.0, 0.5), &mut rng).unwrap();
        let obs = Tensor::from_vec(
            (0..12)
                .map(|i| (i as f32 * 0.9).sin() * 2.0)
                .collect::<Vec<_>>(),
            (4, 3),
            &Device::Cpu,
        )
        .unwrap();
        let eps = pi.noise(4, &mut rng).unwrap();
        let f = pi.sample_with_noise(&obs, &eps).unwrap();
        let r = pi.sample_reference(&obs, &eps).unwrap();
        let w = Tensor::new(&[0.3f32, -1.7], &Device::Cpu).unwrap();
        let loss = |s: &PolicySample| {
            (s.action.broadcast_mul(&w).unwrap().sum_all().unwrap()
                + (s.log_prob.sum_all().unwrap() * 0.7).unwrap())
            .unwrap()
        };
        let (lf, lr) = (loss(&f), loss(&r));
        let v = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let close = |a: Vec<f32>, b: Vec<f32>| {
            a.iter()
                .zip(&b)
                .all(|(x, y)| (x - y).abs() < 1e-4 * (1.0 + y.abs()))
        };
        assert!(close(v(&f.log_prob), v(&r.log_prob)));
        assert!(close(v(&f.action), v(&r.action)));
        let (gf, gr) = (lf.backward().unwrap(), lr.backward().unwrap());
        for var in pi.net().vars() {
            assert!(close(v(gf.get(var).unwrap()), v(gr.get(var).unwrap())));
        }
    }
}
