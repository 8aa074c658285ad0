//! Compute thread layout, the learner's thread pool, and the allocator setting that keeps
//! freed tensor memory.
//!
//! **The learner's cores** ([`LearnerPool`]): a run given N learner threads (SMILe's
//! `learner_threads`, `smile expert --learner-threads`) runs its updates inside a rayon pool of
//! N threads. Inside it, every large matrix product of the fused layers is cut into N blocks
//! that idle threads steal (`model::fused::gemm_into`), and SMILe runs its discriminator and
//! SAC steps as the two sides of a `rayon::join`: the thread that finishes its step first
//! helps with the other's products instead of waiting. Outside a pool everything runs on the
//! calling thread.
//!
//! Measured on the project's 2-vCPU machines (DESIGN.md): candle's matmul with its default
//! thread count (one per core) made a 256-wide MLP train step about 8x *slower* than with one
//! thread, because the learner, the rollout thread and the gemm workers oversubscribe two cores.
//! The layout used here: the learner runs candle single-threaded on the main thread and
//! environment rollouts run on their own thread, so each uses one core.
//!
//! candle-core 0.11 reads the matmul thread count from `RAYON_NUM_THREADS` on every matmul
//! (`candle_core::utils::get_num_threads`), and `CANDLE_NUM_THREADS` once for its barrier pool.

/// Sets candle's compute thread count by setting `RAYON_NUM_THREADS` and `CANDLE_NUM_THREADS`.
///
/// Call it first thing in `main` (or a test), before any other thread is spawned: it mutates
/// the process environment. Returns the value previously set, if any.
pub fn set_compute_threads(n: usize) -> Option<String> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let n = n.max(1).to_string();
    let prev = std::env::var("RAYON_NUM_THREADS").ok();
    if prev.as_deref() == Some(n.as_str())
        && std::env::var("CANDLE_NUM_THREADS").ok().as_deref() == Some(n.as_str())
    {
        // Already set: do not write the environment again (tests call this from many threads).
        return prev;
    }
    // SAFETY: documented precondition: called before other threads exist, or (tests) first
    // thing in every test with the same value, so after the first call nothing is written.
    unsafe {
        std::env::set_var("RAYON_NUM_THREADS", &n);
        std::env::set_var("CANDLE_NUM_THREADS", &n);
    }
    prev
}

/// N learner threads (see the module doc); one thread is no pool at all.
#[derive(Debug)]
pub struct LearnerPool {
    pool: Option<rayon::ThreadPool>,
    threads: usize,
}

impl LearnerPool {
    /// A pool of `threads` threads (`smile-learner-{i}`); 0 or 1 runs on the caller's thread.
    pub fn new(threads: usize) -> crate::error::Result<Self> {
        let threads = threads.max(1);
        let pool = if threads > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("smile-learner-{i}"))
                    .build()
                    .map_err(|e| crate::error::Error::Threads {
                        threads,
                        reason: e.to_string(),
                    })?,
            )
        } else {
            None
        };
        Ok(Self { pool, threads })
    }

    /// Its thread count.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Starts `f` on a thread of the pool and returns at once (a thread that is free picks it
    /// up; on a busy pool it waits its turn); without a pool `f` runs here, now.
    pub fn spawn(&self, f: impl FnOnce() + Send + 'static) {
        match &self.pool {
            Some(p) => p.spawn(f),
            None => f(),
        }
    }

    /// Runs `f` inside the pool (on the calling thread without one), the caller waiting.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) => p.install(f),
            None => f(),
        }
    }
}

/// Whether the caller runs inside a learner pool of two or more threads.
pub fn in_pool() -> bool {
    rayon::current_thread_index().is_some() && rayon::current_num_threads() > 1
}

/// Runs `a` and `b` as the two sides of a `rayon::join` inside a learner pool of two or more
/// threads (a free thread takes `b` whole), and one after the other, `a` first, elsewhere
/// (one learner thread, or outside any pool: never rayon's global pool).
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    if in_pool() {
        rayon::join(a, b)
    } else {
        let ra = a();
        (ra, b())
    }
}

/// `skip_serializing_if` of the configs' `learner_threads` (1, the default, is not written, so
/// configs and checkpoints of one-thread runs stay as they were).
pub(crate) fn is_one(v: &usize) -> bool {
    *v == 1
}

/// The most learner threads a run accepts.
pub const MAX_LEARNER_THREADS: usize = 256;

/// Checks a config's `learner_threads` (1 to [`MAX_LEARNER_THREADS`]).
pub(crate) fn check_learner_threads(v: usize) -> crate::error::Result<()> {
    if (1..=MAX_LEARNER_THREADS).contains(&v) {
        Ok(())
    } else {
        Err(crate::error::Error::Config(format!(
            "learner_threads must be 1 to {MAX_LEARNER_THREADS}, not {v}"
        )))
    }
}

/// The thread count candle's matmul currently uses.
pub fn compute_threads() -> usize {
    candle_core::utils::get_num_threads()
}

/// CPU time this process has used so far, user plus system, over every thread (`getrusage`),
/// in seconds; `None` where the platform does not say.
///
/// A compute budget counted in it (SMILe's `cpu_budget_s`) gives two runs the same compute
/// whatever else the machine runs beside them, which a wall-clock budget on a shared machine
/// does not.
pub fn process_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        // SAFETY: getrusage writes one plain struct that we own; RUSAGE_SELF is always valid.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
            return None;
        }
        let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
        Some(secs(u.ru_utime) + secs(u.ru_stime))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Makes glibc keep freed memory for reuse instead of returning it to the kernel (Linux with
/// glibc; a no-op elsewhere). Returns whether the settings took.
///
/// candle allocates every intermediate tensor afresh and frees it right after; with glibc's
/// defaults, blocks of a few hundred KB to MB are `mmap`ed and unmapped, or the heap top is
/// trimmed, on every step, and each reuse page-faults the memory back in. Measured with
/// `smile bench --workload disc` (2-vCPU EPYC, 2026-11-30): a third of the time was in the
/// kernel, and the discriminator step took 2.4x longer at H = 64 (8.0 vs 3.3 ms). Raising the
/// mmap threshold to its maximum (32 MiB) and the trim threshold to 1 GiB keeps the pages;
/// the process's resident memory then stays at its peak, which a trainer reaches in its first
/// steps anyway. Call it first thing in `main`, before threads exist.
pub fn keep_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only changes allocator parameters; called before other threads run.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn process_cpu_seconds_counts_work() {
        let a = super::process_cpu_seconds().expect("unix reports CPU time");
        // About 50 ms of arithmetic the optimiser cannot drop.
        let t = std::time::Instant::now();
        let mut x = 1.0f64;
        while t.elapsed().as_millis() < 50 {
            x = std::hint::black_box(x * 1.000_001 + 1e-9);
        }
        let b = super::process_cpu_seconds().unwrap();
        assert!(x.is_finite());
        assert!(b - a >= 0.02, "{a} -> {b}");
    }

    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn glibc_accepts_the_allocator_settings() {
        assert!(super::keep_freed_memory());
    }
}
