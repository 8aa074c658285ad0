//! Discriminator losses of adversarial imitation (SMILe's AIRL discriminator), each next to
//! the equation it implements:
//!
//! ```text
//! L_bce = mean[ softplus(l) - y l ]                            (BCE with logits, l = logit)
//! x~ = u x_E + (1 - u) x_pi,  u ~ U(0, 1) per sample,  z detached
//! L_gp = mean[ (|| d D(x~, z) / d x~ || - 1)^2 ]               (WGAN-GP form)
//! ```

use candle_core::{DType, Device, Tensor};

use crate::Result;
use crate::nn::Mlp;

/// `dD/dx` of a ReLU MLP with a scalar output, per row, as a differentiable function of the
/// weights (for the gradient penalty; candle has no double backward through our fused
/// layers). With row-vector layers `h_{l+1} = relu(h_l W_l + b_l)`:
/// `g = (((1 W_L^T) . m_{L-1}) W_{L-1}^T . ... . m_0) W_0^T`, where `m_l = 1[pre-activation > 0]`
/// (constants: ReLU's second derivative is zero almost everywhere, so this equals PyTorch's
/// `create_graph=True` gradient).
pub fn input_gradient(net: &Mlp, x: &Tensor) -> Result<Tensor> {
    let vars = net.vars();
    let n = vars.len() / 2;
    let mut masks = Vec::with_capacity(n - 1);
    let mut h = x.detach();
    for l in 0..n - 1 {
        let pre = h
            .matmul(&vars[2 * l].as_tensor().detach())?
            .broadcast_add(&vars[2 * l + 1].as_tensor().detach())?;
        masks.push(pre.gt(0.0)?.to_dtype(DType::F32)?);
        h = pre.relu()?;
    }
    let rows = x.dim(0)?;
    let w_last = vars[2 * (n - 1)].as_tensor(); // (h, 1)
    let mut g = Tensor::ones((rows, 1), DType::F32, &Device::Cpu)?.matmul(&w_last.t()?)?;
    for l in (0..n - 1).rev() {
        g = (g * &masks[l])?.matmul(&vars[2 * l].as_tensor().t()?)?;
    }
    Ok(g)
}

/// BCE with logits, `mean[max(l, 0) - l y + ln(1 + e^{-|l|})]`.
pub fn bce_with_logits(logits: &Tensor, labels: &Tensor) -> Result<Tensor> {
    let softplus = (logits.relu()? + logits.abs()?.neg()?.exp()?.affine(1.0, 1.0)?.log()?)?;
    Ok((softplus - (logits * labels)?)?.mean_all()?)
}

/// `L_gp = mean[(||dD([x~, z])/dx~|| - 1)^2]` with `x~ = u x_E + (1 - u) x_pi` per row; `z`
/// is detached (the penalty does not train the encoder) and the gradient is taken with
/// respect to `x~` only.
pub fn gradient_penalty(
    net: &Mlp,
    x_expert: &Tensor,
    x_policy: &Tensor,
    z: &Tensor,
    u: &Tensor,
) -> Result<Tensor> {
    let xd = x_expert.dim(1)?;
    let x_mix = (x_expert.broadcast_mul(u)? + x_policy.broadcast_mul(&u.affine(-1.0, 1.0)?)?)?;
    let mix = Tensor::cat(&[&x_mix, &z.detach()], 1)?;
    let g = input_gradient(net, &mix)?.narrow(1, 0, xd)?;
    let norm = (g.sqr()?.sum_keepdim(1)? + 1e-12)?.sqrt()?;
    Ok((norm - 1.0)?.sqr()?.mean_all()?)
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
}
