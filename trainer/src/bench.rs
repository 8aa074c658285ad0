//! Learner micro-benchmarks, matching `../shared/bench/torch_reference.py` workload `sac`:
//! one SAC-v2 update (critic, actor, temperature, targets) on a fixed random batch, obs 20 +
//! z 16, act 6, two hidden layers of width H, batch 256; each update timed on its own and the
//! median reported. Plus a phase breakdown of one update for profiling.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::Result;
use crate::algo::sac::{Sac, SacConfig};
use crate::data::BatchVecs;

/// Shape of the benchmarked SAC update.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SacBenchShape {
    /// Hidden width H (two hidden layers).
    pub hidden: usize,
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
    /// The torch reference's shape at width `hidden`: batch 256, obs 20, z 16, act 6.
    pub fn reference(hidden: usize) -> Self {
        Self {
            hidden,
            batch: 256,
            obs_dim: 20,
            z_dim: 16,
            act_dim: 6,
        }
    }
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
pub fn sac_fixture(
    shape: SacBenchShape,
    seed: u64,
) -> Result<(Sac, crate::data::Batch, ChaCha8Rng)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d_in = shape.obs_dim + shape.z_dim;
    let cfg = SacConfig {
        hidden: vec![shape.hidden; 2],
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
    };
    let batch = v.to_batch(d_in, shape.act_dim)?;
    Ok((sac, batch, rng))
}

/// Median time of one full SAC update at `shape`.
pub fn bench_sac_update(shape: SacBenchShape, warmup: usize, iters: usize) -> Result<Timing> {
    let (mut sac, batch, mut rng) = sac_fixture(shape, 0)?;
    time_it(warmup, iters, || sac.update(&batch, &mut rng).map(|_| ()))
}
