//! The stack's high-water mark by painting: at boot every word between the end of the static
//! data and the stack pointer gets a pattern; the lowest word that lost it is the deepest the
//! stack has been.

const PATTERN: u32 = 0xC0DE_57AC;
/// Left unpainted below the stack pointer at paint time (`paint`'s own frame).
const MARGIN: usize = 64;

unsafe extern "C" {
    /// The end of .bss (cortex-m-rt's heap start: this firmware has no heap).
    static __sheap: u32;
    /// The initial stack pointer: the top of RAM.
    static _stack_start: u32;
}

fn bottom() -> usize {
    &raw const __sheap as usize
}

fn top() -> usize {
    &raw const _stack_start as usize
}

/// Paints the free stack.
#[inline(always)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    let mut at = bottom();
    while at + 4 <= sp - MARGIN {
        // SAFETY: between the end of .bss and below the live stack: unused RAM.
        unsafe { core::ptr::write_volatile(at as *mut u32, PATTERN) };
        at += 4;
    }
}

/// Bytes of stack used at most since boot, and the bytes there are.
pub fn high_water() -> (usize, usize) {
    let mut at = bottom();
    // SAFETY: reads of RAM between .bss and the stack's top.
    while at < top() && unsafe { core::ptr::read_volatile(at as *const u32) } == PATTERN {
        at += 4;
    }
    (top() - at, top() - bottom())
}
