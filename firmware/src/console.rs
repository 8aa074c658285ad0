//! The board's console: its events, in the words `firmware-sim device` prints, written to the
//! debugger by semihosting (QEMU prints them). Without the `semihosting` feature (a real part
//! with no debugger) it says nothing, and a panic parks the core.

use core::fmt::Display;

use device_core::BoardEvent;

#[cfg(feature = "semihosting")]
macro_rules! say {
    ($($arg:tt)*) => { cortex_m_semihosting::hprintln!("{}", format_args!($($arg)*)) };
}
#[cfg(not(feature = "semihosting"))]
macro_rules! say {
    ($($arg:tt)*) => {{ let _ = format_args!($($arg)*); }};
}

/// The clock's calibration at boot.
pub fn calibration(per_us: f32) {
    // Tenths as an integer: core's float formatting alone takes kilobytes of stack.
    let tenths = (per_us * 10.0) as u32;
    say!(
        "device: clock: {}.{} instructions per microsecond of SysTick time",
        tenths / 10,
        tenths % 10
    );
}

/// One board event.
pub fn event(event: BoardEvent<'_>) {
    match event {
        BoardEvent::Booted(Some((len, crc))) => {
            say!("device: booted; flash holds a {len} B blob (CRC-32 {crc:08x})")
        }
        BoardEvent::Booted(None) => say!("device: booted; flash is empty"),
        BoardEvent::Committed { blob, crc } => {
            say!("device: blob committed: {} B, CRC-32 {crc:08x}", blob.len())
        }
        BoardEvent::Refused(reason) => say!("device: refused a message: {reason:?}"),
        BoardEvent::Taught {
            transitions,
            push_time,
        } => say!(
            "device: context taught from {transitions} transitions; z fixed; pushes {} ns",
            push_time.as_nanos()
        ),
        BoardEvent::Greeted => {
            let (used, size) = crate::stack::high_water();
            say!("device: stack high-water {used} B of {size} B")
        }
        BoardEvent::Watchdog(silent) => say!(
            "device: watchdog: no tick for {} ms; holding the safe action",
            silent.as_millis()
        ),
        BoardEvent::Resumed(tick) => say!("device: ticks resumed at tick {tick}"),
        _ => {}
    }
}

/// Reports `why` and stops the core (QEMU exits with failure).
pub fn fail(why: &dyn Display) -> ! {
    say!("device: stopped: {why}");
    halt("failed")
}

/// Stops: QEMU exits (with failure: a board never stops on purpose); silicon parks the core.
pub fn halt(why: &str) -> ! {
    say!("device: halt: {why}");
    #[cfg(feature = "semihosting")]
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    say!("device: panic: {info}");
    halt("panic")
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    say!("device: hard fault at pc {:#010x}", frame.pc());
    halt("hard fault")
}
