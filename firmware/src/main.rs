//! SMILe's device firmware for a Cortex-M4F: `device-core`'s board (bootloader, application,
//! watchdog; `docs/PROTOCOL.md`) served over the UART of the Arm MPS2 AN386 board that QEMU
//! models, with a policy blob's flash region, a SysTick clock and a painted stack.
//!
//! Boot it: `scripts/build-firmware.sh`, then
//! `qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -monitor none
//! -serial pty -semihosting-config enable=on,target=native -kernel <elf>` and drive the
//! pseudo-terminal QEMU names with `firmware-sim host --port /dev/pts/N --baud 0`.
#![no_std]
#![no_main]

mod clock;
mod console;
mod stack;
mod uart;

use core::time::Duration;

use cortex_m_rt::entry;
use device_core::{BoardConfig, Device, DeviceConfig, FrameReader, MAX_FRAME, Port};

use crate::uart::Uart;

/// The board's system clock: the MPS2's 25 MHz (the UART's baud divider and SysTick run on it).
const SYSCLK_HZ: u32 = 25_000_000;
/// The UART's line rate (docs/PROTOCOL.md's default).
const BAUD: u32 = 115_200;
/// The blob's flash region: the 64 KiB budget of firmware-sim's device.
const BLOB_FLASH_BYTES: usize = 64 * 1024;

/// The flash region the bootloader writes blobs into, word aligned for infer-core's tables.
#[repr(C, align(4))]
struct BlobFlash([u8; BLOB_FLASH_BYTES]);

#[unsafe(link_section = ".blob_flash")]
static mut BLOB_FLASH: BlobFlash = BlobFlash([0xFF; BLOB_FLASH_BYTES]);

/// The board's port: the UART, a frame being assembled, the SysTick clock.
struct UartPort {
    uart: Uart,
    reader: FrameReader,
}

impl Port for UartPort {
    type Error = core::convert::Infallible;

    fn receive(
        &mut self,
        frame: &mut [u8; MAX_FRAME],
        wait: Duration,
    ) -> Result<Option<usize>, Self::Error> {
        let until = clock::now() + wait;
        loop {
            while let Some(byte) = self.uart.read() {
                if let Some(got) = self.reader.push(byte) {
                    frame[..got.len()].copy_from_slice(got);
                    return Ok(Some(got.len()));
                }
            }
            if clock::now() >= until {
                return Ok(None);
            }
        }
    }

    fn send(&mut self, frame: &[u8]) -> Result<(), Self::Error> {
        for &byte in frame {
            self.uart.write(byte);
        }
        Ok(())
    }

    fn now(&self) -> Duration {
        clock::now()
    }
}

#[entry]
fn main() -> ! {
    // Before anything else takes stack: everything below here is painted, so the deepest
    // write the board ever makes can be read back (`stack::high_water`).
    stack::paint();
    run()
}

/// The board: clocks, UART, flash region, then device-core's state machine for ever.
#[inline(never)]
fn run() -> ! {
    let mut core = cortex_m::Peripherals::take().expect("taken once, at boot");
    clock::start(&mut core.SYST, SYSCLK_HZ);
    console::calibration(clock::instructions_per_microsecond());
    // SAFETY: the only reference to the region, taken once at boot; the bootloader owns it.
    let flash: &'static mut [u8] = unsafe { &mut (*(&raw mut BLOB_FLASH)).0 };
    let mut device = Device::new(flash, DeviceConfig::default());
    let config = BoardConfig::default();
    let mut port = UartPort {
        uart: Uart::uart0(SYSCLK_HZ, BAUD),
        reader: FrameReader::default(),
    };
    match device_core::serve(&mut port, &mut device, &config, &mut console::event) {
        Ok(()) => console::halt("the board stopped serving"),
        Err(e) => console::fail(&e),
    }
}
