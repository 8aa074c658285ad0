//! Rollouts off the learner's critical path (`learner_threads >= 2`).
//!
//! Each iteration of Algorithm 1 adds `rollouts_per_iter` episodes to the task replays and then
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

use rand_chacha::ChaCha8Rng;
use sim::{Environment, Task};

use crate::data::{TaskReplay, run_episode};
use crate::error::{Error, Result};
use crate::model::{ObsNorm, TanhGaussianPolicy};
use crate::threads::LearnerPool;

/// One planned episode: its training task, the task, the reset seed and the context's z.
pub(super) struct PlannedEpisode {
    pub(super) task_index: usize,
    pub(super) task: Task,
    pub(super) seed: u64,
    pub(super) z: Vec<f32>,
}

/// A batch of episodes with everything they need, owned (it runs on another thread).
pub(super) struct RolloutJob {
    pub(super) actor: TanhGaussianPolicy,
    pub(super) norm: ObsNorm,
    pub(super) env: Box<dyn Environment>,
    pub(super) episodes: Vec<PlannedEpisode>,
    pub(super) rng: ChaCha8Rng,
}

/// One episode's transitions, row-major.
#[derive(Default)]
struct Transitions {
    obs: Vec<f32>,
    act: Vec<f32>,
    next_obs: Vec<f32>,
    terminated: Vec<bool>,
}

/// What a finished job brings back: its environment (for the next job) and the episodes.
pub(super) struct RolloutsDone {
    pub(super) env: Box<dyn Environment>,
    episodes: Vec<(usize, Transitions)>,
    /// Environment steps taken, all episodes together.
    pub(super) steps: u64,
}

impl RolloutsDone {
    /// Adds every episode to its task's replay, in the planned order.
    pub(super) fn store(&self, replay: &mut TaskReplay) -> Result<()> {
        for (ti, tr) in &self.episodes {
            let buf = replay.task_mut(*ti);
            let (od, ad) = (self.env.obs_dim(), self.env.act_dim());
            for (r, &term) in tr.terminated.iter().enumerate() {
                buf.push(
                    &tr.obs[r * od..(r + 1) * od],
                    &tr.act[r * ad..(r + 1) * ad],
                    0.0,
                    &tr.next_obs[r * od..(r + 1) * od],
                    term,
                )?;
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
            let out = run_episode(
                self.env.as_mut(),
                &ep.task,
                ep.seed,
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
    pub(super) fn start(self, pool: &LearnerPool) -> InFlight {
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
    pub(super) fn wait(self) -> Result<RolloutsDone> {
        self.rx.recv().map_err(|_| Error::Threads {
            threads: self.threads,
            reason: "the rollout job stopped without a result (a learner thread panicked)".into(),
        })?
    }
}
