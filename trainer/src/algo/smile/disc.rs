//! The discriminator + encoder update of SMILe (the loss is in the parent module's doc and in
//! [`crate::model::Discriminator`]): its batch, what it changes, and the step itself, shared by
//! [`super::Smile::disc_step`], the second learner thread (`overlap`) and `smile bench`.

use candle_core::backprop::GradStore;
use candle_core::{DType, Device, Tensor};
use rand::Rng;

use crate::error::{Error, Result};
use crate::model::scalar;
use crate::model::{
    ContextBatch, ContextEncoder, DiscStats, Discriminator, Input, SharedCols, bce_with_logits,
};
use crate::optim::Adam;

/// One discriminator batch: `tasks` tasks, each with a context and `per_task` expert and
/// `per_task` policy rows of `x` (row `r` belongs to task `r / per_task`).
pub(crate) struct DiscBatch {
    pub(super) context: ContextBatch,
    x_expert: Tensor,
    x_policy: Tensor,
    tasks: usize,
    per_task: usize,
}

impl DiscBatch {
    /// A batch from encoder inputs and row-major `x` rows (`tasks * per_task` each).
    pub(crate) fn new(
        context: ContextBatch,
        x_expert: Vec<f32>,
        x_policy: Vec<f32>,
        tasks: usize,
        per_task: usize,
    ) -> Result<Self> {
        let rows = tasks * per_task;
        let x_dim = x_expert.len() / rows.max(1);
        Ok(Self {
            context,
            x_expert: Tensor::from_vec(x_expert, (rows, x_dim), &Device::Cpu)?,
            x_policy: Tensor::from_vec(x_policy, (rows, x_dim), &Device::Cpu)?,
            tasks,
            per_task,
        })
    }

    /// Each task's `z` (rows of `z`, shape `(tasks, z)`) repeated for its rows, through a
    /// one-hot matrix so that gradients flow back into `z`.
    pub(super) fn z_rows(&self, z: &Tensor) -> Result<Tensor> {
        let (t, n) = (self.tasks, self.per_task);
        let mut onehot = vec![0.0f32; t * n * t];
        for r in 0..t * n {
            onehot[r * t + r / n] = 1.0;
        }
        Ok(Tensor::from_vec(onehot, (t * n, t), &Device::Cpu)?.matmul(z)?)
    }
}

/// What one discriminator + encoder update changes: the networks and their optimisers.
pub(crate) struct DiscLearner<'a> {
    pub encoder: &'a ContextEncoder,
    pub disc: &'a Discriminator,
    pub disc_opt: &'a mut Adam,
    pub enc_opt: &'a mut Adam,
    pub gp_weight: f32,
}

/// One discriminator + encoder update on `batch` (shared by [`Smile::disc_step`] and
/// `smile bench --workload disc`); `update` only names the step in a non-finite-loss error.
pub(crate) fn disc_update(
    l: DiscLearner<'_>,
    batch: &DiscBatch,
    update: u64,
    rng: &mut impl Rng,
) -> Result<DiscStats> {
    let (grads, stats) = disc_grads(l.encoder, l.disc, l.gp_weight, batch, update, rng)?;
    // One backward pass, two optimisers: the discriminator (betas (0, 0.999)) and the
    // encoder (trained only through this loss).
    l.disc_opt.step(&grads)?;
    l.enc_opt.step(&grads)?;
    Ok(stats)
}

/// The loss `L_D` of one discriminator + encoder update and its gradients, the networks only
/// read (an overlapped pair computes them while the SAC side reads the same networks for its
/// reward, and steps the optimisers after both sides are done).
pub(crate) fn disc_grads(
    encoder: &ContextEncoder,
    disc: &Discriminator,
    gp_weight: f32,
    batch: &DiscBatch,
    update: u64,
    rng: &mut impl Rng,
) -> Result<(GradStore, DiscStats)> {
    let rows = batch.tasks * batch.per_task;
    let z = encoder.z(&batch.context, true, rng)?; // (t, z), gradient into the encoder
    let z_rows = batch.z_rows(&z)?; // (t n, z)
    let inp = Tensor::cat(
        &[
            &Tensor::cat(&[&batch.x_expert, &z_rows], 1)?,
            &Tensor::cat(&[&batch.x_policy, &z_rows], 1)?,
        ],
        0,
    )?;
    // (2 t n, 1): expert rows, then policy rows; each task's z on its n rows of each half, so
    // the first layer computes the z block once per n rows.
    let zd = z_rows.dim(1)?;
    let shared = SharedCols {
        start: inp.dim(1)? - zd,
        len: zd,
        group_rows: batch.per_task,
    };
    let logits = disc.logits(Input::shared(&inp, Some(shared)))?;
    let labels = Tensor::cat(
        &[
            Tensor::ones((rows, 1), DType::F32, &Device::Cpu)?,
            Tensor::zeros((rows, 1), DType::F32, &Device::Cpu)?,
        ],
        0,
    )?;
    // L_bce = mean[softplus(l) - y l]
    let bce = bce_with_logits(&logits, &labels)?;
    // L_gp = mean[(||dD/dx~|| - 1)^2], x~ = u x_E + (1 - u) x_pi, z detached
    let mut loss = bce.clone();
    let mut gp_v = 0.0;
    if gp_weight > 0.0 {
        let u: Vec<f32> = (0..rows).map(|_| rng.random::<f32>()).collect();
        let u = Tensor::from_vec(u, (rows, 1), &Device::Cpu)?;
        let gp = disc.gradient_penalty(
            &batch.x_expert,
            &batch.x_policy,
            &z_rows,
            &u,
            Some(batch.per_task),
        )?;
        gp_v = scalar(&gp)?;
        // L_D = L_bce + lambda_gp L_gp
        loss = (loss + (gp * gp_weight as f64)?)?;
    }
    let bce_v = scalar(&bce)?;
    for (what, v) in [("losses/disc_bce", bce_v), ("losses/disc_gp", gp_v)] {
        if !v.is_finite() {
            return Err(Error::NonFinite {
                what,
                value: v,
                update,
            });
        }
    }
    let grads = loss.backward()?;
    let lg = logits.detach().flatten_all()?.to_vec1::<f32>()?;
    let acc_e = lg[..rows].iter().filter(|v| **v > 0.0).count() as f32 / rows as f32;
    let acc_p = lg[rows..].iter().filter(|v| **v < 0.0).count() as f32 / rows as f32;
    let stats = DiscStats {
        bce: bce_v,
        gp: gp_v,
        acc_expert: acc_e,
        acc_policy: acc_p,
    };
    Ok((grads, stats))
}
