//! `learner_threads = 2`: the discriminator step of each update pair runs on a long-lived
//! second thread while the SAC step runs on the caller's.
//!
//! Why a long-lived thread: the first version spawned a scoped thread per pair and measured
//! no gain (`smile bench --workload pair`, 2026-11-30): `perf sched timehist` showed the
//! discriminator step taking ~5 ms on a fresh thread against ~3 ms on the main one (a new
//! thread starts with cold gemm packing buffers and allocator arena), and under load the
//! scheduler left the short-lived thread on the main thread's core. A thread that lives for
//! the whole run keeps its buffers and gets balanced onto the other core once.
//!
//! The discriminator, encoder and their optimisers travel to the worker and back with every
//! job: the networks are shared handles (candle `Var`s, updated in place), the optimisers are
//! moved out of the run for the job's duration and always returned, even when the step
//! fails or panics, so a failed step leaves the run whole.

use std::sync::mpsc;
use std::thread::JoinHandle;

use rand_chacha::ChaCha8Rng;

use super::{DiscBatch, DiscLearner, disc_update};
use crate::model::{ContextEncoder, DiscStats, Discriminator};
use crate::optim::Adam;
use crate::{Error, Result};

/// One discriminator + encoder step to run on the worker.
pub(crate) struct DiscJob {
    pub encoder: ContextEncoder,
    pub disc: Discriminator,
    pub disc_opt: Adam,
    pub enc_opt: Adam,
    pub batch: DiscBatch,
    pub update: u64,
    pub rng: ChaCha8Rng,
    pub gp_weight: f32,
}

/// A finished job: the step's result and the optimisers, handed back.
pub(crate) struct DiscDone {
    pub stats: Result<DiscStats>,
    pub disc_opt: Adam,
    pub enc_opt: Adam,
}

/// The second learner thread.
pub(crate) struct DiscWorker {
    jobs: Option<mpsc::Sender<DiscJob>>,
    done: mpsc::Receiver<DiscDone>,
    handle: Option<JoinHandle<()>>,
}

impl DiscWorker {
    /// Starts the thread (`smile-disc`); the process-wide compute-thread setting holds there too.
    pub fn spawn() -> Result<Self> {
        let (jobs, inbox) = mpsc::channel::<DiscJob>();
        let (outbox, done) = mpsc::channel::<DiscDone>();
        let handle = std::thread::Builder::new()
            .name("smile-disc".into())
            .spawn(move || {
                for mut job in inbox {
                    // A panic in the step becomes an error reply, so the optimisers come back.
                    let stats = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        disc_update(
                            DiscLearner {
                                encoder: &job.encoder,
                                disc: &job.disc,
                                disc_opt: &mut job.disc_opt,
                                enc_opt: &mut job.enc_opt,
                                gp_weight: job.gp_weight,
                            },
                            &job.batch,
                            job.update,
                            &mut job.rng,
                        )
                    }))
                    .unwrap_or_else(|_| {
                        Err(Error::Data(format!(
                            "the discriminator step of update {} panicked",
                            job.update
                        )))
                    });
                    let reply = DiscDone {
                        stats,
                        disc_opt: job.disc_opt,
                        enc_opt: job.enc_opt,
                    };
                    if outbox.send(reply).is_err() {
                        return; // the run is gone
                    }
                }
            })
            .map_err(|e| Error::Data(format!("cannot start the discriminator thread: {e}")))?;
        Ok(Self {
            jobs: Some(jobs),
            done,
            handle: Some(handle),
        })
    }

    /// Hands `job` to the thread; gives it back if the thread is gone.
    pub fn start(&self, job: DiscJob) -> std::result::Result<(), Box<DiscJob>> {
        match &self.jobs {
            Some(jobs) => jobs.send(job).map_err(|e| Box::new(e.0)),
            None => Err(Box::new(job)),
        }
    }

    /// Waits for the job started last.
    pub fn finish(&self) -> Result<DiscDone> {
        self.done.recv().map_err(|_| Self::lost())
    }

    /// The error of a run whose worker thread is gone.
    pub fn lost() -> Error {
        Error::Data(
            "the discriminator thread stopped (it panicked: see above); the last checkpoint \
             is the last good state"
                .into(),
        )
    }
}

impl Drop for DiscWorker {
    fn drop(&mut self) {
        // Closing the job channel ends the thread's loop.
        self.jobs.take();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
