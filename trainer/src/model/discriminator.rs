//! SMILe's context-conditioned AIRL discriminator `D(x, z)` and its losses, each next to the
//! equation it implements.
//!
//! The input is `[x, z]` with `x = [norm(s), a]` (state-action) or `[norm(s), norm(s')]`
//! (state-only) and `z` the task latent of the context encoder. The logit is clamped to
//! `[-c, c]`; its value is also the policy's reward, `log D - log(1 - D)`.
//!
//! ```text
//! l = clamp(D(x, z), -c, c)                                    (logit; c = 10)
//! L_bce = mean[ softplus(l) - y l ]                            (BCE with logits)
//! x~ = u x_E + (1 - u) x_pi,  u ~ U(0, 1) per sample,  z detached
//! L_gp = mean[ (|| d D(x~, z) / d x~ || - 1)^2 ]               (WGAN-GP form)
//! ```

use candle_core::{DType, Device, Tensor, Var};
use rand::Rng;

use super::context::ObsNorm;
use super::fused::SharedCols;
use super::mlp::{Input, Mlp};
use crate::error::{Error, Result};

/// What the discriminator sees of a transition besides `z`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscInput {
    /// `x = [norm(s), a]` (SMILe state-action).
    StateAction,
    /// `x = [norm(s), norm(s')]` (SMILe state-only: demos without actions suffice).
    StateOnly,
}

/// The discriminator network with its input layout and logit clamp.
#[derive(Debug, Clone)]
pub struct Discriminator {
    net: Mlp,
    input: DiscInput,
    obs_dim: usize,
    act_dim: usize,
    clamp: f32,
}

impl Discriminator {
    /// A new discriminator `[x, z] -> hidden... -> 1` (initialised as [`Mlp::new`]).
    pub fn new(
        obs_dim: usize,
        act_dim: usize,
        z_dim: usize,
        hidden: &[usize],
        input: DiscInput,
        logit_clamp: f32,
        rng: &mut impl Rng,
    ) -> Result<Self> {
        let x_dim = match input {
            DiscInput::StateAction => obs_dim + act_dim,
            DiscInput::StateOnly => 2 * obs_dim,
        };
        let mut widths = vec![x_dim + z_dim];
        widths.extend_from_slice(hidden);
        widths.push(1);
        Ok(Self {
            net: Mlp::new(&widths, rng)?,
            input,
            obs_dim,
            act_dim,
            clamp: logit_clamp,
        })
    }

    /// Width of `x` (without `z`).
    pub fn x_dim(&self) -> usize {
        match self.input {
            DiscInput::StateAction => self.obs_dim + self.act_dim,
            DiscInput::StateOnly => 2 * self.obs_dim,
        }
    }

    /// The input layout.
    pub fn input(&self) -> DiscInput {
        self.input
    }

    /// Appends `x` of one transition `(s, a, s')`: `[norm(s), a]` or `[norm(s), norm(s')]`.
    pub fn push_x(&self, norm: &ObsNorm, s: &[f32], a: &[f32], s2: &[f32], out: &mut Vec<f32>) {
        norm.push(s, out);
        match self.input {
            DiscInput::StateAction => out.extend_from_slice(a),
            DiscInput::StateOnly => norm.push(s2, out),
        }
    }

    /// The underlying network (checkpoints, export of its widths).
    pub fn net(&self) -> &Mlp {
        &self.net
    }

    /// The trainable variables (for its optimiser).
    pub fn vars(&self) -> &[Var] {
        self.net.vars()
    }

    /// `l = clamp(D([x, z]), -c, c)` for rows `[x, z]`; gradients flow into the weights and
    /// into `z` (so into the encoder).
    pub fn logits<'a>(&self, xz: impl Into<Input<'a>>) -> Result<Tensor> {
        let c = self.clamp as f64;
        Ok(self.net.forward(xz)?.clamp(-c, c)?)
    }

    /// The policy's reward `r = clamp(D([x, z]), -c, c) = log D - log(1 - D)`, a constant for
    /// the SAC step (no gradient anywhere).
    pub fn reward<'a>(&self, xz: impl Into<Input<'a>>) -> Result<Tensor> {
        let c = self.clamp as f64;
        Ok(self.net.forward_const_weights(xz)?.clamp(-c, c)?.detach())
    }

    /// `L_gp = mean[(||dD([x~, z])/dx~|| - 1)^2]` with `x~ = u x_E + (1 - u) x_pi` per row; `z`
    /// is detached (the penalty does not train the encoder) and the gradient is taken with
    /// respect to `x~` only. `z_group_rows`: `z`'s rows repeat in groups of that many (a task's z
    /// on its rows), so the first layer computes the z block once per group.
    pub fn gradient_penalty(
        &self,
        x_expert: &Tensor,
        x_policy: &Tensor,
        z: &Tensor,
        u: &Tensor,
        z_group_rows: Option<usize>,
    ) -> Result<Tensor> {
        let xd = x_expert.dim(1)?;
        let x_mix =
            (x_expert.broadcast_mul(u)? + x_policy.broadcast_mul(&u.affine(-1.0, 1.0)?)?)?;
        let mix = Tensor::cat(&[&x_mix, &z.detach()], 1)?;
        let zd = z.dim(1)?;
        let shared = z_group_rows.map(|group_rows| SharedCols {
            start: xd,
            len: zd,
            group_rows,
        });
        let g = input_gradient_first_cols(&self.net, Input::shared(&mix, shared), xd)?;
        let norm = (g.sqr()?.sum_keepdim(1)? + 1e-12)?.sqrt()?;
        Ok((norm - 1.0)?.sqr()?.mean_all()?)
    }
}

/// `dD/dx` of a ReLU MLP with a scalar output, per row, as a differentiable function of the
/// weights (for the gradient penalty; candle has no double backward through our fused
/// layers). With row-vector layers `h_{l+1} = relu(h_l W_l + b_l)`:
/// `g = (((1 W_L^T) . m_{L-1}) W_{L-1}^T . ... . m_0) W_0^T`, where `m_l = 1[pre-activation > 0]`
/// (constants: ReLU's second derivative is zero almost everywhere, so this equals PyTorch's
/// `create_graph=True` gradient). Only the first `cols` columns (the gradient penalty's `x~`,
/// not its detached `z`): the last product of the chain then uses only the first `cols` rows
/// of `W_0`, which skips `z`'s share of that product, of its backward and of `W_0`'s gradient
/// (about a third of the discriminator's first layer there at the authors' shapes).
fn input_gradient_first_cols(net: &Mlp, input: Input<'_>, cols: usize) -> Result<Tensor> {
    let x = input.x;
    if cols == 0 || cols > x.dim(1)? {
        return Err(Error::Config(format!(
            "input gradient of the first {cols} of {} columns",
            x.dim(1)?
        )));
    }
    let vars = net.vars();
    let n = vars.len() / 2;
    // The hidden layers' ReLU outputs y_l (constants; y_l > 0 exactly where m_l = 1).
    let mut acts = Vec::with_capacity(n - 1);
    let mut h = x.detach();
    for l in 0..n - 1 {
        h = super::fused::linear_shared(
            &h,
            &vars[2 * l].as_tensor().detach(),
            &vars[2 * l + 1].as_tensor().detach(),
            true,
            if l == 0 { input.shared } else { None },
        )?;
        acts.push(h.clone());
    }
    let rows = x.dim(0)?;
    let w_last = vars[2 * (n - 1)].as_tensor(); // (h, 1)
    let mut g = Tensor::ones((rows, 1), DType::F32, &Device::Cpu)?.matmul(&w_last.t()?)?;
    for l in (0..n - 1).rev() {
        // g <- (g . m_l) W_l^T, one fused node (its products split in a learner pool); for the
        // first layer only W_0's rows of the wanted input columns.
        let w = vars[2 * l].as_tensor();
        let w = if l == 0 {
            w.narrow(0, 0, cols)?
        } else {
            w.clone()
        };
        g = super::fused::masked_matmul_t(&g, &acts[l], &w)?;
    }
    if n == 1 {
        g = g.narrow(1, 0, cols)?; // no hidden layer: the chain is W_0^T alone
    }
    Ok(g)
}

/// BCE with logits, `mean[max(l, 0) - l y + ln(1 + e^{-|l|})]`.
pub fn bce_with_logits(logits: &Tensor, labels: &Tensor) -> Result<Tensor> {
    let softplus = (logits.relu()? + logits.abs()?.neg()?.exp()?.affine(1.0, 1.0)?.log()?)?;
    Ok((softplus - (logits * labels)?)?.mean_all()?)
}

/// Scalars of one discriminator step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DiscStats {
    /// `losses/disc_bce`.
    pub bce: f32,
    /// `losses/disc_gp`.
    pub gp: f32,
    /// `charts/disc_acc_expert`: fraction of expert rows with logit > 0.
    pub acc_expert: f32,
    /// `charts/disc_acc_policy`: fraction of policy rows with logit < 0.
    pub acc_policy: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Var;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The whole input's gradient (every column).
    fn input_gradient(net: &Mlp, x: &Tensor) -> Result<Tensor> {
        input_gradient_first_cols(net, x.into(), x.dim(1)?)
    }

    #[test]
    fn input_gradient_matches_autograd() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let net = Mlp::new(&[5, 7, 6, 1], &mut rng).unwrap();
        let x: Vec<f32> = (0..20)
            .map(|i| ((i * 37 % 11) as f32 - 5.0) * 0.3)
            .collect();
        let xv = Var::from_tensor(&Tensor::from_vec(x, (4, 5), &Device::Cpu).unwrap()).unwrap();
        let grads = net
            .forward(xv.as_tensor())
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let auto = grads.get(xv.as_tensor()).unwrap().to_vec2::<f32>().unwrap();
        let ours = input_gradient(&net, xv.as_tensor())
            .unwrap()
            .to_vec2::<f32>()
            .unwrap();
        for (a, b) in auto.iter().flatten().zip(ours.iter().flatten()) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // And it is differentiable in the weights: the penalty has weight gradients.
        let gp = input_gradient(&net, xv.as_tensor())
            .unwrap()
            .sqr()
            .unwrap()
            .sum_all()
            .unwrap();
        let g = gp.backward().unwrap();
        assert!(g.get(net.vars()[0].as_tensor()).is_some());
        assert!(g.get(net.vars()[4].as_tensor()).is_some());
    }

    /// The fused chain's weight gradients (the penalty's double backward) equal those of the
    /// same chain written with plain candle ops (matmul, mask multiply), which candle
    /// differentiates itself.
    #[test]
    fn the_penalty_chain_has_plain_candles_weight_gradients() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let net = Mlp::new(&[6, 9, 7, 8, 1], &mut rng).unwrap();
        let x: Vec<f32> = (0..30)
            .map(|i| ((i * 29 % 13) as f32 - 6.0) * 0.25)
            .collect();
        let x = Tensor::from_vec(x, (5, 6), &Device::Cpu).unwrap();
        let plain = |net: &Mlp, x: &Tensor| -> Tensor {
            let vars = net.vars();
            let n = vars.len() / 2;
            let mut masks = Vec::new();
            let mut h = x.clone();
            for l in 0..n - 1 {
                let pre = h
                    .matmul(&vars[2 * l].as_tensor().detach())
                    .unwrap()
                    .broadcast_add(&vars[2 * l + 1].as_tensor().detach())
                    .unwrap();
                masks.push(pre.gt(0.0).unwrap().to_dtype(DType::F32).unwrap());
                h = pre.relu().unwrap();
            }
            let mut g = Tensor::ones((5, 1), DType::F32, &Device::Cpu)
                .unwrap()
                .matmul(&vars[2 * (n - 1)].as_tensor().t().unwrap())
                .unwrap();
            for l in (0..n - 1).rev() {
                g = (g * &masks[l])
                    .unwrap()
                    .matmul(&vars[2 * l].as_tensor().t().unwrap())
                    .unwrap();
            }
            g
        };
        let loss = |g: Tensor| g.sqr().unwrap().sum_all().unwrap().backward().unwrap();
        let (ours, reference) = (
            loss(input_gradient(&net, &x).unwrap()),
            loss(plain(&net, &x)),
        );
        for v in net.vars() {
            let (a, b) = (ours.get(v.as_tensor()), reference.get(v.as_tensor()));
            match (a, b) {
                (Some(a), Some(b)) => {
                    let d = (a - b).unwrap().abs().unwrap().max_all().unwrap();
                    assert!(d.to_vec0::<f32>().unwrap() < 1e-4, "{:?}", v.shape());
                }
                (None, None) => {} // the biases: the chain does not depend on them
                (a, b) => panic!("gradient present {} vs {}", a.is_some(), b.is_some()),
            }
        }
    }

    /// The penalty's chain on the first columns only is the full chain's first columns, and
    /// its weight gradients (the double backward) are the full chain's when the loss reads only
    /// those columns, `W_0`'s other rows getting zeros; every net depth, bad widths refused.
    #[test]
    fn first_cols_chain_is_the_full_chain_narrowed() {
        let x: Vec<f32> = (0..35)
            .map(|i| ((i * 31 % 17) as f32 - 8.0) * 0.2)
            .collect();
        let x = Tensor::from_vec(x, (5, 7), &Device::Cpu).unwrap();
        for widths in [vec![7, 1], vec![7, 9, 1], vec![7, 9, 8, 1]] {
            let net = Mlp::new(&widths, &mut ChaCha8Rng::seed_from_u64(3)).unwrap();
            let full = input_gradient(&net, &x).unwrap().narrow(1, 0, 4).unwrap();
            let first = input_gradient_first_cols(&net, (&x).into(), 4).unwrap();
            assert_eq!(first.dims(), &[5, 4]);
            let d = (&full - &first).unwrap().abs().unwrap().max_all().unwrap();
            assert!(d.to_vec0::<f32>().unwrap() < 1e-6, "{widths:?}");
            let loss = |g: Tensor| g.sqr().unwrap().sum_all().unwrap().backward().unwrap();
            let (a, b) = (loss(full), loss(first));
            for v in net.vars() {
                match (a.get(v.as_tensor()), b.get(v.as_tensor())) {
                    (Some(a), Some(b)) => {
                        let d = (a - b).unwrap().abs().unwrap().max_all().unwrap();
                        assert!(
                            d.to_vec0::<f32>().unwrap() < 1e-5,
                            "{widths:?} {:?}",
                            v.shape()
                        );
                    }
                    (None, None) => {}
                    (a, b) => panic!("gradient present {} vs {}", a.is_some(), b.is_some()),
                }
            }
            assert!(input_gradient_first_cols(&net, (&x).into(), 0).is_err());
            assert!(input_gradient_first_cols(&net, (&x).into(), 8).is_err());
        }
    }
}
