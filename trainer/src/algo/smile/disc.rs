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
pub struct DiscBatch {
    pub(super) context: ContextBatch,
    x_expert: Tensor,
    x_policy: Tensor,
    tasks: usize,
    per_task: usize,
}

impl DiscBatch {
    /// A batch from encoder inputs and row-major `x` rows (`tasks * per_task` each).
    pub fn new(
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
pub struct DiscLearner<'a> {
    /// The context encoder (trained only through this loss).
    pub encoder: &'a ContextEncoder,
    /// The discriminator.
    pub disc: &'a Discriminator,
    /// The discriminator's optimiser (betas (0, 0.999) in the authors' recipe).
    pub disc_opt: &'a mut Adam,
    /// The encoder's optimiser.
    pub enc_opt: &'a mut Adam,
    /// The gradient penalty's weight (`gp_weight`).
    pub gp_weight: f32,
}

/// One discriminator + encoder update on `batch` (shared by [`Smile::disc_step`] and
/// `smile bench --workload disc`); `update` only names the step in a non-finite-loss error.
pub fn disc_update(
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
///
/// `L_bce` and `L_gp` share no node but the discriminator's weights (the penalty's `z` is
/// detached), so their gradients come from separate backward passes, added afterwards: inside
/// a learner pool they run as the sides of joins ([`crate::threads::join`]), which a free core
/// can take whole instead of only the blocks of their matrix products. Deterministic for a
/// thread count; one thread and a pool differ in the last bits (the penalty's split).
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
    // The penalty's mixing weights, drawn before the two halves split (a fixed draw order).
    let u = if gp_weight > 0.0 {
        let u: Vec<f32> = (0..rows).map(|_| rng.random::<f32>()).collect();
        Some(Tensor::from_vec(u, (rows, 1), &Device::Cpu)?)
    } else {
        None
    };
    // Inside a learner pool the penalty is two halves of the tasks (a mean over rows is the
    // halves' means weighted by their rows), pieces a free core can take whole: 2% off a
    // two-thread pair at the authors' shapes. One thread keeps it whole (1% faster there).
    let half = if crate::threads::in_pool() {
        (batch.tasks / 2) * batch.per_task
    } else {
        rows
    };
    let gp_part = |start: usize, len: usize| -> Result<Option<(GradStore, f32)>> {
        match &u {
            Some(u) if len > 0 => {
                gp_grads(disc, batch, &z_rows, u, (start, len), gp_weight, update).map(Some)
            }
            _ => Ok(None),
        }
    };
    let (bce, (gp_a, gp_b)) = crate::threads::join(
        || bce_grads(disc, batch, &z_rows, update),
        || crate::threads::join(|| gp_part(0, half), || gp_part(half, rows - half)),
    );
    let (mut grads, bce_v, lg) = bce?;
    let mut gp_v = 0.0;
    for (gp_grads, v) in [gp_a?, gp_b?].into_iter().flatten() {
        // dL_D/dtheta = dL_bce/dtheta + lambda_gp dL_gp/dtheta
        grads.extend(gp_grads)?;
        gp_v += v; // each share was checked finite before its backward
    }
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

/// `L_bce`'s gradients (discriminator and encoder), its value and the batch's logits.
fn bce_grads(
    disc: &Discriminator,
    batch: &DiscBatch,
    z_rows: &Tensor,
    update: u64,
) -> Result<(GradStore, f32, Vec<f32>)> {
    let rows = batch.tasks * batch.per_task;
    let inp = Tensor::cat(
        &[
            &Tensor::cat(&[&batch.x_expert, z_rows], 1)?,
            &Tensor::cat(&[&batch.x_policy, z_rows], 1)?,
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
    let v = finite("losses/disc_bce", scalar(&bce)?, update)?;
    let grads = bce.backward()?;
    Ok((grads, v, logits.detach().flatten_all()?.to_vec1::<f32>()?))
}

/// The gradients of `lambda_gp L_gp`'s share from the rows `(start, len)` (the
/// discriminator's only) and that share of `L_gp`.
fn gp_grads(
    disc: &Discriminator,
    batch: &DiscBatch,
    z_rows: &Tensor,
    u: &Tensor,
    (start, len): (usize, usize),
    gp_weight: f32,
    update: u64,
) -> Result<(GradStore, f32)> {
    // L_gp = mean[(||dD/dx~|| - 1)^2], x~ = u x_E + (1 - u) x_pi, z detached; these rows'
    // share of it is their mean times len / rows.
    let share = len as f64 / (batch.tasks * batch.per_task) as f64;
    let rows = |t: &Tensor| t.narrow(0, start, len);
    let gp = (disc.gradient_penalty(
        &rows(&batch.x_expert)?,
        &rows(&batch.x_policy)?,
        &rows(z_rows)?,
        &rows(u)?,
        Some(batch.per_task),
    )? * share)?;
    let v = finite("losses/disc_gp", scalar(&gp)?, update)?;
    Ok(((gp * gp_weight as f64)?.backward()?, v))
}

/// `v`, or the non-finite-loss error naming `what` and the update.
fn finite(what: &'static str, v: f32, update: u64) -> Result<f32> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::NonFinite {
            what,
            value: v,
            update,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ContextConfig, ContextSpec, DiscInput, ObsNorm};
    use crate::threads::LearnerPool;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A small encoder, discriminator and batch of random rows (3 tasks x 8 rows).
    fn setup() -> (ContextEncoder, Discriminator, DiscBatch) {
        let (od, ad, tasks, per_task) = (5, 2, 3, 8);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let cfg = ContextConfig {
            enc_hidden: vec![16],
            r_dim: 8,
            z_dim: 4,
            head_hidden: vec![],
            stochastic_z: false,
            ..ContextConfig::default()
        };
        let encoder = ContextEncoder::new(od, ad, cfg, &mut rng).unwrap();
        let disc = Discriminator::new(od, ad, 4, &[32, 32], DiscInput::StateAction, 10.0, &mut rng)
            .unwrap();
        let mut normal = |n: usize| -> Vec<f32> {
            (0..n)
                .map(|_| rng.sample::<f32, _>(rand_distr::StandardNormal))
                .collect()
        };
        let trajs: Vec<sim::Trajectory> = (0..tasks * 2)
            .map(|_| {
                let mut t = sim::Trajectory::new(0);
                for i in 0..4 {
                    let (o, a, n) = (normal(od), normal(ad), normal(od));
                    let tr = sim::TransitionRef {
                        obs: &o,
                        action: &a,
                        reward: 0.0,
                        next_obs: &n,
                        done: false,
                    };
                    t.push(i, tr);
                }
                t
            })
            .collect();
        let (xe, xp) = (
            normal(tasks * per_task * (od + ad)),
            normal(tasks * per_task * (od + ad)),
        );
        let specs: Vec<ContextSpec<'_>> = trajs
            .chunks(2)
            .map(|c| ContextSpec::all(c.iter().collect()))
            .collect();
        let context = encoder.batch(&ObsNorm::identity(od), &specs).unwrap();
        let batch = DiscBatch::new(context, xe, xp, tasks, per_task).unwrap();
        (encoder, disc, batch)
    }

    /// Every variable's gradient in `g`, flattened, in the networks' order.
    fn flat(g: &GradStore, enc: &ContextEncoder, disc: &Discriminator) -> Vec<Vec<f32>> {
        enc.vars()
            .iter()
            .chain(disc.vars().iter())
            .map(|v| {
                g.get(v.as_tensor())
                    .expect("every variable has a gradient")
                    .flatten_all()
                    .unwrap()
                    .to_vec1::<f32>()
                    .unwrap()
            })
            .collect()
    }

    #[test]
    fn split_gradients_are_one_backward_of_the_sum_and_repeat_per_thread_count() {
        let (enc, disc, batch) = setup();
        let gp_w = 10.0;
        let grads = |threads: usize| {
            let pool = LearnerPool::new(threads).unwrap();
            pool.install(|| {
                let mut rng = ChaCha8Rng::seed_from_u64(3);
                let (g, s) = disc_grads(&enc, &disc, gp_w, &batch, 1, &mut rng).unwrap();
                (flat(&g, &enc, &disc), s)
            })
        };
        let (g1, s1) = grads(1);
        // Two learner threads: the halves run as joins (the penalty in two pieces); the same
        // bits every time.
        let (g2, s2) = grads(2);
        assert_eq!(g2, grads(2).0);
        assert_eq!(g1, grads(1).0);
        assert!(s1.gp > 0.0 && s1.bce > 0.0);
        assert_eq!(s1.bce, s2.bce);
        assert!((s1.gp - s2.gp).abs() <= 1e-5 * s1.gp);

        // The reference: L_D = L_bce + lambda L_gp in one graph, one backward, the same draws
        // (z first, then u).
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let rows = batch.tasks * batch.per_task;
        let z_rows = batch
            .z_rows(&enc.z(&batch.context, true, &mut rng).unwrap())
            .unwrap();
        let u: Vec<f32> = (0..rows).map(|_| rng.random::<f32>()).collect();
        let u = Tensor::from_vec(u, (rows, 1), &Device::Cpu).unwrap();
        let inp = Tensor::cat(
            &[
                &Tensor::cat(&[&batch.x_expert, &z_rows], 1).unwrap(),
                &Tensor::cat(&[&batch.x_policy, &z_rows], 1).unwrap(),
            ],
            0,
        )
        .unwrap();
        let logits = disc.logits(Input::from(&inp)).unwrap();
        let labels = Tensor::cat(
            &[
                Tensor::ones((rows, 1), DType::F32, &Device::Cpu).unwrap(),
                Tensor::zeros((rows, 1), DType::F32, &Device::Cpu).unwrap(),
            ],
            0,
        )
        .unwrap();
        let bce = bce_with_logits(&logits, &labels).unwrap();
        let gp = disc
            .gradient_penalty(&batch.x_expert, &batch.x_policy, &z_rows, &u, None)
            .unwrap();
        assert!((scalar(&gp).unwrap() - s1.gp).abs() <= 1e-5 * s1.gp);
        let reference = (bce + (gp * gp_w as f64).unwrap())
            .unwrap()
            .backward()
            .unwrap();
        let reference = flat(&reference, &enc, &disc);
        for g in [&g1, &g2] {
            for (a, b) in g.iter().flatten().zip(reference.iter().flatten()) {
                assert!((a - b).abs() <= 1e-4 * (1.0 + b.abs()), "{a} vs {b}");
            }
        }
    }
}
