//! Time since boot from SysTick: a 1 ms interrupt counts milliseconds, the counter's current
//! value gives the fraction (one system-clock period, 40 ns at 25 MHz).
//!
//! Under QEMU with `-icount shift=0` one instruction is one nanosecond of virtual time, so a
//! duration read here is an instruction count: that is how docs/DEVICE.md counts `act`.

use core::sync::atomic::{AtomicU32, Ordering};
use core::time::Duration;

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;

static MILLIS: AtomicU32 = AtomicU32::new(0);
static TICKS_PER_MS: AtomicU32 = AtomicU32::new(1);
static NANOS_PER_TICK: AtomicU32 = AtomicU32::new(1);

/// Starts SysTick on the core clock `sysclk_hz`, interrupting every millisecond.
pub fn start(syst: &mut SYST, sysclk_hz: u32) {
    let per_ms = sysclk_hz / 1000;
    TICKS_PER_MS.store(per_ms, Ordering::Relaxed);
    NANOS_PER_TICK.store(1_000_000_000 / sysclk_hz, Ordering::Relaxed);
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(per_ms - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    // The counter starts at 0 and loads its reload value on its first clock; QEMU does that
    // on its own timer thread, up to a millisecond or so late. Time is counted from there.
    while MILLIS.load(Ordering::Acquire) < 2 {}
}

#[exception]
fn SysTick() {
    MILLIS.fetch_add(1, Ordering::Relaxed);
}

/// Time since [`start`], monotonic.
pub fn now() -> Duration {
    let per_ms = TICKS_PER_MS.load(Ordering::Relaxed);
    loop {
        let ms = MILLIS.load(Ordering::Acquire);
        let mut value = SYST::get_current();
        let mut whole = u64::from(ms);
        // The counter may have wrapped with its interrupt not yet taken (QEMU takes it at the
        // end of a translated block): then the value is read again, after the wrap for sure,
        // and the pending millisecond counted.
        if cortex_m::peripheral::SCB::is_pendst_pending() {
            value = SYST::get_current();
            whole += 1;
        }
        if MILLIS.load(Ordering::Acquire) == ms {
            let ticks = per_ms.saturating_sub(1).saturating_sub(value);
            let nanos = ticks * NANOS_PER_TICK.load(Ordering::Relaxed);
            return Duration::from_millis(whole) + Duration::from_nanos(u64::from(nanos));
        }
    }
}

/// Runs a loop of a known number of instructions and returns instructions per microsecond of
/// this clock (1000 under `-icount shift=0`; on silicon, the core's MHz over its CPI).
pub fn instructions_per_microsecond() -> f32 {
    const ITERATIONS: u32 = 500_000;
    let start = now();
    // Two instructions per iteration: a subtract and a taken branch.
    // SAFETY: a register-only loop.
    unsafe {
        core::arch::asm!("2:", "subs {n}, #1", "bne 2b", n = inout(reg) ITERATIONS => _);
    }
    let took = now().saturating_sub(start).as_nanos().max(1) as f32;
    2.0 * ITERATIONS as f32 / (took / 1000.0)
}
