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
//!
//! A boot failure is visible: the panic loop blinks the status LED at 10 Hz and the
//! hard-fault loop at 20 Hz (LED register writes, no driver), for the watchdog's fault
//! timeout (≥ 22 s), then the board resets and tries again. docs/firmware.md "Boot".

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};
use embassy_stm32::pac;

use crate::consts::{ENABLE_PIN, ENABLE_PORT};
use crate::valves::SAFE_CODES;
use crate::watchdog::{self, Timeout};

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
    fault_loop(BLINK_PANIC_HALF_PERIOD)
}

/// LED half-period in the panic loop, CPU cycles (≈ 50 ms at 168 MHz: 10 Hz blink; at the
/// 16 MHz HSI of a board whose clock init never finished, 0.5 s: 1 Hz).
const BLINK_PANIC_HALF_PERIOD: u32 = 8_400_000;
/// LED half-period in the hard-fault loop (≈ 25 ms: 20 Hz, told apart from a panic).
const BLINK_HARDFAULT_HALF_PERIOD: u32 = 4_200_000;

/// The end of every panic and hard fault, valves already safe: the watchdog is set to
/// its longest timeout ([`Timeout::FAULT`], ≥ 22 s) and never fed, and meanwhile the
/// status LED (PD12) blinks by direct register writes (its clock enabled here, so this
/// works before `Board::new` too). Then the IWDG resets the board, which boots latched
/// in `Fault::Watchdog`. Uses a few words of stack only.
#[inline(never)]
fn fault_loop(half_period_cycles: u32) -> ! {
    watchdog::set(Timeout::FAULT);
    pac::RCC.ahb1enr().modify(|w| w.set_gpioden(true));
    pac::GPIOD
        .moder()
        .modify(|w| w.set_moder(LED_PIN, pac::gpio::vals::Moder::OUTPUT));
    let mut on = false;
    loop {
        on = !on;
        pac::GPIOD.bsrr().write(|w| {
            if on {
                w.set_bs(LED_PIN, true)
            } else {
                w.set_br(LED_PIN, true)
            }
        });
        cortex_m::asm::delay(half_period_cycles);
    }
}

/// The status LED's pin on port D (PD12, `crate::board`).
const LED_PIN: usize = 12;

// The hard-fault entry. A stack overflow (flip-link puts the stack at the bottom of RAM,
// so it runs off into unmapped memory below 0x2000_0000) faults on a push; the stack
// pointer is then invalid, so the handler's first instruction moves it back to the top
// of the stack (`_stack_start`) before any Rust code pushes a register. Nothing returns
// from a hard fault here, so the old stack is not needed. If even the exception entry's
// own stacking fails, the core can lock up instead: the watchdog (tick timeout, ≤ 94 ms)
// then resets the board, whose pins come out of reset with the valve power off (PE7 an
// input, pulled down on the board) and the DAC disabled.
// Note(unsafe): three instructions that only reload MSP and branch; replaces
// cortex-m-rt's `HardFault` (its trampoline would push onto the broken stack first).
#[allow(unsafe_code)]
mod hard_fault_entry {
    core::arch::global_asm!(
    ".section .text.HardFault,\"ax\",%progbits",
    ".global HardFault",
    ".type HardFault,%function",
    ".thumb_func",
    "HardFault:",
    "    ldr r0, =_stack_start",
    "    msr msp, r0",
    "    b {handler}",
    ".ltorg",
    ".size HardFault, . - HardFault",
    handler = sym super::hard_fault_on_fresh_stack,
    );
}

/// The hard fault, on a fresh stack (see the `HardFault` entry above): valves safe, then
/// the fault loop.
pub(crate) extern "C" fn hard_fault_on_fresh_stack() -> ! {
    safe_state();
    fault_loop(BLINK_HARDFAULT_HALF_PERIOD)
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
