//! SMILe's two batches, drawn from the run's data, replay and networks (read only): the
//! discriminator's (expert and policy rows of the same tasks, each task with a fresh context)
//! and SAC's (replay rows labelled with the discriminator's reward, and for SMILe + BC the
//! demos of the same tasks).

use candle_core::{Device, Tensor};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use sim::TaskDemos;

use super::SmileConfig;
use crate::data::{
    Batch, BatchVecs, EarlyWeight, MetaData, TaskReplay, distinct_tasks, sample_context,
};
use crate::error::{Error, Result};
use crate::model::{
    ContextBatch, ContextEncoder, ContextSpec, Discriminator, Input, SharedCols, policy_input,
    scalar,
};

/// One discriminator batch: `tasks` tasks, each with a context and `per_task` expert and
/// `per_task` policy rows of `x` (row `r` belongs to task `r / per_task`).
pub struct DiscBatch {
    pub(super) context: ContextBatch,
    pub(super) x_expert: Tensor,
    pub(super) x_policy: Tensor,
    pub(super) tasks: usize,
    pub(super) per_task: usize,
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

/// A transition drawn uniformly from trajectories of `lens` transitions: (trajectory, step).
fn draw_transition(lens: &[usize], rng: &mut impl Rng) -> (usize, usize) {
    let mut k = rng.random_range(0..lens.iter().sum::<usize>());
    let mut j = 0;
    while k >= lens[j] {
        k -= lens[j];
        j += 1;
    }
    (j, k)
}

/// Every demo transition of a task as (trajectory, index), each first-steps one `early`'s
/// weight times: drawing uniformly from it weights the cloning rows. Listed once per run
/// ([`Smile::new`](super::Smile::new)), not per update pair.
pub(super) fn weighted_rows(demos: &TaskDemos, early: EarlyWeight) -> Vec<(usize, usize)> {
    let mut rows = Vec::new();
    for (j, tr) in demos.trajectories.iter().enumerate() {
        for k in 0..tr.len() {
            let step = tr.time_steps.get(k).copied().unwrap_or(u32::MAX);
            rows.extend(std::iter::repeat_n((j, k), early.copies(step) as usize));
        }
    }
    rows
}

/// The networks, data and replay that both steps' batches are drawn from, borrowed field by
/// field, so that the two sides of an overlapped pair can draw their batches at once while
/// both read the same networks.
pub(super) struct BatchSource<'a> {
    pub(super) cfg: &'a SmileConfig,
    pub(super) data: &'a MetaData,
    pub(super) encoder: &'a ContextEncoder,
    pub(super) disc: &'a Discriminator,
    pub(super) replay: &'a TaskReplay,
    pub(super) updates: u64,
    /// SMILe + BC's `[bc_early]`: each training task's weighted demo rows ([`weighted_rows`]).
    pub(super) bc_rows: Option<&'a [Vec<(usize, usize)>]>,
}

impl BatchSource<'_> {
    /// The discriminator's batch: `tasks_per_batch` distinct tasks, each with a fresh context
    /// and `disc_per_task` expert rows (uniform over its demo transitions) and as many policy
    /// rows (its replay); every random choice drawn from `rng`.
    pub(super) fn disc_batch(&self, rng: &mut ChaCha8Rng) -> Result<DiscBatch> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, rng);
        let per_task = cfg.disc_per_task;
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        let norm = &self.data.norm;
        let mut specs: Vec<ContextSpec<'_>> = Vec::with_capacity(tasks.len());
        let (mut x_exp, mut x_pol) = (Vec::new(), Vec::new());
        for &ti in &tasks {
            let demos = &self.data.train[ti];
            specs.push(sample_context(demos, cfg.context_draw(), rng));
            // Expert rows: uniform over the task's demo transitions.
            let lens: Vec<usize> = demos.trajectories.iter().map(|tr| tr.len()).collect();
            for _ in 0..per_task {
                let (j, k) = draw_transition(&lens, rng);
                let tr = &demos.trajectories[j];
                self.disc.push_x(
                    norm,
                    &tr.obs[k * od..(k + 1) * od],
                    &tr.actions[k * ad..(k + 1) * ad],
                    &tr.next_obs[k * od..(k + 1) * od],
                    &mut x_exp,
                );
            }
            let mut pol = BatchVecs::default();
            self.replay.task(ti).sample_into(per_task, rng, &mut pol)?;
            for r in 0..per_task {
                self.disc.push_x(
                    norm,
                    &pol.obs[r * od..(r + 1) * od],
                    &pol.act[r * ad..(r + 1) * ad],
                    &pol.next_obs[r * od..(r + 1) * od],
                    &mut x_pol,
                );
            }
        }
        let context = self.encoder.batch(norm, &specs)?;
        DiscBatch::new(context, x_exp, x_pol, tasks.len(), per_task)
    }

    /// A SAC batch on `tasks_per_batch` fresh tasks and contexts, labelled with the
    /// discriminator's reward; with its reward's mean and, for SMILe + BC, the cloning term's
    /// rows. Every random choice drawn from `rng`.
    pub(super) fn sac_batch(&self, rng: &mut ChaCha8Rng) -> Result<(Batch, f32, Option<DemoRows>)> {
        let cfg = &self.cfg;
        let tasks = distinct_tasks(self.data.train.len(), cfg.tasks_per_batch, rng);
        let n = cfg.sac_per_task;
        let specs: Vec<ContextSpec<'_>> = tasks
            .iter()
            .map(|&ti| sample_context(&self.data.train[ti], cfg.context_draw(), rng))
            .collect();
        let b = self.encoder.batch(&self.data.norm, &specs)?;
        // z from the discriminator's encoder, detached: SAC never updates the encoder.
        let z = self.encoder.z(&b, true, rng)?.detach().to_vec2::<f32>()?;
        let mut bv = BatchVecs::default();
        let mut z_rows = Vec::with_capacity(tasks.len() * n * z[0].len());
        for (k, &ti) in tasks.iter().enumerate() {
            self.replay.task(ti).sample_into(n, rng, &mut bv)?;
            for _ in 0..n {
                z_rows.extend_from_slice(&z[k]);
            }
        }
        let rows = bv.rew.len();
        let (od, ad, zd) = (
            self.data.family.obs_dim(),
            self.data.family.act_dim(),
            z[0].len(),
        );
        // r = clamp(D([x, z]), -10, 10); the SAC config's reward_scale multiplies it.
        let xzd = self.disc.x_dim() + zd;
        let mut dx = Vec::with_capacity(rows * xzd);
        for r in 0..rows {
            self.disc.push_x(
                &self.data.norm,
                &bv.obs[r * od..(r + 1) * od],
                &bv.act[r * ad..(r + 1) * ad],
                &bv.next_obs[r * od..(r + 1) * od],
                &mut dx,
            );
            dx.extend_from_slice(&z_rows[r * zd..(r + 1) * zd]);
        }
        // Each task's z on its n rows: the first layer's z block once per task.
        let xz = Tensor::from_vec(dx, (rows, xzd), &Device::Cpu)?;
        let rew = self.disc.reward(Input::shared(
            &xz,
            Some(SharedCols {
                start: self.disc.x_dim(),
                len: zd,
                group_rows: n,
            }),
        ))?;
        let reward_mean = scalar(&rew.mean_all()?)?;
        let actor_view = self.actor_view(&bv, &z_rows, zd, rng)?;
        let batch = Batch {
            obs: policy_input(&self.data.norm, &bv.obs, &z_rows, zd)?,
            act: Tensor::from_slice(&bv.act, (rows, ad), &Device::Cpu)?,
            rew,
            next_obs: policy_input(&self.data.norm, &bv.next_obs, &z_rows, zd)?,
            done: Tensor::from_slice(&bv.done, (rows, 1), &Device::Cpu)?,
            z_cols: Some(SharedCols {
                start: od,
                len: zd,
                group_rows: n,
            }),
            actor_view,
        };
        let bc = self.demo_rows(&tasks, &z_rows, zd, rng)?;
        Ok((batch, reward_mean, bc))
    }

    /// Through the device's senses (`[sensing]`): the actor's view of the SAC batch's rows,
    /// states and next states read through the sensor model; `None` (and nothing drawn)
    /// without it.
    fn actor_view(
        &self,
        bv: &BatchVecs,
        z_rows: &[f32],
        zd: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Option<(Tensor, Tensor)>> {
        let Some(sensing) = &self.cfg.sensing else {
            return Ok(None);
        };
        let od = self.data.family.obs_dim();
        let (mut o, mut o2) = (bv.obs.clone(), bv.next_obs.clone());
        if sensing.positions {
            // The estimator's readings depend on the episode: the replay kept them.
            if bv.view_obs.len() != o.len() {
                return Err(Error::Replay(
                    "[sensing] positions: the replay kept no views of its states".into(),
                ));
            }
            sensing.take_views(&mut o, &mut o2, &bv.view_obs, &bv.view_next_obs, od, rng);
        } else {
            sensing.read_row_pairs(&mut o, &mut o2, od, rng);
        }
        Ok(Some((
            policy_input(&self.data.norm, &o, z_rows, zd)?,
            policy_input(&self.data.norm, &o2, z_rows, zd)?,
        )))
    }

    /// SMILe + BC: the demos of the SAC batch's `tasks`, `sac_per_task` each, each row with
    /// its task's z. Nothing is drawn when the weight is 0, so such a run is SMILe's, bit for
    /// bit.
    fn demo_rows(
        &self,
        tasks: &[usize],
        z_rows: &[f32],
        zd: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Option<DemoRows>> {
        let w = self.cfg.bc_weight_at(self.updates);
        if w <= 0.0 {
            return Ok(None);
        }
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        let rows = tasks.len() * self.cfg.sac_per_task;
        let (mut obs, mut act) = (Vec::with_capacity(rows * od), Vec::with_capacity(rows * ad));
        for &ti in tasks {
            let demos = &self.data.train[ti];
            let lens: Vec<usize> = demos.trajectories.iter().map(|tr| tr.len()).collect();
            for _ in 0..self.cfg.sac_per_task {
                let (j, k) = match self.bc_rows.map(|r| &r[ti]) {
                    Some(rows) => rows[rng.random_range(0..rows.len())],
                    None => draw_transition(&lens, rng),
                };
                let tr = &demos.trajectories[j];
                obs.extend_from_slice(&tr.obs[k * od..(k + 1) * od]);
                act.extend_from_slice(&tr.actions[k * ad..(k + 1) * ad]);
            }
        }
        // Through the device's senses: the demo's action from its state as the device reads
        // it (noise injection, as Meta-BC's `[sensing]`).
        // With position-only sensing they stay as recorded: a subsampled demo has no history
        // for the estimator.
        if let Some(sensing) = self.cfg.sensing.as_ref().filter(|s| !s.positions) {
            sensing.read_rows(&mut obs, od, rng);
        }
        Ok(Some(DemoRows {
            obs: policy_input(&self.data.norm, &obs, z_rows, zd)?,
            act: Tensor::from_vec(act, (rows, ad), &Device::Cpu)?,
            weight: w,
        }))
    }
}

/// SMILe + BC's cloning rows: the demos of a SAC batch's tasks, `sac_per_task` per task.
pub(super) struct DemoRows {
    /// Policy inputs `[norm(s_E), z]`, each row with its task's detached z.
    pub(super) obs: Tensor,
    /// The expert's actions `a_E`.
    pub(super) act: Tensor,
    /// The term's weight at this update, `w(u)` (> 0).
    pub(super) weight: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two 4-step demos: each of the first two steps' rows listed `weight` times, in order.
    #[test]
    fn the_first_steps_rows_are_listed_weight_times() {
        let mut demos = TaskDemos {
            task: sim::Task::point_goal(0.0),
            trajectories: Vec::new(),
        };
        for _ in 0..2 {
            let mut t = sim::Trajectory::new(0);
            for i in 0..4 {
                let tr = sim::TransitionRef {
                    obs: &[0.0; 4],
                    action: &[0.0; 2],
                    reward: 0.0,
                    next_obs: &[0.0; 4],
                    done: false,
                };
                t.push(i, tr);
            }
            demos.trajectories.push(t);
        }
        let rows = weighted_rows(
            &demos,
            EarlyWeight {
                steps: 2,
                weight: 3,
            },
        );
        let one = |j| {
            [(j, 0); 3]
                .into_iter()
                .chain([(j, 1); 3])
                .chain([(j, 2), (j, 3)])
        };
        assert_eq!(rows, one(0).chain(one(1)).collect::<Vec<_>>());
    }

    #[test]
    fn a_first_steps_weight_needs_the_cloning_term_and_positive_counts() {
        let early = |steps, weight| SmileConfig {
            bc_weight: 1.0,
            bc_early: Some(EarlyWeight { steps, weight }),
            ..SmileConfig::default()
        };
        early(6, 16).validate().unwrap();
        for (cfg, key) in [
            (
                SmileConfig {
                    bc_weight: 0.0,
                    ..early(6, 16)
                },
                "bc_weight",
            ),
            (early(0, 16), "bc_early.steps"),
            (early(6, 0), "bc_early.weight"),
        ] {
            let err = cfg.validate().unwrap_err().to_string();
            assert!(err.contains(key), "{key}: {err}");
        }
    }
}
