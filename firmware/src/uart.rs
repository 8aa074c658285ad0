//! The CMSDK APB UART of the MPS2 boards (UART0 at 0x4000_4000): polled, 8N1.

use core::ptr::{read_volatile, write_volatile};

/// Register word offsets (Arm CMSDK APB UART, DDI0479).
const DATA: usize = 0;
const STATE: usize = 1;
const CTRL: usize = 2;
const BAUDDIV: usize = 4;
/// STATE bits.
const TX_FULL: u32 = 1 << 0;
const RX_FULL: u32 = 1 << 1;
/// CTRL bits.
const TX_ENABLE: u32 = 1 << 0;
const RX_ENABLE: u32 = 1 << 1;

/// One UART.
pub struct Uart {
    base: *mut u32,
}

impl Uart {
    /// UART0, enabled at `baud` from a `sysclk_hz` clock.
    pub fn uart0(sysclk_hz: u32, baud: u32) -> Self {
        let uart = Self {
            base: 0x4000_4000 as *mut u32,
        };
        // SAFETY: UART0's registers on the MPS2 memory map; this driver is their only user.
        unsafe {
            write_volatile(uart.base.add(BAUDDIV), sysclk_hz / baud);
            write_volatile(uart.base.add(CTRL), TX_ENABLE | RX_ENABLE);
        }
        uart
    }

    /// The received byte, if one is waiting.
    pub fn read(&mut self) -> Option<u8> {
        // SAFETY: as in `uart0`.
        unsafe {
            (read_volatile(self.base.add(STATE)) & RX_FULL != 0)
                .then(|| read_volatile(self.base.add(DATA)) as u8)
        }
    }

    /// Sends one byte, waiting while the transmitter is full.
    pub fn write(&mut self, byte: u8) {
        // SAFETY: as in `uart0`.
        unsafe {
            while read_volatile(self.base.add(STATE)) & TX_FULL != 0 {}
            write_volatile(self.base.add(DATA), u32::from(byte));
        }
    }
}
