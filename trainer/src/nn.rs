//! Networks and the optimiser on candle-core.
//!
//! * [`Mlp`]: fully connected ReLU network whose weights are candle [`Var`]s, stored `(in, out)`
//!   so the forward pass is `x @ W + b` without a transpose.
//! * [`FrozenMlp`]: the same network in its *own* storage, never tracked by autograd; used for
//!   Polyak-averaged target networks (a detached view of a `Var` shares its storage and would
//!   silently follow the live weights, see DESIGN.md).
//! * [`Adam`]: Adam (Kingma & Ba 2015, no weight decay) whose per-parameter update is one fused
//!   in-place pass over the parameter, both moments and the gradient (candle has no in-place
//!   Adam; its `AdamW` allocates about eight temporaries per parameter per step).
//!
//! All randomness comes from the caller's RNG so that a seed fixes the whole run.

use std::cell::RefCell;

use candle_core::{CpuStorage, DType, Device, InplaceOp2, Layout, Tensor, Var};
use rand::Rng;

use crate::{Error, Result};

/// Weights and biases of one MLP as plain tensors, in layer order `[w0, b0, w1, b1, ...]`.
///
/// `w_i` has shape `(in, out)`, `b_i` shape `(1, out)`.
fn forward_params(params: &[Tensor], x: &Tensor) -> Result<Tensor> {
    let n_layers = params.len() / 2;
    let mut h = x.clone();
    for (i, wb) in params.chunks_exact(2).enumerate() {
        h = crate::fused::linear(&h, &wb[0], &wb[1], i + 1 < n_layers)?;
    }
    Ok(h)
}

/// A ReLU multi-layer perceptron with trainable weights.
#[derive(Debug, Clone)]
pub struct Mlp {
    /// Layer widths including input and output, e.g. `[36, 256, 256, 1]`.
    widths: Vec<usize>,
    /// `[w0, b0, w1, b1, ...]`, see [`forward_params`].
    vars: Vec<Var>,
}

impl Mlp {
    /// A new MLP `widths[0] -> widths[1] -> ... -> widths[last]` with ReLU between layers and a
    /// linear output. Initialisation as PyTorch's `nn.Linear` default: weights and biases
    /// `U(-1/sqrt(fan_in), 1/sqrt(fan_in))`.
    pub fn new(widths: &[usize], rng: &mut impl Rng) -> Result<Self> {
        if widths.len() < 2 || widths.contains(&0) {
            return Err(Error::Config(format!("bad MLP widths {widths:?}")));
        }
        let mut vars = Vec::with_capacity(2 * (widths.len() - 1));
        for io in widths.windows(2) {
            let (fan_in, fan_out) = (io[0], io[1]);
            let bound = 1.0 / (fan_in as f32).sqrt();
            let mut uniform = |n: usize| -> Vec<f32> {
                (0..n).map(|_| rng.random_range(-bound..bound)).collect()
            };
            let w = Tensor::from_vec(uniform(fan_in * fan_out), (fan_in, fan_out), &Device::Cpu)?;
            let b = Tensor::from_vec(uniform(fan_out), (1, fan_out), &Device::Cpu)?;
            vars.push(Var::from_tensor(&w)?);
            vars.push(Var::from_tensor(&b)?);
        }
        Ok(Self {
            widths: widths.to_vec(),
            vars,
        })
    }

    /// Layer widths including input and output.
    pub fn widths(&self) -> &[usize] {
        &self.widths
    }

    /// The trainable variables, `[w0, b0, w1, b1, ...]`.
    pub fn vars(&self) -> &[Var] {
        &self.vars
    }

    /// Forward pass; gradients flow into this network's weights.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let params: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().clone()).collect();
        forward_params(&params, x)
    }

    /// Forward pass with the weights treated as constants: gradients flow into `x` only.
    ///
    /// This is how the SAC actor loss evaluates `Q(s, pi(s))` without computing critic gradients.
    pub fn forward_const_weights(&self, x: &Tensor) -> Result<Tensor> {
        let params: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().detach()).collect();
        forward_params(&params, x)
    }

    /// A deep copy in separate storage, for target networks.
    pub fn frozen_copy(&self) -> Result<FrozenMlp> {
        let params = self
            .vars
            .iter()
            .map(|v| v.as_tensor().detach().copy())
            .collect::<candle_core::Result<Vec<_>>>()?;
        Ok(FrozenMlp {
            widths: self.widths.clone(),
            params,
        })
    }

    /// Overwrite all weights from `src` (same widths), e.g. when loading a checkpoint.
    pub fn load_from(&self, src: &[Tensor]) -> Result<()> {
        check_shapes(
            &self
                .vars
                .iter()
                .map(|v| v.as_tensor().clone())
                .collect::<Vec<_>>(),
            src,
        )?;
        for (v, s) in self.vars.iter().zip(src) {
            v.set(s)?;
        }
        Ok(())
    }
}

/// An MLP whose weights live in their own storage and are never trained by gradient.
#[derive(Debug, Clone)]
pub struct FrozenMlp {
    widths: Vec<usize>,
    params: Vec<Tensor>,
}

impl FrozenMlp {
    /// Forward pass (no gradient anywhere).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        forward_params(&self.params, &x.detach())
    }

    /// The weights, `[w0, b0, w1, b1, ...]`.
    pub fn params(&self) -> &[Tensor] {
        &self.params
    }

    /// Layer widths including input and output.
    pub fn widths(&self) -> &[usize] {
        &self.widths
    }

    /// Polyak averaging `theta_targ <- (1 - tau) theta_targ + tau theta`, in place.
    pub fn polyak_update(&self, online: &Mlp, tau: f32) -> Result<()> {
        for (t, v) in self.params.iter().zip(online.vars()) {
            t.inplace_op2(v.as_tensor(), &Lerp { tau })?;
        }
        Ok(())
    }

    /// Overwrite all weights from `src` (same shapes), copying into this network's own storage.
    pub fn load_from(&mut self, src: &[Tensor]) -> Result<()> {
        check_shapes(&self.params, src)?;
        self.params = src
            .iter()
            .map(|s| s.detach().copy())
            .collect::<candle_core::Result<Vec<_>>>()?;
        Ok(())
    }
}

fn check_shapes(have: &[Tensor], src: &[Tensor]) -> Result<()> {
    if have.len() != src.len() {
        return Err(Error::Shape(format!(
            "expected {} tensors, got {}",
            have.len(),
            src.len()
        )));
    }
    for (i, (h, s)) in have.iter().zip(src).enumerate() {
        if h.dims() != s.dims() {
            return Err(Error::Shape(format!(
                "tensor {i}: expected shape {:?}, got {:?}",
                h.dims(),
                s.dims()
            )));
        }
    }
    Ok(())
}

/// Contiguous f32 slice of a CPU tensor storage.
fn f32_slice<'a>(s: &'a CpuStorage, l: &Layout) -> candle_core::Result<&'a [f32]> {
    let (a, b) = l
        .contiguous_offsets()
        .ok_or_else(|| candle_core::Error::Msg("non-contiguous tensor in fused op".into()))?;
    match s {
        CpuStorage::F32(v) => Ok(&v[a..b]),
        _ => Err(candle_core::Error::Msg("fused ops are f32 only".into())),
    }
}

fn f32_slice_mut<'a>(s: &'a mut CpuStorage, l: &Layout) -> candle_core::Result<&'a mut [f32]> {
    let (a, b) = l
        .contiguous_offsets()
        .ok_or_else(|| candle_core::Error::Msg("non-contiguous tensor in fused op".into()))?;
    match s {
        CpuStorage::F32(v) => Ok(&mut v[a..b]),
        _ => Err(candle_core::Error::Msg("fused ops are f32 only".into())),
    }
}

/// In-place `dst += tau * (src - dst)`.
struct Lerp {
    tau: f32,
}

impl InplaceOp2 for Lerp {
    fn name(&self) -> &'static str {
        "lerp"
    }
    fn cpu_fwd(
        &self,
        s1: &mut CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<()> {
        let dst = f32_slice_mut(s1, l1)?;
        let src = f32_slice(s2, l2)?;
        for (d, s) in dst.iter_mut().zip(src) {
            *d += self.tau * (*s - *d);
        }
        Ok(())
    }
}

/// Hyper-parameters of [`Adam`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamConfig {
    /// Learning rate.
    pub lr: f32,
    /// First-moment decay.
    pub beta1: f32,
    /// Second-moment decay.
    pub beta2: f32,
    /// Denominator epsilon (added after the square root, as PyTorch does).
    pub eps: f32,
}

impl AdamConfig {
    /// PyTorch's `torch.optim.Adam` defaults with the given learning rate.
    pub fn with_lr(lr: f32) -> Self {
        Self {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }
}

/// Adam without weight decay over a fixed list of variables. Moments are plain `Vec<f32>`s so
/// they can be checkpointed and restored exactly.
#[derive(Debug, Clone)]
pub struct Adam {
    cfg: AdamConfig,
    vars: Vec<Var>,
    m: Vec<Vec<f32>>,
    v: Vec<Vec<f32>>,
    t: u64,
}

/// The fused Adam update for one parameter; `m` and `v` are borrowed for the call.
struct AdamStep<'a> {
    m: RefCell<&'a mut [f32]>,
    v: RefCell<&'a mut [f32]>,
    lr_t: f32,
    b1: f32,
    b2: f32,
    eps_t: f32,
}

impl InplaceOp2 for AdamStep<'_> {
    fn name(&self) -> &'static str {
        "adam"
    }
    fn cpu_fwd(
        &self,
        s1: &mut CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<()> {
        let p = f32_slice_mut(s1, l1)?;
        let g = f32_slice(s2, l2)?;
        let mut m = self.m.borrow_mut();
        let mut v = self.v.borrow_mut();
        if p.len() != g.len() || m.len() != p.len() {
            return Err(candle_core::Error::Msg("adam: length mismatch".into()));
        }
        let (b1, b2, c1, c2) = (self.b1, self.b2, 1.0 - self.b1, 1.0 - self.b2);
        for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
            *m = b1 * *m + c1 * g;
            *v = b2 * *v + c2 * g * g;
            *p -= self.lr_t * *m / (v.sqrt() + self.eps_t);
        }
        Ok(())
    }
}

impl Adam {
    /// A new optimiser for `vars` with zeroed moments.
    pub fn new(vars: Vec<Var>, cfg: AdamConfig) -> Self {
        let m: Vec<Vec<f32>> = vars.iter().map(|v| vec![0.0; v.elem_count()]).collect();
        let v = m.clone();
        Self {
            cfg,
            vars,
            m,
            v,
            t: 0,
        }
    }

    /// Number of steps taken.
    pub fn steps(&self) -> u64 {
        self.t
    }

    /// One Adam step from the gradients of `loss` (runs `loss.backward()`).
    ///
    /// `theta <- theta - lr * m_hat / (sqrt(v_hat) + eps)`, with the bias corrections folded into
    /// the step size and epsilon (algebraically identical to PyTorch's formulation).
    pub fn backward_step(&mut self, loss: &Tensor) -> Result<()> {
        let grads = loss.backward()?;
        self.step(&grads)
    }

    /// One Adam step from already computed gradients (several optimisers can share one
    /// `backward()`, e.g. SMILe's discriminator and encoder with different betas).
    pub fn step(&mut self, grads: &candle_core::backprop::GradStore) -> Result<()> {
        self.t += 1;
        let t = self.t as i32;
        let bc1 = 1.0 - self.cfg.beta1.powi(t);
        let bc2 = 1.0 - self.cfg.beta2.powi(t);
        // lr * (m / bc1) / (sqrt(v / bc2) + eps) = (lr sqrt(bc2) / bc1) m / (sqrt(v) + eps sqrt(bc2))
        let lr_t = self.cfg.lr * bc2.sqrt() / bc1;
        let eps_t = self.cfg.eps * bc2.sqrt();
        for (i, var) in self.vars.iter().enumerate() {
            let Some(g) = grads.get(var.as_tensor()) else {
                // The loss does not depend on this variable: skip it, as PyTorch does for a
                // parameter whose `.grad` is None.
                continue;
            };
            let g = g.contiguous()?;
            let op = AdamStep {
                m: RefCell::new(&mut self.m[i]),
                v: RefCell::new(&mut self.v[i]),
                lr_t,
                b1: self.cfg.beta1,
                b2: self.cfg.beta2,
                eps_t,
            };
            var.as_tensor().inplace_op2(&g, &op)?;
        }
        Ok(())
    }

    /// The moments as tensors `(m_i, v_i)` shaped like the variables, and the step count.
    pub fn state(&self) -> Result<(Vec<Tensor>, Vec<Tensor>, u64)> {
        let to_t = |xs: &[Vec<f32>]| -> Result<Vec<Tensor>> {
            xs.iter()
                .zip(&self.vars)
                .map(|(x, var)| Ok(Tensor::from_slice(x, var.shape(), &Device::Cpu)?))
                .collect()
        };
        Ok((to_t(&self.m)?, to_t(&self.v)?, self.t))
    }

    /// Restore moments and step count saved by [`Adam::state`].
    pub fn set_state(&mut self, m: &[Tensor], v: &[Tensor], t: u64) -> Result<()> {
        let vars: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().clone()).collect();
        check_shapes(&vars, m)?;
        check_shapes(&vars, v)?;
        let flat = |xs: &[Tensor]| -> Result<Vec<Vec<f32>>> {
            xs.iter()
                .map(|x| Ok(x.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()?))
                .collect()
        };
        self.m = flat(m)?;
        self.v = flat(v)?;
        self.t = t;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn adam_matches_reference_formula() {
        // One scalar parameter, loss = 0.5 * p^2 -> grad = p. Compare with textbook Adam.
        let var = Var::from_tensor(&Tensor::new(&[1.5f32], &Device::Cpu).unwrap()).unwrap();
        let cfg = AdamConfig::with_lr(0.1);
        let mut opt = Adam::new(vec![var.clone()], cfg);
        let (mut p, mut m, mut v) = (1.5f64, 0.0f64, 0.0f64);
        for t in 1..=5 {
            let loss = (var.as_tensor().sqr().unwrap() * 0.5)
                .unwrap()
                .sum_all()
                .unwrap();
            opt.backward_step(&loss).unwrap();
            let g = p;
            m = 0.9 * m + 0.1 * g;
            v = 0.999 * v + 0.001 * g * g;
            let mh = m / (1.0 - 0.9f64.powi(t));
            let vh = v / (1.0 - 0.999f64.powi(t));
            p -= 0.1 * mh / (vh.sqrt() + 1e-8);
            let got = var.as_tensor().to_vec1::<f32>().unwrap()[0] as f64;
            assert!((got - p).abs() < 1e-5, "step {t}: {got} vs {p}");
        }
    }

    #[test]
    fn target_has_own_storage_and_lerps() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let net = Mlp::new(&[3, 4, 2], &mut rng).unwrap();
        let targ = net.frozen_copy().unwrap();
        let before = targ.params()[0]
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap();
        // Change the live weights: the target must not follow.
        net.vars()[0]
            .set(&net.vars()[0].as_tensor().affine(1.0, 1.0).unwrap())
            .unwrap();
        let after = targ.params()[0]
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap();
        assert_eq!(before, after);
        targ.polyak_update(&net, 0.5).unwrap();
        let lerped = targ.params()[0]
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap();
        for (b, l) in before.iter().zip(&lerped) {
            assert!((l - (b + 0.5)).abs() < 1e-6);
        }
    }

    #[test]
    fn const_weights_give_no_weight_grads() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let net = Mlp::new(&[3, 4, 1], &mut rng).unwrap();
        let x = Var::from_tensor(&Tensor::ones((2, 3), DType::F32, &Device::Cpu).unwrap()).unwrap();
        let loss = net
            .forward_const_weights(x.as_tensor())
            .unwrap()
            .sum_all()
            .unwrap();
        let grads = loss.backward().unwrap();
        assert!(grads.get(x.as_tensor()).is_some());
        for v in net.vars() {
            assert!(grads.get(v.as_tensor()).is_none());
        }
    }
}
