//! Flat, preallocated ring replay buffers.
//!
//! One [`ReplayBuffer`] holds `capacity` transitions `(s, a, r, s', terminated)` in five flat
//! `Vec<f32>`s allocated once; when full, the oldest transition is overwritten. Meta-learning
//! keeps one buffer per task ([`TaskReplay`]), as the reference implementation does (50k per task
//! for HalfCheetah).
//!
//! `terminated` is a true terminal state (no bootstrap); a time-limit truncation is *not* a
//! terminal and must be stored with `terminated = false`.

use candle_core::{Device, Tensor};
use rand::Rng;

use crate::error::{Error, Result};
use crate::model::{SharedCols, TensorLookup};

/// A minibatch as tensors, ready for an update.
#[derive(Debug, Clone)]
pub struct Batch {
    /// Observations `(B, obs_dim)`.
    pub obs: Tensor,
    /// Actions `(B, act_dim)`.
    pub act: Tensor,
    /// Rewards `(B, 1)`.
    pub rew: Tensor,
    /// Next observations `(B, obs_dim)`.
    pub next_obs: Tensor,
    /// 1.0 where the transition ended in a true terminal state, `(B, 1)`.
    pub done: Tensor,
    /// Columns of `obs` and `next_obs` that repeat within groups of rows (a meta-learner's
    /// task-major batch: each task's `z` on its rows), for the networks' first layers; `None`
    /// for a plain batch.
    pub z_cols: Option<SharedCols>,
    /// The states the actor reads in place of `obs` and `next_obs` (same shapes and
    /// `z_cols`), where it reads them through the device's sensors while the critics read the
    /// true ones (SMILe's `[sensing]`); `None`: the actor reads `obs` and `next_obs`.
    pub actor_view: Option<(Tensor, Tensor)>,
}

impl Batch {
    /// What the actor reads for the states (`obs`, or the sensed view).
    pub fn actor_obs(&self) -> &Tensor {
        self.actor_view.as_ref().map_or(&self.obs, |v| &v.0)
    }

    /// What the actor reads for the next states (`next_obs`, or the sensed view).
    pub fn actor_next_obs(&self) -> &Tensor {
        self.actor_view.as_ref().map_or(&self.next_obs, |v| &v.1)
    }
}

/// A minibatch as flat row-major vectors (for callers that edit it before making tensors, e.g.
/// appending a task embedding to every observation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchVecs {
    /// Observations, `B * obs_dim`.
    pub obs: Vec<f32>,
    /// Actions, `B * act_dim`.
    pub act: Vec<f32>,
    /// Rewards, `B`.
    pub rew: Vec<f32>,
    /// Next observations, `B * obs_dim`.
    pub next_obs: Vec<f32>,
    /// Terminal flags (0 or 1), `B`.
    pub done: Vec<f32>,
    /// The states as the policy read them (`B * obs_dim`), from a buffer that keeps them
    /// ([`ReplayBuffer::with_views`]); empty otherwise.
    pub view_obs: Vec<f32>,
    /// The next states as the policy read them, as `view_obs`.
    pub view_next_obs: Vec<f32>,
}

impl BatchVecs {
    /// Convert to tensors with the given dimensions.
    pub fn to_batch(&self, obs_dim: usize, act_dim: usize) -> Result<Batch> {
        let b = self.rew.len();
        let dev = &Device::Cpu;
        Ok(Batch {
            obs: Tensor::from_slice(&self.obs, (b, obs_dim), dev)?,
            act: Tensor::from_slice(&self.act, (b, act_dim), dev)?,
            rew: Tensor::from_slice(&self.rew, (b, 1), dev)?,
            next_obs: Tensor::from_slice(&self.next_obs, (b, obs_dim), dev)?,
            done: Tensor::from_slice(&self.done, (b, 1), dev)?,
            z_cols: None,
            actor_view: None,
        })
    }
}

/// A ring buffer of transitions with fixed dimensions and capacity.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayBuffer {
    obs_dim: usize,
    act_dim: usize,
    capacity: usize,
    len: usize,
    pos: usize,
    obs: Vec<f32>,
    act: Vec<f32>,
    rew: Vec<f32>,
    next_obs: Vec<f32>,
    done: Vec<f32>,
    /// The states and next states as the policy read them (position-only sensing: the
    /// estimator's output, which depends on the episode's history and cannot be redrawn at
    /// batch time); `None` in a buffer without views.
    views: Option<(Vec<f32>, Vec<f32>)>,
}

impl ReplayBuffer {
    /// An empty buffer; all storage is allocated here.
    pub fn new(obs_dim: usize, act_dim: usize, capacity: usize) -> Result<Self> {
        if capacity == 0 || obs_dim == 0 || act_dim == 0 {
            return Err(Error::Config(
                "replay buffer dimensions must be positive".into(),
            ));
        }
        Ok(Self {
            obs_dim,
            act_dim,
            capacity,
            len: 0,
            pos: 0,
            obs: vec![0.0; capacity * obs_dim],
            act: vec![0.0; capacity * act_dim],
            rew: vec![0.0; capacity],
            next_obs: vec![0.0; capacity * obs_dim],
            done: vec![0.0; capacity],
            views: None,
        })
    }

    /// An empty buffer that also keeps each transition's states as the policy read them
    /// (given to [`Self::push`]; batches carry them in `view_obs` and `view_next_obs`).
    pub fn with_views(obs_dim: usize, act_dim: usize, capacity: usize) -> Result<Self> {
        let mut b = Self::new(obs_dim, act_dim, capacity)?;
        b.keep_views();
        Ok(b)
    }

    /// Makes room for the views (an empty buffer's, so nothing stored lacks one).
    fn keep_views(&mut self) {
        let n = self.capacity * self.obs_dim;
        self.views = Some((vec![0.0; n], vec![0.0; n]));
    }

    /// Whether the buffer keeps the policy's views.
    pub fn has_views(&self) -> bool {
        self.views.is_some()
    }

    /// Number of stored transitions.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Maximum number of transitions.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Observation dimension.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Action dimension.
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Store one transition, overwriting the oldest when full. `view`: the states as the
    /// policy read them, `(s, s')`, which a buffer [`with views`](Self::with_views) keeps beside
    /// them and needs (a buffer without views refuses them).
    pub fn push(
        &mut self,
        obs: &[f32],
        act: &[f32],
        rew: f32,
        next_obs: &[f32],
        terminated: bool,
        view: Option<(&[f32], &[f32])>,
    ) -> Result<()> {
        let (od, ad) = (self.obs_dim, self.act_dim);
        let views = view.map(|(vo, vn)| (vo.len(), vn.len()));
        if obs.len() != od
            || next_obs.len() != od
            || act.len() != ad
            || views.is_some_and(|v| v != (od, od))
        {
            let views = views.map_or(String::new(), |(vo, vn)| format!(" views {vo}/{vn}"));
            return Err(Error::Shape(format!(
                "push: obs {}/{} act {}{views} into buffer of obs {od} act {ad}",
                obs.len(),
                next_obs.len(),
                act.len(),
            )));
        }
        if view.is_some() != self.views.is_some() {
            return Err(Error::Replay(match view {
                Some(_) => "views pushed into a buffer without views".into(),
                None => "a buffer with views needs the policy's view of each transition".into(),
            }));
        }
        let i = self.pos;
        self.obs[i * od..(i + 1) * od].copy_from_slice(obs);
        self.next_obs[i * od..(i + 1) * od].copy_from_slice(next_obs);
        self.act[i * ad..(i + 1) * ad].copy_from_slice(act);
        self.rew[i] = rew;
        self.done[i] = if terminated { 1.0 } else { 0.0 };
        if let (Some((vo, vn)), Some((so, sn))) = (self.views.as_mut(), view) {
            vo[i * od..(i + 1) * od].copy_from_slice(so);
            vn[i * od..(i + 1) * od].copy_from_slice(sn);
        }
        self.pos = (self.pos + 1) % self.capacity;
        self.len = (self.len + 1).min(self.capacity);
        Ok(())
    }

    /// Append the transitions at `idx` (uniform indices in `0..len`) to `out`.
    pub fn gather_into(&self, idx: &[usize], out: &mut BatchVecs) {
        let (od, ad) = (self.obs_dim, self.act_dim);
        for &i in idx {
            out.obs.extend_from_slice(&self.obs[i * od..(i + 1) * od]);
            out.next_obs
                .extend_from_slice(&self.next_obs[i * od..(i + 1) * od]);
            out.act.extend_from_slice(&self.act[i * ad..(i + 1) * ad]);
            out.rew.push(self.rew[i]);
            out.done.push(self.done[i]);
            if let Some((vo, vn)) = &self.views {
                out.view_obs.extend_from_slice(&vo[i * od..(i + 1) * od]);
                out.view_next_obs
                    .extend_from_slice(&vn[i * od..(i + 1) * od]);
            }
        }
    }

    /// `n` transitions drawn uniformly with replacement, appended to `out`.
    pub fn sample_into(&self, n: usize, rng: &mut impl Rng, out: &mut BatchVecs) -> Result<()> {
        if self.len == 0 {
            return Err(Error::Replay("sampling from an empty buffer".into()));
        }
        let idx: Vec<usize> = (0..n).map(|_| rng.random_range(0..self.len)).collect();
        self.gather_into(&idx, out);
        Ok(())
    }

    /// `n` transitions drawn uniformly with replacement, as tensors.
    pub fn sample(&self, n: usize, rng: &mut impl Rng) -> Result<Batch> {
        let mut v = BatchVecs::default();
        self.sample_into(n, rng, &mut v)?;
        v.to_batch(self.obs_dim, self.act_dim)
    }

    /// Named tensors holding the stored rows plus `[len, pos]`, for checkpoints.
    pub fn to_tensors(&self, prefix: &str) -> Result<Vec<(String, Tensor)>> {
        let (n, dev) = (self.len, &Device::Cpu);
        let t = |name: &str, data: &[f32], w: usize| -> Result<(String, Tensor)> {
            Ok((
                format!("{prefix}.{name}"),
                Tensor::from_slice(&data[..n * w], (n, w), dev)?,
            ))
        };
        let counters = [self.len as u32, self.pos as u32, self.capacity as u32];
        let mut out = vec![
            t("obs", &self.obs, self.obs_dim)?,
            t("act", &self.act, self.act_dim)?,
            t("rew", &self.rew, 1)?,
            t("next_obs", &self.next_obs, self.obs_dim)?,
            t("done", &self.done, 1)?,
            (
                format!("{prefix}.counters"),
                Tensor::from_slice(&counters, 3, dev)?,
            ),
        ];
        if let Some((vo, vn)) = &self.views {
            out.push(t("view_obs", vo, self.obs_dim)?);
            out.push(t("view_next_obs", vn, self.obs_dim)?);
        }
        Ok(out)
    }

    /// Restore the contents written by [`ReplayBuffer::to_tensors`]; `get` looks a tensor up by
    /// name. Dimensions and capacity must match this buffer.
    pub fn load_tensors(&mut self, prefix: &str, get: TensorLookup) -> Result<()> {
        let c = get(&format!("{prefix}.counters"))?.to_vec1::<u32>()?;
        let [len, pos, cap] = c[..] else {
            return Err(Error::Shape(format!(
                "{prefix}.counters: expected 3 values"
            )));
        };
        let (len, pos) = (len as usize, pos as usize);
        if cap as usize != self.capacity || len > self.capacity || pos >= self.capacity {
            return Err(Error::Shape(format!(
                "{prefix}: saved buffer (len {len}, pos {pos}, capacity {cap}) does not fit \
                 capacity {}",
                self.capacity
            )));
        }
        let load = |name: &str, dst: &mut Vec<f32>, w: usize| -> Result<()> {
            let t = get(&format!("{prefix}.{name}"))?;
            if t.dims() != [len, w] {
                return Err(Error::Shape(format!(
                    "{prefix}.{name}: expected ({len}, {w}), got {:?}",
                    t.dims()
                )));
            }
            dst[..len * w].copy_from_slice(&t.flatten_all()?.to_vec1::<f32>()?);
            dst[len * w..].fill(0.0);
            Ok(())
        };
        load("obs", &mut self.obs, self.obs_dim)?;
        load("act", &mut self.act, self.act_dim)?;
        load("rew", &mut self.rew, 1)?;
        load("next_obs", &mut self.next_obs, self.obs_dim)?;
        load("done", &mut self.done, 1)?;
        if let Some((vo, vn)) = self.views.as_mut() {
            load("view_obs", vo, self.obs_dim)?;
            load("view_next_obs", vn, self.obs_dim)?;
        }
        self.len = len;
        self.pos = pos;
        Ok(())
    }
}

/// One replay buffer per task (meta-learning keeps each task's policy data apart).
#[derive(Debug, Clone, PartialEq)]
pub struct TaskReplay {
    buffers: Vec<ReplayBuffer>,
}

impl TaskReplay {
    /// `n_tasks` empty buffers of `capacity_per_task` transitions each.
    pub fn new(
        n_tasks: usize,
        obs_dim: usize,
        act_dim: usize,
        capacity_per_task: usize,
    ) -> Result<Self> {
        let buffers = (0..n_tasks)
            .map(|_| ReplayBuffer::new(obs_dim, act_dim, capacity_per_task))
            .collect::<Result<_>>()?;
        Ok(Self { buffers })
    }

    /// These buffers, each keeping the policy's views too ([`ReplayBuffer::with_views`]).
    pub fn with_views(mut self) -> Self {
        for b in &mut self.buffers {
            b.keep_views();
        }
        self
    }

    /// Number of tasks.
    pub fn n_tasks(&self) -> usize {
        self.buffers.len()
    }

    /// The buffer of task `i`.
    pub fn task(&self, i: usize) -> &ReplayBuffer {
        &self.buffers[i]
    }

    /// The buffer of task `i`, mutably.
    pub fn task_mut(&mut self, i: usize) -> &mut ReplayBuffer {
        &mut self.buffers[i]
    }

    /// Total transitions over all tasks.
    pub fn total_len(&self) -> usize {
        self.buffers.iter().map(ReplayBuffer::len).sum()
    }

    /// Named tensors of every task buffer (`{prefix}.{task}.…`).
    pub fn to_tensors(&self, prefix: &str) -> Result<Vec<(String, Tensor)>> {
        let mut out = Vec::new();
        for (i, b) in self.buffers.iter().enumerate() {
            out.extend(b.to_tensors(&format!("{prefix}.{i}"))?);
        }
        Ok(out)
    }

    /// Restore every task buffer written by [`TaskReplay::to_tensors`].
    pub fn load_tensors(&mut self, prefix: &str, get: TensorLookup) -> Result<()> {
        for (i, b) in self.buffers.iter_mut().enumerate() {
            b.load_tensors(&format!("{prefix}.{i}"), get)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use std::collections::HashMap;

    #[test]
    fn ring_overwrites_oldest_and_round_trips() {
        let mut b = ReplayBuffer::new(2, 1, 3).unwrap();
        for i in 0..5 {
            let x = i as f32;
            b.push(&[x, x], &[x], x, &[x + 1.0, x + 1.0], i == 4, None)
                .unwrap();
        }
        assert_eq!(b.len(), 3);
        let mut v = BatchVecs::default();
        b.gather_into(&[0, 1, 2], &mut v);
        // slots 0,1 were overwritten by transitions 3,4; slot 2 holds transition 2
        assert_eq!(v.rew, vec![3.0, 4.0, 2.0]);
        assert_eq!(v.done, vec![0.0, 1.0, 0.0]);
        let map: HashMap<String, Tensor> = b.to_tensors("rb").unwrap().into_iter().collect();
        let mut c = ReplayBuffer::new(2, 1, 3).unwrap();
        c.load_tensors("rb", &|n| Ok(map[n].clone())).unwrap();
        assert_eq!(b, c);
        let mut wrong = ReplayBuffer::new(2, 1, 4).unwrap();
        assert!(wrong.load_tensors("rb", &|n| Ok(map[n].clone())).is_err());
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let batch = b.sample(7, &mut rng).unwrap();
        assert_eq!(batch.obs.dims(), &[7, 2]);
        assert!(
            ReplayBuffer::new(2, 1, 3)
                .unwrap()
                .sample(1, &mut rng)
                .is_err()
        );
    }

    #[test]
    fn views_ride_with_their_transitions_and_round_trip() {
        let mut b = ReplayBuffer::with_views(2, 1, 3).unwrap();
        for i in 0..4 {
            let x = i as f32;
            let view = ([x + 0.5, x + 0.5], [x + 1.5, x + 1.5]);
            let view = Some((&view.0[..], &view.1[..]));
            b.push(&[x, x], &[x], x, &[x + 1.0, x + 1.0], false, view)
                .unwrap();
        }
        let mut v = BatchVecs::default();
        b.gather_into(&[0, 2], &mut v);
        // slot 0 holds transition 3, slot 2 transition 2
        assert_eq!(v.rew, vec![3.0, 2.0]);
        assert_eq!(v.view_obs, vec![3.5, 3.5, 2.5, 2.5]);
        assert_eq!(v.view_next_obs, vec![4.5, 4.5, 3.5, 3.5]);
        let map: HashMap<String, Tensor> = b.to_tensors("rb").unwrap().into_iter().collect();
        let mut c = ReplayBuffer::with_views(2, 1, 3).unwrap();
        c.load_tensors("rb", &|n| Ok(map[n].clone())).unwrap();
        assert_eq!(b, c);
        // A buffer without views refuses a viewed push, a views buffer one without views (and
        // the views of the wrong width), and a views buffer needs the views saved.
        let mut plain = ReplayBuffer::new(2, 1, 3).unwrap();
        let view = Some((&[0.0; 2][..], &[0.0; 2][..]));
        assert!(
            plain
                .push(&[0.0; 2], &[0.0], 0.0, &[0.0; 2], false, view)
                .is_err()
        );
        let before = c.clone();
        assert!(
            c.push(&[0.0; 2], &[0.0], 0.0, &[0.0; 2], false, None)
                .is_err()
        );
        let narrow = Some((&[0.0; 1][..], &[0.0; 2][..]));
        assert!(
            c.push(&[0.0; 2], &[0.0], 0.0, &[0.0; 2], false, narrow)
                .is_err()
        );
        assert_eq!(c, before, "a refused push stores nothing");
        let saved: HashMap<String, Tensor> = plain.to_tensors("rb").unwrap().into_iter().collect();
        let e = c.load_tensors("rb", &|n| {
            saved
                .get(n)
                .cloned()
                .ok_or_else(|| Error::Replay(format!("no {n}")))
        });
        assert!(e.is_err());
    }
}
