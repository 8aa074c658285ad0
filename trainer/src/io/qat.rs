//! Quantization-aware fine-tuning of a meta-policy's actor before its int8 export (issue 59,
//! item 3's last step), with a straight-through estimator.
//!
//! Post-training quantization rounds each weight to its row's int8 grid
//! (`w_q = s round(w / s)`, `s = max|w_row| / 127`, [`infer_core`]'s writer) and each hidden
//! activation of a `w8a8` layer to `0..=255` steps of its calibrated range. The rounding is
//! blind: each weight goes to its nearest grid point whatever the others did, and the errors
//! add up along the layers (measured on MuJoCo's cheetah SMILe + BC: the `w8a32` blob alone is
//! +4.1% on the task's metric, docs/DEVICE.md).
//!
//! Here the actor is trained *through* that rounding so that its quantized self acts as the
//! float policy does. The loss is the distance between the quantized actor's deterministic
//! action and the float actor's, on the states the policy meets (the meta-train demos' and,
//! optionally, its own closed loop's), each with its own task's latent:
//!
//! `L = E_(s, z) || tanh(mu_q(s, z)) - tanh(mu(s, z)) ||^2`
//!
//! where `mu_q` runs every layer with fake-quantized weights and the `w8a8` layers (all but
//! the first and last, as the blob deploys them: [`default_edges`](super::export::default_edges))
//! with fake-quantized inputs. Rounding has no gradient; the straight-through estimator
//! (Bengio et al. 2013) passes it through as the identity: `w_ste = w + sg(w_q - w)`, whose
//! value is `w_q` and whose gradient is that of `w`. The float weights move a little so that
//! their grid points land better; the blob is then written from them as from any policy.
//!
//! The context encoder is left as it is: it runs once per teaching, in `w8a32` (its latent
//! moves 0.02 at most on the cheetah). Only the actor's mean rows matter (the blob keeps no
//! log-sigma), so the loss reads them alone.

use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng};
use sim::DemoDataset;

use super::export::closed_loop_states;
use crate::error::{Error, Result};
use crate::model::{MetaPolicy, Mlp};
use crate::optim::{Adam, AdamConfig};

/// How the quantization-aware fine-tune runs.
#[derive(Debug, Clone, PartialEq)]
pub struct QatConfig {
    /// Adam steps (at least 1).
    pub steps: usize,
    /// Adam's learning rate at the first step, decaying linearly to zero at the last: small,
    /// the float weights should move by about one grid step.
    pub lr: f32,
    /// States per step.
    pub batch: usize,
    /// Seed of the batch sampling.
    pub seed: u64,
    /// The plant and episode count of the policy's own closed loop on each meta-train task,
    /// whose states join the demos' (none: the demos' states only).
    pub closed_loop: Option<(sim::EnvConfig, usize)>,
}

impl QatConfig {
    /// `steps` steps with the defaults measured on MuJoCo's cheetah (docs/DEVICE.md, step 4):
    /// Adam from 1e-4, 256 states per step, seed 0, the demos' states and one closed-loop episode per task.
    pub fn new(steps: usize, env: sim::EnvConfig) -> Self {
        Self {
            steps,
            lr: 1e-4,
            batch: 256,
            seed: 0,
            closed_loop: Some((env, 1)),
        }
    }
}

/// What the fine-tune did: the loss of the quantized actor before and after, on every state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct QatReport {
    /// States (and their tasks' latents) the actor was fine-tuned on.
    pub states: usize,
    /// Adam steps taken.
    pub steps: usize,
    /// Mean over states and action dimensions of `|a_q - a|` before the fine-tune.
    pub action_mean_abs_diff_before: f32,
    /// The same after (the best of the periodic checks, whose weights are returned).
    pub action_mean_abs_diff_after: f32,
}

/// `mp` with its actor fine-tuned so that its int8 export acts as its float self (the module
/// doc); `demos` are meta-train demos of its family and plant. Deterministic for a seed.
pub fn quantization_aware(
    mp: &MetaPolicy,
    demos: &DemoDataset,
    cfg: &QatConfig,
) -> Result<(MetaPolicy, QatReport)> {
    if cfg.steps == 0 || cfg.batch == 0 || cfg.lr.is_nan() || cfg.lr <= 0.0 {
        return Err(Error::Config(format!(
            "quantization-aware fine-tune: steps {}, batch {} and learning rate {} must be > 0",
            cfg.steps, cfg.batch, cfg.lr
        )));
    }
    super::export::check_demos_fit(mp, demos, "the fine-tune's demos")?;
    let rows = inputs(mp, demos, cfg.closed_loop)?;
    let n = rows.dim(0)?;
    let act_dim = mp.policy.act_dim();
    let teacher = mp.policy.net();
    let target = teacher
        .forward(&rows)?
        .narrow(1, 0, act_dim)?
        .tanh()?
        .detach();
    let ranges = hidden_ranges(teacher, &rows)?;
    let student = teacher.deep_copy()?;
    let error = |net: &Mlp| -> Result<f32> {
        let a = quantized_forward(net, &rows, &ranges)?
            .narrow(1, 0, act_dim)?
            .tanh()?;
        Ok((a - &target)?.abs()?.mean_all()?.to_scalar::<f32>()?)
    };
    let before = error(&student)?;
    let (mut best, mut best_params) = (before, params(&student)?);
    let mut adam = Adam::new(student.vars().to_vec(), AdamConfig::with_lr(cfg.lr));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.seed);
    let check_every = cfg.steps.div_ceil(10);
    for step in 1..=cfg.steps {
        let idx: Vec<u32> = (0..cfg.batch)
            .map(|_| rng.random_range(0..n as u32))
            .collect();
        let idx = Tensor::from_vec(idx, cfg.batch, &Device::Cpu)?;
        let x = rows.index_select(&idx, 0)?;
        let a = quantized_forward(&student, &x, &ranges)?
            .narrow(1, 0, act_dim)?
            .tanh()?;
        // L = E || tanh(mu_q(s, z)) - tanh(mu(s, z)) ||^2, straight through the rounding
        let loss = (a - target.index_select(&idx, 0)?)?.sqr()?.mean_all()?;
        // The step decays linearly to zero: at a constant rate the weights keep hopping
        // across grid points and the quantized actor never settles.
        adam.set_lr(cfg.lr * (1.0 - (step - 1) as f32 / cfg.steps as f32));
        adam.backward_step(&loss)?;
        if step % check_every == 0 || step == cfg.steps {
            let e = error(&student)?;
            if e < best {
                (best, best_params) = (e, params(&student)?);
            }
        }
    }
    let policy = mp.policy.deep_copy()?;
    policy.net().load_from(&best_params)?;
    let tuned = MetaPolicy {
        policy,
        ..mp.clone()
    };
    let report = QatReport {
        states: n,
        steps: cfg.steps,
        action_mean_abs_diff_before: before,
        action_mean_abs_diff_after: best,
    };
    Ok((tuned, report))
}

/// The weights of `net` in their own storage.
fn params(net: &Mlp) -> Result<Vec<Tensor>> {
    net.vars()
        .iter()
        .map(|v| Ok(v.as_tensor().detach().copy()?))
        .collect()
}

/// The actor's input rows `[normalised s, z]`: every state of each task's demos, and of the
/// policy's closed loop on the task if asked, with the latent of all the task's demos.
fn inputs(
    mp: &MetaPolicy,
    demos: &DemoDataset,
    closed_loop: Option<(sim::EnvConfig, usize)>,
) -> Result<Tensor> {
    let od = demos.obs_dim;
    let mut rows: Vec<f32> = Vec::new();
    let mut plant = match closed_loop {
        Some((env, _)) => Some(sim::make_env(mp.family, env)?),
        None => None,
    };
    for (t, td) in demos.tasks.iter().enumerate() {
        let context: Vec<&sim::Trajectory> = td.trajectories.iter().collect();
        let z = mp.latent(&context)?;
        let mut push = |obs: &[f32]| {
            mp.norm.push(obs, &mut rows);
            rows.extend_from_slice(&z);
        };
        td.trajectories
            .iter()
            .flat_map(|tr| tr.obs.chunks_exact(od))
            .for_each(&mut push);
        if let (Some(plant), Some((_, episodes))) = (plant.as_mut(), closed_loop) {
            let visited = closed_loop_states(mp, plant.as_mut(), t, &td.task, &z, episodes)?;
            visited.iter().for_each(|obs| push(obs));
        }
    }
    let width = od + mp.z_dim();
    let n = rows.len() / width;
    Ok(Tensor::from_vec(rows, (n, width), &Device::Cpu)?)
}

/// The widest value entering each layer of `net` on `rows` (the first layer's entry unused):
/// the range a `w8a8` hidden layer's input is calibrated to, as the blob writer does.
fn hidden_ranges(net: &Mlp, rows: &Tensor) -> Result<Vec<f32>> {
    let mut ranges = vec![0.0];
    let mut h = rows.clone();
    let layers = net.vars().chunks_exact(2).count();
    for (l, wb) in net.vars().chunks_exact(2).enumerate() {
        h = h
            .matmul(wb[0].as_tensor())?
            .broadcast_add(wb[1].as_tensor())?;
        if l + 1 < layers {
            h = h.relu()?;
            ranges.push(h.max_all()?.to_scalar::<f32>()?);
        }
    }
    Ok(ranges)
}

/// `net` on `x` as its int8 blob runs it: every weight on its row's int8 grid, and the input
/// of every layer but the first and last on 255 steps of its range (`ranges`), both straight
/// through for the gradient.
fn quantized_forward(net: &Mlp, x: &Tensor, ranges: &[f32]) -> Result<Tensor> {
    let layers = net.vars().chunks_exact(2).count();
    let mut h = x.clone();
    for (l, wb) in net.vars().chunks_exact(2).enumerate() {
        let (w, b) = (wb[0].as_tensor(), wb[1].as_tensor());
        if l > 0 && l + 1 < layers && ranges[l] > 0.0 {
            let s = f64::from(ranges[l]) / 255.0;
            let q = (h.affine(1.0 / s, 0.0)?.clamp(0.0, 255.0)?.round()? * s)?;
            h = (&h + (q - &h)?.detach())?;
        }
        // Weights are stored (in, out): one int8 row of the blob is one column here.
        let s = (w.abs()?.max_keepdim(0)? / 127.0)?.clamp(f32::MIN_POSITIVE, f32::MAX)?;
        let wq = (w.broadcast_div(&s)?.round()?.broadcast_mul(&s))?;
        let w_ste = (w + (wq - w)?.detach())?;
        h = h.matmul(&w_ste)?.broadcast_add(b)?;
        if l + 1 < layers {
            h = h.relu()?;
        }
    }
    Ok(h)
}
