//! Multi-layer perceptrons on candle-core (the optimiser is in [`crate::optim`]).
//!
//! * [`Mlp`]: fully connected ReLU network whose weights are candle [`Var`]s, stored `(in, out)`
//!   so the forward pass is `x @ W + b` without a transpose.
//! * [`FrozenMlp`]: the same network in its *own* storage, never tracked by autograd; used for
//!   Polyak-averaged target networks (a detached view of a `Var` shares its storage and would
//!   silently follow the live weights, see DESIGN.md).
//!
//! All randomness comes from the caller's RNG so that a seed fixes the whole run.

use candle_core::{Device, Tensor, Var};
use rand::Rng;

use super::fused::{OnSlices, SharedCols, SliceUpdate};
use crate::error::{Error, Result};

/// Weights and biases of one MLP as plain tensors, in layer order `[w0, b0, w1, b1, ...]`.
///
/// `w_i` has shape `(in, out)`, `b_i` shape `(1, out)`.
fn forward_params(params: &[Tensor], x: Input<'_>) -> Result<Tensor> {
    let n_layers = params.len() / 2;
    let mut h = x.x.clone();
    for (i, wb) in params.chunks_exact(2).enumerate() {
        // Only the first layer sees the input's shared columns.
        let shared = if i == 0 { x.shared } else { None };
        h = super::fused::linear_shared(&h, &wb[0], &wb[1], i + 1 < n_layers, shared)?;
    }
    Ok(h)
}

/// A network's input rows, and the columns that repeat within groups of them if any (a task's
/// `z` on each of the task's rows): the first layer then computes their product once per group.
/// A plain `&Tensor` converts into an input without shared columns.
#[derive(Debug, Clone, Copy)]
pub struct Input<'a> {
    /// The rows `(B, in)`.
    pub x: &'a Tensor,
    /// The columns that repeat within groups of rows, if any.
    pub shared: Option<SharedCols>,
}

impl<'a> Input<'a> {
    /// `x` with the given shared columns (`None`: a plain input).
    pub fn shared(x: &'a Tensor, shared: Option<SharedCols>) -> Self {
        Self { x, shared }
    }
}

impl<'a> From<&'a Tensor> for Input<'a> {
    fn from(x: &'a Tensor) -> Self {
        Self { x, shared: None }
    }
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
    pub fn forward<'a>(&self, x: impl Into<Input<'a>>) -> Result<Tensor> {
        let params: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().clone()).collect();
        forward_params(&params, x.into())
    }

    /// Forward pass with the weights treated as constants: gradients flow into `x` only.
    ///
    /// This is how the SAC actor loss evaluates `Q(s, pi(s))` without computing critic gradients.
    pub fn forward_const_weights<'a>(&self, x: impl Into<Input<'a>>) -> Result<Tensor> {
        let params: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().detach()).collect();
        forward_params(&params, x.into())
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

    /// A trainable copy in separate storage: later steps on either network leave the other as
    /// it was (a plain `clone` shares the variables' storage, which optimisers update in place).
    pub fn deep_copy(&self) -> Result<Mlp> {
        let vars = self
            .vars
            .iter()
            .map(|v| Var::from_tensor(&v.as_tensor().detach().copy()?))
            .collect::<candle_core::Result<Vec<_>>>()?;
        Ok(Mlp {
            widths: self.widths.clone(),
            vars,
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
    pub fn forward<'a>(&self, x: impl Into<Input<'a>>) -> Result<Tensor> {
        let x = x.into();
        forward_params(&self.params, Input::shared(&x.x.detach(), x.shared))
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
            t.inplace_op2(v.as_tensor(), &OnSlices(Lerp { tau }))?;
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

pub(crate) fn check_shapes(have: &[Tensor], src: &[Tensor]) -> Result<()> {
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

/// In-place `dst += tau * (src - dst)`.
struct Lerp {
    tau: f32,
}

impl SliceUpdate for Lerp {
    const NAME: &'static str = "lerp";

    fn apply(&self, dst: &mut [f32], src: &[f32]) -> candle_core::Result<()> {
        for (d, s) in dst.iter_mut().zip(src) {
            *d += self.tau * (*s - *d);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::DType;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

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
