//! A learner's throughput clock. Its own module, below the learners that hold one and the fit
//! loop whose trait names them: in `fit.rs` it closed a circle (expert -> fit -> learner ->
//! expert).

/// Units of work per second since this process started training: the `charts/sps` every
/// learner logs (reset by its [`Learner::begin`](crate::Learner::begin)).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Throughput {
    t0: std::time::Instant,
    done0: u64,
}

impl Throughput {
    /// Starts the clock at `done` units.
    pub(crate) fn since(done: u64) -> Self {
        Self {
            t0: std::time::Instant::now(),
            done0: done,
        }
    }

    /// Units per second from the start to `done`.
    pub(crate) fn per_s(&self, done: u64) -> f64 {
        done.saturating_sub(self.done0) as f64 / self.t0.elapsed().as_secs_f64().max(1e-9)
    }
}
