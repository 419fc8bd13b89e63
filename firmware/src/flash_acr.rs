//! The flash interface's accelerator (ART, RM0090 §3.5.2): prefetch, instruction cache
//! and data cache.
//!
//! embassy-stm32 0.6 writes `FLASH_ACR` with the wait states only (5 at 168 MHz), so
//! all three stay off after its init and every flash fetch waits 5 cycles per 128-bit
//! line: code runs 2–3× slower than with them on. [`enable_accelerator`] turns them on
//! right after the clock init; the cycle estimates of docs/bench.md assume they are on.
//!
//! The data cache holds flash *data* (constants, and the table slots when read back),
//! so after any program or erase of the slots it is reset ([`reset_data_cache`]) before
//! the next read (RM0090: DCRST only while DCEN = 0). The instruction cache needs no
//! reset: the program sectors are never written.

use embassy_stm32::pac;

/// Prefetch, instruction and data cache on (each cache reset first, as RM0090 asks).
pub fn enable_accelerator() {
    let acr = pac::FLASH.acr();
    acr.modify(|w| {
        w.set_icen(false);
        w.set_dcen(false);
    });
    acr.modify(|w| {
        w.set_icrst(true);
        w.set_dcrst(true);
    });
    acr.modify(|w| {
        w.set_icrst(false);
        w.set_dcrst(false);
    });
    acr.modify(|w| {
        w.set_prften(true);
        w.set_icen(true);
        w.set_dcen(true);
    });
}

/// Discards the data cache's lines (after a program or erase), leaving it on if it was.
#[cfg_attr(feature = "console", allow(dead_code))]
pub fn reset_data_cache() {
    let acr = pac::FLASH.acr();
    let on = acr.read().dcen();
    acr.modify(|w| w.set_dcen(false));
    acr.modify(|w| w.set_dcrst(true));
    acr.modify(|w| w.set_dcrst(false));
    if on {
        acr.modify(|w| w.set_dcen(true));
    }
}

/// Whether prefetch and both caches are on (reported at boot).
pub fn accelerator_on() -> bool {
    let a = pac::FLASH.acr().read();
    a.prften() && a.icen() && a.dcen()
}
