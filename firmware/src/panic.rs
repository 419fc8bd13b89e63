//! The last line of defence: panics and hard faults put the valves at null first.
//!
//! `panic-probe` cannot do this (it only logs and halts), so the handlers here, before
//! anything else — with interrupts disabled, so the tick cannot run again — write every
//! on-chip DAC channel's calibrated null code straight into its data register through
//! the PAC and drive the valve-power enable low through the GPIO's bit-set/reset
//! register; only then do they log. They then spin without feeding the independent
//! watchdog, which resets the board within its timeout; the runtime boots latched in
//! `Fault::Watchdog` (code 0x0200), so a panic always ends in a reported fault that
//! only an operator can clear. The writes are single stores to registers whose clocks
//! `Board::new` enabled; a panic earlier than that finds the enable pin still in its
//! reset state (input, held low by the board's pull-down) and the DAC off.

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};
use embassy_stm32::pac;

use crate::board::{ENABLE_PIN, ENABLE_PORT};
use crate::valves::SAFE_CODES;

static PANICKED: AtomicBool = AtomicBool::new(false);

/// Valves to null, valve power off. Callable from any context.
#[inline(always)]
pub fn safe_state() {
    cortex_m::interrupt::disable();
    for (i, c) in SAFE_CODES.iter().enumerate() {
        let code = c.load(Ordering::Relaxed);
        pac::DAC1.dhr12r(i).write(|w| w.set_dhr(code));
    }
    ENABLE_PORT.bsrr().write(|w| w.set_br(ENABLE_PIN, true));
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    safe_state();
    // A panic while logging must not recurse into the logger.
    if !PANICKED.swap(true, Ordering::Relaxed) {
        defmt::error!("PANIC: {}", defmt::Display2Format(info));
    }
    loop {
        // No watchdog feed: the IWDG resets the board.
        cortex_m::asm::nop();
    }
}

// Note(unsafe): cortex-m-rt requires the HardFault handler to be an `unsafe fn`; it only
// performs the register stores of `safe_state`.
#[allow(unsafe_code)]
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    safe_state();
    loop {
        cortex_m::asm::nop();
    }
}

/// How the board came out of reset: reads and clears the reset flags (call first).
pub fn boot_cause() -> hydra_core::runtime::BootCause {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    if csr.wdgrstf() {
        hydra_core::runtime::BootCause::Watchdog
    } else {
        hydra_core::runtime::BootCause::Normal
    }
}

/// Stops the watchdog and the tick timer while a debugger halts the core.
pub fn freeze_in_debug() {
    pac::DBGMCU.apb1fzr().modify(|w| {
        w.set_iwdg(true);
        w.set_tim7(true);
    });
}
