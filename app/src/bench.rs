//! Learner micro-benchmarks, matching `docs/bench/pytorch/torch_reference.py`'s workloads, each
//! update timed on its own and the median reported:
//! - `sac`: one SAC-v2 update (critic, actor, temperature, targets) on a fixed random batch,
//!   obs 20 + z 16, act 6, two hidden layers of width H, batch 256 (any widths, depth, batch
//!   and z: [`SacBenchShape`]; the SMILe authors': 3 x 256 at batch 1024, z 64).
//! - `disc`: one context-encoder + discriminator update, SMILe's own code
//!   ([`trainer::smile`]): 8 tasks, each a context of 4 trajectories x 16 transitions
//!   `[s, a, s']` through the encoder MLP (H, H) -> r 32, mean over time, sum over
//!   trajectories, linear head -> z 16 (deterministic); discriminator MLP (H, H) on `[s, a, z]`
//!   for 128 expert + 128 policy rows per task; BCE with logits + 10 x gradient penalty on
//!   interpolated `(s, a)`; Adam. (Our head also outputs log-sigma: 32 instead of 16 outputs.)
//!   Any widths and depths: [`DiscBenchShape`]; the authors': discriminator 3 x 512, encoder
//!   2 x 256 -> r 64 -> z 64.
//!
//! Each shape also states the floating-point work of its matrix products
//! ([`SacBenchShape::flops`], [`DiscBenchShape::flops`]): the products the algorithm needs,
//! counted the same way for both sides (an implementation that skips an unneeded gradient is
//! not credited for it), so `flops / time` is the achieved GFLOP/s to set beside the
//! machine's single-core sgemm rate.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use trainer::BatchVecs;
use trainer::Result;
use trainer::sac::{Sac, SacConfig};
use trainer::smile::{DiscBatch, DiscLearner, disc_update};
use trainer::{Adam, AdamConfig};
use trainer::{ContextConfig, ContextEncoder, ContextSpec, DiscInput, Discriminator, ObsNorm};

/// Shape of the benchmarked SAC update.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SacBenchShape {
    /// Hidden widths of the critics and the policy (torch_reference: `--layers` x `--hidden`).
    pub hidden: Vec<usize>,
    /// Batch size.
    pub batch: usize,
    /// Observation dimension (the policy input is obs + z).
    pub obs_dim: usize,
    /// Context embedding dimension appended to the observation.
    pub z_dim: usize,
    /// Action dimension.
    pub act_dim: usize,
}

impl SacBenchShape {
    /// The torch reference's shape at width `hidden`: two layers, batch 256, obs 20, z 16,
    /// act 6.
    pub fn reference(hidden: usize) -> Self {
        Self::with_hidden(vec![hidden; 2])
    }

    /// The torch reference's batch and dimensions with these hidden widths.
    pub fn with_hidden(hidden: Vec<usize>) -> Self {
        Self {
            hidden,
            batch: 256,
            obs_dim: 20,
            z_dim: 16,
            act_dim: 6,
        }
    }

    /// The SMILe authors' SAC (issue "SMILe as its authors ran it"): 3 x 256 critics and
    /// policy at batch 1024 (8 tasks x 128), z 64; torch_reference's obs 20 and act 6.
    pub fn authors() -> Self {
        Self {
            batch: 1024,
            z_dim: 64,
            ..Self::with_hidden(vec![256; 3])
        }
    }

    /// Floating-point operations of the update's matrix products (multiply-add = 2): target
    /// (policy and both target critics forward on the next states), critic loss (both critics
    /// forward, weight and hidden gradients back), actor loss (policy forward, both critics
    /// forward and input gradients back, policy weight and hidden gradients back).
    pub fn flops(&self) -> f64 {
        let d_in = self.obs_dim + self.z_dim;
        let q = widths(d_in + self.act_dim, &self.hidden, 1);
        let pi = widths(d_in, &self.hidden, 2 * self.act_dim);
        let b = self.batch as f64;
        let fwd = |w: &[usize]| b * mlp_products(w);
        // backward: weight gradients everywhere, input gradients below the first layer
        let bwd_params =
            |w: &[usize]| b * (2.0 * mlp_products(w) - w[0] as f64 * w[1] as f64 * 2.0);
        // input gradients only (the critics in the actor loss): every layer's input gradient
        let bwd_input = |w: &[usize]| b * mlp_products(w);
        let target = fwd(&pi) + 2.0 * fwd(&q);
        let critic = 2.0 * (fwd(&q) + bwd_params(&q));
        let actor = fwd(&pi) + 2.0 * (fwd(&q) + bwd_input(&q)) + bwd_params(&pi);
        target + critic + actor
    }
}

/// `[d_in, hidden..., d_out]`.
fn widths(d_in: usize, hidden: &[usize], d_out: usize) -> Vec<usize> {
    let mut w = vec![d_in];
    w.extend_from_slice(hidden);
    w.push(d_out);
    w
}

/// `sum_l 2 w_l w_{l+1}`: the multiply-adds of one row through an MLP of these widths.
fn mlp_products(w: &[usize]) -> f64 {
    w.windows(2).map(|p| 2.0 * p[0] as f64 * p[1] as f64).sum()
}

/// Timing summary of one workload, in microseconds.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Timing {
    /// Median per-iteration time.
    pub median_us: f64,
    /// 10th percentile.
    pub p10_us: f64,
    /// 90th percentile.
    pub p90_us: f64,
    /// `1e6 / median_us`.
    pub updates_per_s: f64,
    /// Mean on-CPU time of the timing thread per iteration (Linux `schedstat`), which, unlike
    /// wall-clock, does not count time the thread waited for a core busy with other work.
    pub cpu_mean_us: Option<f64>,
}

/// Nanoseconds this thread has spent on a CPU (`/proc/thread-self/schedstat`), if available.
pub fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Time `f` `iters` times after `warmup` untimed calls.
pub fn time_it(warmup: usize, iters: usize, mut f: impl FnMut() -> Result<()>) -> Result<Timing> {
    for _ in 0..warmup {
        f()?;
    }
    let mut ts = Vec::with_capacity(iters.max(1));
    let cpu0 = thread_cpu_ns();
    for _ in 0..iters.max(1) {
        let t0 = Instant::now();
        f()?;
        ts.push(t0.elapsed().as_secs_f64() * 1e6);
    }
    let cpu_mean_us = match (cpu0, thread_cpu_ns()) {
        (Some(a), Some(b)) => Some((b - a) as f64 / 1e3 / ts.len() as f64),
        _ => None,
    };
    ts.sort_by(f64::total_cmp);
    let med = ts[ts.len() / 2];
    Ok(Timing {
        median_us: med,
        p10_us: ts[ts.len() / 10],
        p90_us: ts[9 * ts.len() / 10],
        updates_per_s: 1e6 / med,
        cpu_mean_us,
    })
}

/// A SAC agent and a fixed random batch of the given shape.
pub fn sac_fixture(shape: SacBenchShape, seed: u64) -> Result<(Sac, trainer::Batch, ChaCha8Rng)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d_in = shape.obs_dim + shape.z_dim;
    let cfg = SacConfig {
        hidden: shape.hidden.clone(),
        batch_size: shape.batch,
        ..Default::default()
    };
    let sac = Sac::new(d_in, shape.act_dim, cfg, &mut rng)?;
    let b = shape.batch;
    let normal = |rng: &mut ChaCha8Rng, n: usize| -> Vec<f32> {
        (0..n)
            .map(|_| rng.sample::<f32, _>(rand_distr::StandardNormal))
            .collect()
    };
    let v = BatchVecs {
        obs: normal(&mut rng, b * d_in),
        act: (0..b * shape.act_dim)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect(),
        rew: normal(&mut rng, b),
        next_obs: normal(&mut rng, b * d_in),
        done: vec![0.0; b],
        ..BatchVecs::default()
    };
    let batch = v.to_batch(d_in, shape.act_dim)?;
    Ok((sac, batch, rng))
}

/// Median time of one full SAC update at `shape`.
pub fn bench_sac_update(shape: SacBenchShape, warmup: usize, iters: usize) -> Result<Timing> {
    let (mut sac, batch, mut rng) = sac_fixture(shape, 0)?;
    time_it(warmup, iters, || sac.update(&batch, &mut rng).map(|_| ()))
}

/// Shape of the benchmarked discriminator + encoder update (torch_reference's `disc`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscBenchShape {
    /// Hidden widths of the discriminator (torch_reference: `--layers` x `--disc-hidden`).
    pub hidden: Vec<usize>,
    /// Hidden widths of the encoder's per-transition MLP (torch_reference: 2 x `--enc-hidden`).
    pub enc_hidden: Vec<usize>,
    /// Tasks per batch.
    pub tasks: usize,
    /// Context trajectories per task.
    pub ctx_trajs: usize,
    /// Transitions per context trajectory.
    pub ctx_len: usize,
    /// Expert (and as many policy) rows per task.
    pub samples: usize,
    /// Observation dimension.
    pub obs_dim: usize,
    /// Action dimension.
    pub act_dim: usize,
    /// Per-transition representation dimension.
    pub r_dim: usize,
    /// Latent dimension.
    pub z_dim: usize,
    /// Gradient-penalty weight.
    pub gp_weight: f32,
}

impl DiscBenchShape {
    /// torch_reference's defaults at width `hidden`: 8 tasks x 4 trajectories x 16 steps,
    /// 128 samples, obs 20, act 6, r 32, z 16, gradient penalty 10, two hidden layers in the
    /// discriminator and the encoder.
    pub fn reference(hidden: usize) -> Self {
        Self::with_hidden(vec![hidden; 2], vec![hidden; 2])
    }

    /// The SMILe authors' shapes: discriminator 3 x 512, encoder 2 x 256 -> r 64 -> z 64;
    /// torch_reference's batch and dimensions otherwise (2,048 discriminator rows).
    pub fn authors() -> Self {
        Self {
            r_dim: 64,
            z_dim: 64,
            ..Self::with_hidden(vec![512; 3], vec![256; 2])
        }
    }

    /// torch_reference's batch and dimensions with these discriminator and encoder widths.
    pub fn with_hidden(hidden: Vec<usize>, enc_hidden: Vec<usize>) -> Self {
        Self {
            hidden,
            enc_hidden,
            tasks: 8,
            ctx_trajs: 4,
            ctx_len: 16,
            samples: 128,
            obs_dim: 20,
            act_dim: 6,
            r_dim: 32,
            z_dim: 16,
            gp_weight: 10.0,
        }
    }

    /// Floating-point operations of the step's matrix products (multiply-add = 2): the
    /// encoder forward and back on every context transition (weight and hidden gradients;
    /// the head r -> z as torch_reference's, one linear layer); the discriminator forward and
    /// back on the expert and policy rows (input gradients too: z trains the encoder); the
    /// penalty's forward on the interpolates, its input-gradient chain `g W^T` down to the
    /// input, and that chain's backward (each product's operand and weight gradients).
    pub fn flops(&self) -> f64 {
        let x_dim = self.obs_dim + self.act_dim;
        let enc = widths(
            2 * self.obs_dim + self.act_dim,
            &self.enc_hidden,
            self.r_dim,
        );
        let ctx_rows = (self.tasks * self.ctx_trajs * self.ctx_len) as f64;
        let encoder = ctx_rows * (2.0 * mlp_products(&enc) - 2.0 * enc[0] as f64 * enc[1] as f64)
            + 3.0 * self.tasks as f64 * 2.0 * (self.r_dim * self.z_dim) as f64;
        let d = widths(x_dim + self.z_dim, &self.hidden, 1);
        let rows = (self.tasks * self.samples) as f64;
        let disc = 2.0 * rows * 3.0 * mlp_products(&d);
        // penalty: forward through the hidden layers, then the chain and its backward (three
        // products per weight matrix; the output layer's row is one product and its gradient)
        let hidden_products = mlp_products(&d[..d.len() - 1]);
        let last_hidden = d[d.len() - 2] as f64;
        let gp = rows * (4.0 * hidden_products + 2.0 * 2.0 * last_hidden);
        encoder + disc + gp
    }
}

/// The networks, optimisers and fixed random batch of one discriminator + encoder update at a
/// [`DiscBenchShape`]: what `smile bench --workload disc` and the criterion benchmark time.
pub struct DiscFixture {
    encoder: ContextEncoder,
    disc: Discriminator,
    disc_opt: Adam,
    enc_opt: Adam,
    batch: DiscBatch,
    rng: ChaCha8Rng,
    gp_weight: f32,
}

impl DiscFixture {
    /// The fixture of `shape`, every weight and row drawn from `seed`.
    pub fn new(shape: &DiscBenchShape, seed: u64) -> Result<Self> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (od, ad) = (shape.obs_dim, shape.act_dim);
        let cfg = ContextConfig {
            enc_hidden: shape.enc_hidden.clone(),
            r_dim: shape.r_dim,
            z_dim: shape.z_dim,
            head_hidden: vec![],
            stochastic_z: false,
            ..ContextConfig::default()
        };
        let encoder = ContextEncoder::new(od, ad, cfg, &mut rng)?;
        let disc = Discriminator::new(
            od,
            ad,
            shape.z_dim,
            &shape.hidden,
            DiscInput::StateAction,
            10.0,
            &mut rng,
        )?;
        let disc_opt = Adam::new(
            disc.vars().to_vec(),
            AdamConfig {
                beta1: 0.0,
                ..AdamConfig::with_lr(3e-4)
            },
        );
        let enc_opt = Adam::new(encoder.vars(), AdamConfig::with_lr(3e-4));
        let normal = |rng: &mut ChaCha8Rng, n: usize| -> Vec<f32> {
            (0..n)
                .map(|_| rng.sample::<f32, _>(rand_distr::StandardNormal))
                .collect()
        };
        let trajectories: Vec<sim::Trajectory> = (0..shape.tasks * shape.ctx_trajs)
            .map(|_| {
                let mut t = sim::Trajectory::new(0);
                for i in 0..shape.ctx_len {
                    let (o, a, n) = (
                        normal(&mut rng, od),
                        normal(&mut rng, ad),
                        normal(&mut rng, od),
                    );
                    t.push(
                        i as u32,
                        sim::TransitionRef {
                            obs: &o,
                            action: &a,
                            reward: 0.0,
                            next_obs: &n,
                            done: false,
                        },
                    );
                }
                t
            })
            .collect();
        let specs: Vec<ContextSpec<'_>> = trajectories
            .chunks(shape.ctx_trajs)
            .map(|c| ContextSpec::all(c.iter().collect()))
            .collect();
        let context = encoder.batch(&ObsNorm::identity(od), &specs)?;
        let rows = shape.tasks * shape.samples;
        let batch = DiscBatch::new(
            context,
            normal(&mut rng, rows * (od + ad)),
            normal(&mut rng, rows * (od + ad)),
            shape.tasks,
            shape.samples,
        )?;
        Ok(Self {
            encoder,
            disc,
            disc_opt,
            enc_opt,
            batch,
            rng,
            gp_weight: shape.gp_weight,
        })
    }

    /// One discriminator + encoder update on the fixed batch (SMILe's own step).
    pub fn step(&mut self) -> Result<()> {
        let learner = DiscLearner {
            encoder: &self.encoder,
            disc: &self.disc,
            disc_opt: &mut self.disc_opt,
            enc_opt: &mut self.enc_opt,
            gp_weight: self.gp_weight,
        };
        disc_update(learner, &self.batch, 0, &mut self.rng).map(|_| ())
    }
}

/// Median time of one discriminator + encoder update at `shape` on a fixed random batch.
pub fn bench_disc_step(shape: DiscBenchShape, warmup: usize, iters: usize) -> Result<Timing> {
    let mut fixture = DiscFixture::new(&shape, 0)?;
    time_it(warmup, iters, || fixture.step())
}

/// Per-pair timing of whole SMILe iterations (`smile bench --workload pair`).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PairTiming {
    /// Median wall time of one iteration (rollouts + update pairs) divided by its pairs: what
    /// `charts/sps` measures in training (`1e6 / per_pair_us` pairs per second).
    pub per_pair_us: f64,
    /// Median wall time of the iteration less the time the learner's thread spent on
    /// rollouts, per pair (`IterationReport::rollout_s`): the update pairs alone, what the
    /// PyTorch prototype's `ms_per_upd` measures. With two or more learner threads the
    /// rollouts run beside the pairs, which then take longer than they would alone.
    pub updates_only_per_pair_us: f64,
    /// `1e6 / per_pair_us`.
    pub pairs_per_s: f64,
    /// Timed iterations.
    pub iterations: usize,
}

/// Times whole SMILe iterations of `cfg` on `demos` after a warm start and `warmup` untimed
/// iterations: `cfg.rollouts_per_iter` rollouts in random training tasks, then
/// `cfg.updates_per_iter` update pairs (one discriminator + encoder step, one SAC step).
pub fn bench_smile_pairs(
    cfg: trainer::smile::SmileConfig,
    demos: &sim::DemoDataset,
    warmup: usize,
    iters: usize,
) -> Result<PairTiming> {
    let family = cfg.env;
    let data = trainer::MetaData::from_dataset(demos, family, cfg.holdout_every)?;
    let pairs = cfg.updates_per_iter.max(1);
    // Every timed iteration runs all its pairs, whatever the config's training length.
    let cfg = trainer::smile::SmileConfig {
        total_updates: trainer::MAX_STEPS,
        ..cfg
    };
    let mut run = trainer::smile::Smile::new(cfg, data)?;
    run.warm_start()?;
    // The training loop's own iteration (`Smile::iteration`): with two or more learner
    // threads its rollouts run beside the pairs.
    let iteration = |run: &mut trainer::smile::Smile| -> Result<(f64, f64)> {
        let t0 = Instant::now();
        let report = run.iteration(&mut |_| {})?;
        let all = t0.elapsed().as_secs_f64();
        Ok((all, all - report.rollout_s))
    };
    for _ in 0..warmup {
        iteration(&mut run)?;
    }
    let (mut all, mut upd) = (Vec::new(), Vec::new());
    for _ in 0..iters.max(1) {
        let (a, u) = iteration(&mut run)?;
        all.push(a);
        upd.push(u);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let per_pair_us = median(&mut all) * 1e6 / pairs as f64;
    Ok(PairTiming {
        per_pair_us,
        updates_only_per_pair_us: median(&mut upd) * 1e6 / pairs as f64,
        pairs_per_s: 1e6 / per_pair_us,
        iterations: all.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The work counts, by hand on one-row shapes.
    #[test]
    fn flops_count_every_product_the_steps_need() {
        // critics [3, 4, 1], policy [2, 4, 2]: 32 flops per row each; target 32 + 2 x 32,
        // critic loss 2 x (32 + 64 - 24), actor 32 + 2 x (32 + 32) + (64 - 16)
        let sac = SacBenchShape {
            hidden: vec![4],
            batch: 1,
            obs_dim: 1,
            z_dim: 1,
            act_dim: 1,
        };
        assert_eq!(sac.flops(), 96.0 + 144.0 + 208.0);
        // encoder [3, 3, 2] on one transition: 30 forward + 30 weight + 12 hidden gradients,
        // head 3 x 2 x (2 x 1); discriminator [3, 4, 1]: two rows x 3 x 32; penalty on one row:
        // forward 24, chain 24, its backward 48, the output row and its gradient 16
        let disc = DiscBenchShape {
            hidden: vec![4],
            enc_hidden: vec![3],
            tasks: 1,
            ctx_trajs: 1,
            ctx_len: 1,
            samples: 1,
            obs_dim: 1,
            act_dim: 1,
            r_dim: 2,
            z_dim: 1,
            gp_weight: 10.0,
        };
        assert_eq!(disc.flops(), 54.0 + 192.0 + 112.0);
        // the authors' shapes: the figures BENCHMARKS.md quotes
        assert!((SacBenchShape::authors().flops() / 1e9 - 4.93).abs() < 0.01);
        assert!((DiscBenchShape::authors().flops() / 1e9 - 11.87).abs() < 0.01);
    }
}
