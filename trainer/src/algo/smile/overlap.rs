//! SMILe on N > 1 learner threads (`learner_threads >= 2`): the work beside the update pairs.
//! The algorithm (`algo/smile.rs`) asks three things of this module: [`Smile::start_rollouts`]
//! and [`Smile::land_rollouts`] around an iteration's pairs, and [`Smile::overlapped_pair`].
//!
//! **The pair's two halves at once.** The discriminator's half (batch, loss, gradients) and the
//! SAC half (its batch, rewarded by the discriminator as it is before this pair, and its
//! steps) run as the sides of a `rayon::join`; the discriminator's and encoder's optimiser
//! steps follow. Their large matrix products are split across the pool and the side that
//! finishes first steals the other's blocks (`crate::threads`). Both sides only read the
//! networks, data and replay; every random draw has a fixed order (the discriminator side
//! draws from its own RNG, seeded from the run's RNG before the join; the SAC side from the
//! run's RNG alone), so a run is deterministic for a seed and thread count.
//!
//! **Rollouts off the learner's critical path.** Each iteration of Algorithm 1 adds `rollouts_per_iter` episodes to the task replays and then
//! runs `updates_per_iter` update pairs. Run one after the other, the rollouts leave every core
//! but one idle while they step the simulator (about 3 ms per pair at the authors' cheetah
//! recipe, docs/BENCHMARKS.md). With a learner pool they run as one job on a pool thread
//! *during* the iteration's pairs instead:
//!
//! * planned on the learner's thread first, drawing from the run's RNG in the order the
//!   sequential rollouts draw (task, context, z, for each episode in turn), then one seed for
//!   the job's own RNG, which samples the actions;
//! * acted with a copy of the policy in its own storage, taken when the iteration starts: the
//!   policy the sequential rollouts would act with (the pairs update the live one in place);
//! * their transitions enter the replays after the iteration's pairs, so those pairs sample
//!   the replays without them: the one way this differs from the sequential schedule.
//!
//! A pool thread that picks the job up steps episodes while the other threads run the pairs'
//! products (the pool's threads steal each other's blocks, so none waits). Where the job runs
//! and when it finishes does not change any value: the run stays deterministic for a seed and
//! thread count.

use std::sync::mpsc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{Environment, Task};

use super::batch::DiscBatch;
use super::{Smile, disc_loss, sac_update};
use crate::algo::sac::SacStats;
use crate::data::{Sensing, TaskReplay, sensed_episode};
use crate::error::{Error, Result};
use crate::model::{DiscStats, ObsNorm, TanhGaussianPolicy};
use crate::threads::LearnerPool;

impl Smile {
    /// The learner pool, started at its first use.
    fn pool(&mut self) -> Result<LearnerPool> {
        match self.pool.take() {
            Some(p) => Ok(p),
            None => LearnerPool::new(self.cfg.learner_threads),
        }
    }

    /// One update pair with both halves at once (the module doc), inside the learner pool.
    pub(super) fn overlapped_pair(&mut self) -> Result<(DiscStats, SacStats, f32)> {
        let pool = self.pool()?;
        let out = pool.install(|| self.pair_in_pool());
        self.pool = Some(pool);
        out
    }

    /// [`Self::overlapped_pair`] inside the pool. Nothing but the discriminator side's seed
    /// is drawn before the join, so neither core waits there.
    fn pair_in_pool(&mut self) -> Result<(DiscStats, SacStats, f32)> {
        let mut disc_rng = ChaCha8Rng::seed_from_u64(self.rng.random());
        let (source, sac, rng) = self.parts();
        let (d, s) = rayon::join(
            || {
                let batch = source.disc_batch(&mut disc_rng)?;
                let (gp, u) = (source.cfg.gp_weight, source.updates);
                disc_loss(source.encoder, source.disc, gp, &batch, u, &mut disc_rng)
            },
            || sac_update(&source, sac, rng),
        );
        let ((grads, ds), (ss, reward_mean)) = (d?, s?);
        self.disc_opt.step(&grads)?;
        self.enc_opt.step(&grads)?;
        Ok((ds, ss, reward_mean))
    }

    /// Starts an iteration's `n` rollouts on the learner pool (the module doc), to run beside
    /// its pairs: planned here with the draws of `n` sequential rollouts from the run's RNG
    /// (task, context, z, for each in turn), then the job's own RNG's seed.
    pub(super) fn start_rollouts(&mut self, n: usize) -> Result<InFlight> {
        let mut episodes = Vec::with_capacity(n);
        for _ in 0..n {
            let ti = self.rng.random_range(0..self.data.train.len());
            let z = self.rollout_z(ti)?;
            episodes.push(PlannedEpisode {
                task_index: ti,
                task: self.data.train[ti].task,
                seed: self.episode_seed(),
                z,
            });
            self.episodes += 1;
        }
        let env = match self.rollout_env.take() {
            Some(env) => env,
            None => sim::make_env(self.cfg.env, self.cfg.rollout_env_config())?,
        };
        let job = RolloutJob {
            actor: self.sac.actor.deep_copy()?,
            norm: self.data.norm.clone(),
            env,
            episodes,
            sensing: self.cfg.sensing,
            rng: ChaCha8Rng::seed_from_u64(self.rng.random()),
        };
        let pool = self.pool()?;
        let in_flight = job.start(&pool);
        self.pool = Some(pool);
        Ok(in_flight)
    }

    /// Waits for the rollouts of [`Self::start_rollouts`] and adds them to the replays.
    pub(super) fn land_rollouts(&mut self, in_flight: InFlight) -> Result<()> {
        let done = in_flight.wait()?;
        done.store(&mut self.replay)?;
        self.env_steps += done.steps;
        self.rollout_env = Some(done.env);
        Ok(())
    }
}

/// One planned episode: its training task, the task, the reset seed and the context's z.
struct PlannedEpisode {
    task_index: usize,
    task: Task,
    seed: u64,
    z: Vec<f32>,
}

/// A batch of episodes with everything they need, owned (it runs on another thread).
struct RolloutJob {
    actor: TanhGaussianPolicy,
    norm: ObsNorm,
    env: Box<dyn Environment>,
    episodes: Vec<PlannedEpisode>,
    sensing: Option<Sensing>,
    rng: ChaCha8Rng,
}

/// One episode's transitions, row-major.
#[derive(Default)]
struct Transitions {
    obs: Vec<f32>,
    act: Vec<f32>,
    next_obs: Vec<f32>,
    terminated: Vec<bool>,
    /// The states and next states as the policy read them (position-only sensing), else empty.
    view_obs: Vec<f32>,
    view_next_obs: Vec<f32>,
}

/// What a finished job brings back: its environment (for the next job) and the episodes.
struct RolloutsDone {
    env: Box<dyn Environment>,
    episodes: Vec<(usize, Transitions)>,
    /// Environment steps taken, all episodes together.
    steps: u64,
}

impl RolloutsDone {
    /// Adds every episode to its task's replay, in the planned order.
    fn store(&self, replay: &mut TaskReplay) -> Result<()> {
        for (ti, tr) in &self.episodes {
            let buf = replay.task_mut(*ti);
            let (od, ad) = (self.env.obs_dim(), self.env.act_dim());
            for (r, &term) in tr.terminated.iter().enumerate() {
                let row = r * od..(r + 1) * od;
                let (o, a, o2) = (
                    &tr.obs[row.clone()],
                    &tr.act[r * ad..(r + 1) * ad],
                    &tr.next_obs[row.clone()],
                );
                let view = (!tr.view_obs.is_empty())
                    .then(|| (&tr.view_obs[row.clone()], &tr.view_next_obs[row]));
                buf.push(o, a, 0.0, o2, term, view)?;
            }
        }
        Ok(())
    }
}

impl RolloutJob {
    /// Runs the planned episodes one after the other.
    fn run(mut self) -> Result<RolloutsDone> {
        let (mut episodes, mut steps) = (Vec::with_capacity(self.episodes.len()), 0u64);
        let (actor, norm, rng) = (&self.actor, &self.norm, &mut self.rng);
        for ep in &self.episodes {
            let mut tr = Transitions::default();
            let out = sensed_episode(
                self.env.as_mut(),
                &ep.task,
                ep.seed,
                self.sensing.as_ref(),
                &mut |o, a| {
                    let mut x = norm.apply(o);
                    x.extend_from_slice(&ep.z);
                    a.copy_from_slice(&actor.act(&x, false, rng)?);
                    Ok(())
                },
                &mut |st| {
                    tr.obs.extend_from_slice(st.obs);
                    tr.act.extend_from_slice(st.action);
                    tr.next_obs.extend_from_slice(st.next_obs);
                    tr.terminated.push(st.terminated);
                    if let Some((v, v2)) = st.sensed {
                        tr.view_obs.extend_from_slice(v);
                        tr.view_next_obs.extend_from_slice(v2);
                    }
                    Ok(())
                },
            )?;
            steps += out.steps as u64;
            episodes.push((ep.task_index, tr));
        }
        Ok(RolloutsDone {
            env: self.env,
            episodes,
            steps,
        })
    }

    /// Starts the job on a thread of `pool`; [`InFlight::wait`] returns its result.
    fn start(self, pool: &LearnerPool) -> InFlight {
        let (tx, rx) = mpsc::channel();
        pool.spawn(move || {
            // The receiver only goes away when the learner has already failed.
            let _ = tx.send(self.run());
        });
        InFlight {
            rx,
            threads: pool.threads(),
        }
    }
}

/// A job running on the pool.
pub(super) struct InFlight {
    rx: mpsc::Receiver<Result<RolloutsDone>>,
    threads: usize,
}

impl InFlight {
    /// Waits for the job's result.
    fn wait(self) -> Result<RolloutsDone> {
        self.rx.recv().map_err(|_| Error::Threads {
            threads: self.threads,
            reason: "the rollout job stopped without a result (a learner thread panicked)".into(),
        })?
    }
}

/// The gradients of `L_bce` and of `lambda_gp L_gp`'s shares (`gp` on rows `(start, len)`),
/// the shares in row order. Inside a learner pool the penalty is two halves of the tasks (a
/// mean over rows is the halves' means weighted by their rows), and the three run as the sides
/// of joins, pieces a free core can take whole instead of only the blocks of their matrix
/// products: 2% off a two-thread pair at the authors' shapes. One thread keeps the penalty
/// whole (1% faster there).
pub(super) fn bce_and_penalty<B: Send, G: Send>(
    bce: impl FnOnce() -> Result<B> + Send,
    gp: impl Fn((usize, usize)) -> Result<Option<G>> + Sync,
    batch: &DiscBatch,
) -> Result<(B, [Option<G>; 2])> {
    let rows = batch.tasks * batch.per_task;
    let half = if crate::threads::in_pool() {
        (batch.tasks / 2) * batch.per_task
    } else {
        rows
    };
    let (bce, (a, b)) = crate::threads::join(bce, || {
        crate::threads::join(|| gp((0, half)), || gp((half, rows - half)))
    });
    Ok((bce?, [a?, b?]))
}
