//! Counting instructions with SysTick under QEMU's `-icount shift=0`.
//!
//! With `-icount shift=0` QEMU advances its virtual clock by exactly 1 ns per executed
//! instruction, and mps2-an386's SysTick runs from the 25 MHz core clock: one SysTick
//! count per 40 instructions, deterministic from run to run. [`calibrate`] checks that
//! ratio with a loop of known length instead of assuming it; a figure is then
//! `ticks · instructions_per_tick / calls`, averaged over enough calls that the ±1-tick
//! quantisation is below 0.05 instruction per call.
#![allow(unsafe_code)]

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;

/// SysTick's counter is 24 bits wide.
const MASK: u32 = 0x00FF_FFFF;

/// Starts SysTick free-running from the core clock (reload 2^24 − 1, no interrupt).
pub fn start(mut syst: SYST) {
    syst.disable_interrupt();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(MASK);
    syst.clear_current();
    syst.enable_counter();
}

/// The current (down-counting) SysTick value.
#[inline(always)]
pub fn now() -> u32 {
    SYST::get_current()
}

/// SysTick counts elapsed since `start` (the counter counts down and wraps at 2^24;
/// a measured section must stay below 2^24 counts = 671 M instructions).
#[inline(always)]
pub fn since(start: u32) -> u32 {
    start.wrapping_sub(now()) & MASK
}

/// Instructions in the calibration loop: 2 per iteration (`subs`, `bne`).
pub const CAL_ITERATIONS: u32 = 500_000;

/// Runs a loop of exactly `2·CAL_ITERATIONS` instructions (plus the handful around it)
/// and returns the SysTick counts it took.
#[inline(never)]
pub fn calibrate() -> u32 {
    let t0 = now();
    // Note(unsafe): a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, #1",
            "bne 2b",
            n = inout(reg) CAL_ITERATIONS => _,
            options(nomem, nostack)
        );
    }
    since(t0)
}
