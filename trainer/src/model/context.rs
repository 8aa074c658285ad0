//! The context-conditioned model every meta-learner here shares (SMILe, Meta-BC, Meta-DAgger).
//!
//! * [`ObsNorm`]: observation z-scoring with the mean/std of the meta-train demo states
//!   (reference §2; std 0 -> 1). It travels with the policy into the exported blob.
//! * [`ContextEncoder`] (permutation invariant, reference §2): a per-transition MLP
//!   `phi([norm(s), a, norm(s')]) -> r` (or `[norm(s), norm(s')]` state-only); the mean of `r`
//!   over the steps of each trajectory; the masked **sum** over the context's trajectories;
//!   then a head to a diagonal Gaussian `q(z | c) = N(mu, sigma)` with
//!   `log sigma = head_logsig - 2` (the reference subtracts 2.0). z is sampled during training,
//!   the posterior mean `mu` is used for evaluation and export.
//!
//!   ```text
//!   r_{j,t} = phi(x_{j,t});   rbar_j = (1/T_j) sum_t r_{j,t};   s = sum_j m_j rbar_j
//!   (mu, log sigma) = head(s);   z = mu + sigma * eps  (training)  |  z = mu  (eval)
//!   ```
//!   Both aggregations are one matrix product `s = A R` with `A[task, row] = m_j / T_j`.
//!
//! [`crate::model::MetaPolicy`] composes this encoder with the conditioned policy.

use candle_core::{Device, Tensor, Var};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use sim::{DemoDataset, Trajectory};

use crate::error::{Error, Result};
use crate::model::Mlp;

/// Encoder and latent sizes (shared by all algorithms).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContextConfig {
    /// State-only transitions `(s, s')` instead of `(s, a, s')`. Default false.
    pub state_only: bool,
    /// Hidden widths of the per-transition MLP. Default `[64, 64]` (reference §7 point-goal;
    /// the paper used 256 x 2).
    pub enc_hidden: Vec<usize>,
    /// Per-transition representation width r. Default 32 (§7).
    pub r_dim: usize,
    /// Latent width z. Default 16 (§7).
    pub z_dim: usize,
    /// Hidden widths of the r -> (mu, log sigma) head. Default `[64, 64]` (the reference).
    /// A linear head (`[]`) makes a smaller blob but cost SMILe on point-goal dearly: test
    /// min distance 0.16-0.22 instead of 0.11 (docs/RESULTS.md, "encoder head").
    pub head_hidden: Vec<usize>,
    /// Sample z during training (true, the paper) or use the posterior mean (false, §7's
    /// "deterministic" prototype). Default true.
    pub stochastic_z: bool,
}

impl Default for ContextConfig {
    fn default() -> Self {
        Self {
            state_only: false,
            enc_hidden: vec![64, 64],
            r_dim: 32,
            z_dim: 16,
            head_hidden: vec![64, 64],
            stochastic_z: true,
        }
    }
}

/// The reference subtracts this from the head's log-sigma output.
pub const LOG_STD_SHIFT: f64 = 2.0;

/// Observation z-scoring.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObsNorm {
    /// Per-component mean.
    pub mean: Vec<f32>,
    /// Per-component std (> 0).
    pub std: Vec<f32>,
}

impl ObsNorm {
    /// Identity normalisation of `dim` components.
    pub fn identity(dim: usize) -> Self {
        Self {
            mean: vec![0.0; dim],
            std: vec![1.0; dim],
        }
    }

    /// Mean and std of every demo state `s` in `ds` (std below 1e-6 becomes 1).
    pub fn from_demos(ds: &DemoDataset) -> Result<Self> {
        let d = ds.obs_dim;
        let (mut sum, mut sq, mut n) = (vec![0.0f64; d], vec![0.0f64; d], 0usize);
        for t in ds.tasks.iter().flat_map(|t| &t.trajectories) {
            for row in t.obs.chunks_exact(d) {
                for (i, v) in row.iter().enumerate() {
                    sum[i] += *v as f64;
                    sq[i] += (*v as f64) * (*v as f64);
                }
                n += 1;
            }
        }
        if n == 0 {
            return Err(Error::Data("demo dataset holds no transitions".into()));
        }
        let mean: Vec<f32> = sum.iter().map(|s| (s / n as f64) as f32).collect();
        let std = sq
            .iter()
            .zip(&sum)
            .map(|(q, s)| {
                let m = s / n as f64;
                let sd = (q / n as f64 - m * m).max(0.0).sqrt() as f32;
                if sd < 1e-6 { 1.0 } else { sd }
            })
            .collect();
        Ok(Self { mean, std })
    }

    /// Appends `norm(x)` to `out`.
    pub fn push(&self, x: &[f32], out: &mut Vec<f32>) {
        out.extend(
            x.iter()
                .zip(&self.mean)
                .zip(&self.std)
                .map(|((v, m), s)| (v - m) / s),
        );
    }

    /// `norm(x)` as a new vector.
    pub fn apply(&self, x: &[f32]) -> Vec<f32> {
        let mut out = Vec::with_capacity(x.len());
        self.push(x, &mut out);
        out
    }
}

/// One task's context: its candidate trajectories, of which the first `k` count (the mask of
/// the reference's few-shot contexts).
#[derive(Debug, Clone)]
pub struct ContextSpec<'a> {
    /// Trajectories (usually 4).
    pub trajectories: Vec<&'a Trajectory>,
    /// How many of them are unmasked.
    pub k: usize,
    /// Either empty (every transition of the unmasked trajectories is encoded) or, per unmasked
    /// trajectory, the indices of the transitions that stand for it.
    pub steps: Vec<Vec<usize>>,
}

impl<'a> ContextSpec<'a> {
    /// All of `trajectories`, unmasked, every transition.
    pub fn all(trajectories: Vec<&'a Trajectory>) -> Self {
        Self::first(trajectories.len(), trajectories)
    }

    /// The first `k` of `trajectories` unmasked, every transition.
    pub fn first(k: usize, trajectories: Vec<&'a Trajectory>) -> Self {
        Self {
            trajectories,
            k,
            steps: Vec::new(),
        }
    }
}

/// Encoder inputs for a batch of contexts, ready for [`ContextEncoder::posterior`].
#[derive(Debug, Clone)]
pub struct ContextBatch {
    /// Per-transition encoder inputs `(R, in_dim)`.
    pub rows: Tensor,
    /// Aggregation `(T, R)`: `A[task, row] = mask_j / len_j` for the row's trajectory j.
    pub agg: Tensor,
}

/// The permutation-invariant context encoder with a Gaussian head.
#[derive(Debug, Clone)]
pub struct ContextEncoder {
    cfg: ContextConfig,
    obs_dim: usize,
    act_dim: usize,
    /// Per-transition MLP `x -> r`.
    pub phi: Mlp,
    /// Head `sum_j rbar_j -> (mu, log sigma + 2)`, output width `2 z_dim`.
    pub head: Mlp,
}

impl ContextEncoder {
    /// A fresh encoder for `obs_dim` observations and `act_dim` actions.
    pub fn new(
        obs_dim: usize,
        act_dim: usize,
        cfg: ContextConfig,
        rng: &mut impl Rng,
    ) -> Result<Self> {
        if cfg.r_dim == 0 || cfg.z_dim == 0 {
            return Err(Error::Config(
                "context r_dim and z_dim must be positive".into(),
            ));
        }
        let in_dim = if cfg.state_only {
            2 * obs_dim
        } else {
            2 * obs_dim + act_dim
        };
        let mut w = vec![in_dim];
        w.extend_from_slice(&cfg.enc_hidden);
        w.push(cfg.r_dim);
        let phi = Mlp::new(&w, rng)?;
        let mut h = vec![cfg.r_dim];
        h.extend_from_slice(&cfg.head_hidden);
        h.push(2 * cfg.z_dim);
        let head = Mlp::new(&h, rng)?;
        Ok(Self {
            cfg,
            obs_dim,
            act_dim,
            phi,
            head,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ContextConfig {
        &self.cfg
    }

    /// Latent width.
    pub fn z_dim(&self) -> usize {
        self.cfg.z_dim
    }

    /// Width of one encoder input row.
    pub fn input_dim(&self) -> usize {
        self.phi.widths()[0]
    }

    /// All trainable variables (phi then head).
    pub fn vars(&self) -> Vec<Var> {
        [self.phi.vars(), self.head.vars()].concat()
    }

    /// Appends the encoder input of transition `i` of `t` to `out`.
    pub fn push_row(&self, norm: &ObsNorm, t: &Trajectory, i: usize, out: &mut Vec<f32>) {
        let (o, a) = (self.obs_dim, self.act_dim);
        norm.push(&t.obs[i * o..(i + 1) * o], out);
        if !self.cfg.state_only {
            out.extend_from_slice(&t.actions[i * a..(i + 1) * a]);
        }
        norm.push(&t.next_obs[i * o..(i + 1) * o], out);
    }

    /// Builds the encoder inputs of several tasks' contexts (one latent per context).
    pub fn batch(&self, norm: &ObsNorm, contexts: &[ContextSpec<'_>]) -> Result<ContextBatch> {
        let mut rows = Vec::new();
        let mut owner: Vec<(usize, f32)> = Vec::new(); // (context, weight) per row
        for (c, spec) in contexts.iter().enumerate() {
            if !spec.steps.is_empty() && spec.steps.len() != spec.k.min(spec.trajectories.len()) {
                return Err(Error::Data(format!(
                    "context {c}: {} step lists for {} unmasked trajectories",
                    spec.steps.len(),
                    spec.k
                )));
            }
            // Masked trajectories (j >= k) weigh 0 in the sum: they are not encoded at all.
            for (j, t) in spec.trajectories.iter().take(spec.k).enumerate() {
                let all: Vec<usize>;
                let idx = match spec.steps.get(j) {
                    Some(idx) => idx,
                    None => {
                        all = (0..t.len()).collect();
                        &all
                    }
                };
                if idx.is_empty() {
                    continue;
                }
                let w = 1.0 / idx.len() as f32;
                for &i in idx {
                    if i >= t.len() {
                        return Err(Error::Data(format!(
                            "context {c}: step {i} of a {}-step trajectory",
                            t.len()
                        )));
                    }
                    self.push_row(norm, t, i, &mut rows);
                    owner.push((c, w));
                }
            }
        }
        let (n_rows, n_ctx, d) = (owner.len(), contexts.len(), self.input_dim());
        if n_ctx == 0 {
            return Err(Error::Data("no contexts to encode".into()));
        }
        let mut agg = vec![0.0f32; n_ctx * n_rows.max(1)];
        for (r, (c, w)) in owner.iter().enumerate() {
            agg[c * n_rows.max(1) + r] = *w;
        }
        if n_rows == 0 {
            // Every context is empty: one zero row keeps the shapes valid; s = 0.
            rows = vec![0.0; d];
        }
        let dev = &Device::Cpu;
        Ok(ContextBatch {
            rows: Tensor::from_vec(rows, (n_rows.max(1), d), dev)?,
            agg: Tensor::from_vec(agg, (n_ctx, n_rows.max(1)), dev)?,
        })
    }

    /// `(mu, log sigma)` of `q(z | c)` for each context, shapes `(T, z_dim)`.
    pub fn posterior(&self, b: &ContextBatch) -> Result<(Tensor, Tensor)> {
        let r = self.phi.forward(&b.rows)?; // (R, r)
        let s = b.agg.matmul(&r)?; // (T, r): mean over steps, masked sum over trajectories
        let out = self.head.forward(&s)?;
        let z = self.cfg.z_dim;
        let mu = out.narrow(1, 0, z)?;
        let log_std = (out.narrow(1, z, z)? - LOG_STD_SHIFT)?.clamp(-20.0, 2.0)?;
        Ok((mu, log_std))
    }

    /// z for each context: a reparameterised sample if `sample` (and the config allows it),
    /// else the posterior mean. Gradients flow into the encoder.
    pub fn z(&self, b: &ContextBatch, sample: bool, rng: &mut impl Rng) -> Result<Tensor> {
        let (mu, log_std) = self.posterior(b)?;
        if !(sample && self.cfg.stochastic_z) {
            return Ok(mu);
        }
        let (t, z) = mu.dims2()?;
        let eps: Vec<f32> = (0..t * z)
            .map(|_| rng.sample::<f32, _>(StandardNormal))
            .collect();
        let eps = Tensor::from_vec(eps, (t, z), &Device::Cpu)?;
        Ok((mu + (log_std.exp()? * eps)?)?)
    }

    /// Posterior mean of one context, as a vector.
    pub fn latent(&self, norm: &ObsNorm, context: &[&Trajectory]) -> Result<Vec<f32>> {
        let b = self.batch(norm, &[ContextSpec::all(context.to_vec())])?;
        let (mu, _) = self.posterior(&b)?;
        Ok(mu.flatten_all()?.to_vec1::<f32>()?)
    }
}

/// `[norm(obs), z]` rows for a batch: `obs` is `B * obs_dim`, `z` is `B * z_dim`.
pub fn policy_input(norm: &ObsNorm, obs: &[f32], z: &[f32], z_dim: usize) -> Result<Tensor> {
    let od = norm.mean.len();
    let b = obs.len() / od;
    let mut x = Vec::with_capacity(b * (od + z_dim));
    for (o, zz) in obs.chunks_exact(od).zip(z.chunks_exact(z_dim)) {
        norm.push(o, &mut x);
        x.extend_from_slice(zz);
    }
    Ok(Tensor::from_vec(x, (b, od + z_dim), &Device::Cpu)?)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    use rand_chacha::ChaCha8Rng;

    pub(crate) fn traj(rng: &mut ChaCha8Rng, len: usize, od: usize, ad: usize) -> Trajectory {
        let mut t = Trajectory::new(0);
        for s in 0..len {
            let o: Vec<f32> = (0..od).map(|_| rng.random_range(-2.0..2.0)).collect();
            let a: Vec<f32> = (0..ad).map(|_| rng.random_range(-1.0..1.0)).collect();
            let n: Vec<f32> = (0..od).map(|_| rng.random_range(-2.0..2.0)).collect();
            push_step(&mut t, s as u32, &o, &a, &n);
        }
        t
    }

    /// Appends step `step` (obs `o`, action `a`, next obs `n`; no reward, not done) to `t`.
    fn push_step(t: &mut Trajectory, step: u32, o: &[f32], a: &[f32], n: &[f32]) {
        let transition = sim::TransitionRef {
            obs: o,
            action: a,
            reward: 0.0,
            next_obs: n,
            done: false,
        };
        t.push(step, transition);
    }

    fn reversed(t: &Trajectory, od: usize, ad: usize) -> Trajectory {
        let mut r = Trajectory::new(t.seed);
        for i in (0..t.len()).rev() {
            r.push(i as u32, t.transition(i, od, ad).unwrap());
        }
        r
    }

    pub(crate) fn close(a: &[f32], b: &[f32], tol: f32) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
    }

    pub(crate) fn setup(state_only: bool) -> (ContextEncoder, ObsNorm, Vec<Trajectory>) {
        setup_with_head(state_only, vec![16])
    }

    fn setup_with_head(
        state_only: bool,
        head_hidden: Vec<usize>,
    ) -> (ContextEncoder, ObsNorm, Vec<Trajectory>) {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let cfg = ContextConfig {
            state_only,
            enc_hidden: vec![16, 16],
            r_dim: 8,
            z_dim: 4,
            head_hidden,
            ..ContextConfig::default()
        };
        let enc = ContextEncoder::new(4, 2, cfg, &mut rng).unwrap();
        let norm = ObsNorm {
            mean: vec![0.1, -0.2, 0.3, 0.0],
            std: vec![1.5, 0.5, 2.0, 1.0],
        };
        let trajs = (0..4).map(|i| traj(&mut rng, 3 + i, 4, 2)).collect();
        (enc, norm, trajs)
    }

    #[test]
    fn permutation_invariant_over_trajectories_and_steps() {
        for state_only in [false, true] {
            let (enc, norm, trajs) = setup(state_only);
            let refs: Vec<&Trajectory> = trajs.iter().collect();
            let z0 = enc.latent(&norm, &refs).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(1);
            let mut shuffled = refs.clone();
            shuffled.shuffle(&mut rng);
            assert_ne!(
                shuffled.iter().map(|t| t.len()).collect::<Vec<_>>(),
                refs.iter().map(|t| t.len()).collect::<Vec<_>>()
            );
            assert!(close(&enc.latent(&norm, &shuffled).unwrap(), &z0, 1e-5));
            let rev: Vec<Trajectory> = trajs.iter().map(|t| reversed(t, 4, 2)).collect();
            let rev_refs: Vec<&Trajectory> = rev.iter().collect();
            assert!(close(&enc.latent(&norm, &rev_refs).unwrap(), &z0, 1e-5));
            // Moving a step from one trajectory to another changes the per-trajectory means.
            let mut moved = trajs.clone();
            let last = moved[3].transition(moved[3].len() - 1, 4, 2).unwrap();
            let (o, a, n) = (
                last.obs.to_vec(),
                last.action.to_vec(),
                last.next_obs.to_vec(),
            );
            push_step(&mut moved[0], 9, &o, &a, &n);
            let moved_refs: Vec<&Trajectory> = moved.iter().collect();
            assert!(!close(&enc.latent(&norm, &moved_refs).unwrap(), &z0, 1e-4));
        }
    }

    #[test]
    fn mask_drops_trajectories_and_sum_is_not_mean() {
        // A linear head, so that the sum across trajectories is visible in mu (below).
        let (enc, norm, trajs) = setup_with_head(false, vec![]);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let junk = traj(&mut rng, 6, 4, 2);
        let two: Vec<&Trajectory> = trajs.iter().take(2).collect();
        let b = enc
            .batch(
                &norm,
                &[
                    ContextSpec::first(2, vec![&trajs[0], &trajs[1], &junk, &trajs[3]]),
                    ContextSpec::all(two.clone()),
                    ContextSpec::first(1, vec![&trajs[0], &trajs[1]]),
                ],
            )
            .unwrap();
        let (mu, _) = enc.posterior(&b).unwrap();
        let mu = mu.to_vec2::<f32>().unwrap();
        assert!(
            close(&mu[0], &mu[1], 1e-5),
            "masked trajectories must not count"
        );
        assert!(close(&mu[1], &enc.latent(&norm, &two).unwrap(), 1e-5));
        assert!(!close(&mu[1], &mu[2], 1e-3));
        // Sum, not mean, across trajectories: the same trajectory twice doubles r-sum, which a
        // linear head with zero bias turns into exactly 2x mu.
        let zero_b = Tensor::zeros((1, 2 * 4), candle_core::DType::F32, &Device::Cpu).unwrap();
        enc.head.vars()[1].set(&zero_b).unwrap();
        let once = enc.latent(&norm, &[&trajs[0]]).unwrap();
        let twice = enc.latent(&norm, &[&trajs[0], &trajs[0]]).unwrap();
        let doubled: Vec<f32> = once.iter().map(|v| 2.0 * v).collect();
        assert!(close(&twice, &doubled, 1e-5));
    }

    #[test]
    fn step_lists_encode_exactly_those_transitions() {
        let (enc, norm, trajs) = setup(false);
        let (t0, t1) = (&trajs[3], &trajs[1]); // 6 and 4 steps
        let every = |t: &Trajectory| (0..t.len()).collect::<Vec<usize>>();
        // Every index listed: the same latent as the whole trajectories.
        let full = enc.latent(&norm, &[t0, t1]).unwrap();
        let listed = ContextSpec {
            trajectories: vec![t0, t1],
            k: 2,
            steps: vec![every(t0), every(t1)],
        };
        let (mu, _) = enc
            .posterior(&enc.batch(&norm, &[listed]).unwrap())
            .unwrap();
        assert!(close(&mu.to_vec2::<f32>().unwrap()[0], &full, 1e-5));
        // A subset: the same latent as a trajectory made of just those transitions.
        let pick = [0usize, 2, 3];
        let mut sub = Trajectory::new(0);
        for &i in &pick {
            sub.push(i as u32, t0.transition(i, 4, 2).unwrap());
        }
        let spec = ContextSpec {
            trajectories: vec![t0],
            k: 1,
            steps: vec![pick.to_vec()],
        };
        let (mu, _) = enc.posterior(&enc.batch(&norm, &[spec]).unwrap()).unwrap();
        let want = enc.latent(&norm, &[&sub]).unwrap();
        assert!(close(&mu.to_vec2::<f32>().unwrap()[0], &want, 1e-5));
        assert!(!close(&want, &enc.latent(&norm, &[t0]).unwrap(), 1e-4));
        // Out-of-range indices and mismatched lists are errors, not panics.
        let bad = ContextSpec {
            trajectories: vec![t0],
            k: 1,
            steps: vec![vec![t0.len()]],
        };
        assert!(enc.batch(&norm, &[bad]).is_err());
        let bad = ContextSpec {
            trajectories: vec![t0, t1],
            k: 2,
            steps: vec![vec![0]],
        };
        assert!(enc.batch(&norm, &[bad]).is_err());
    }
}
