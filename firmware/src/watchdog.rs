//! The independent watchdog (IWDG, RM0090 §19), register level: started first thing at
//! reset, fed only by the tick.
//!
//! The IWDG counts down at LSI / prescaler; the F407's LSI is 17 … 47 kHz (32 kHz
//! nominal, DS8626), so every timeout below spans a factor 2.8. Once started it cannot
//! be stopped; only a reset stops it.
//!
//! | phase | prescaler · reload | nominal (32 kHz) | at 47 kHz … 17 kHz | set by |
//! |---|---|---|---|---|
//! | boot (reset → first tick) | /32 · 500 | 500 ms | 340 … 941 ms | [`start`] in `main`, before clock init |
//! | running | /4 · 400 | 50 ms | 34 … 94 ms | [`Timeout::TICK`] when the tick starts |
//! | flash erase (tick paused) | /256 · 1500 | 12.0 s | 8.2 … 22.6 s | `crate::tick::stalled` |
//! | panic / hard fault (LED blinks) | /256 · 4096 | 32.8 s | 22.3 … 61.7 s | `crate::panic` |
//!
//! The boot timeout covers the boot sequence's worst case (docs/firmware.md "Boot"):
//! if the HSE crystal never starts, embassy's clock init waits for `HSERDY` forever and
//! this watchdog resets the board after at most 941 ms, with the valve power still off.

use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};

/// A prescaler and reload pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct Timeout {
    /// LSI divider, 4 … 256.
    pub prescaler: u16,
    /// Reload value, 1 … 4096 counts.
    pub reload: u16,
}

impl Timeout {
    /// From reset to the first tick.
    pub const BOOT: Self = Self {
        prescaler: 32,
        reload: 500,
    };
    /// While the tick runs (fed every period).
    pub const TICK: Self = Self {
        prescaler: 4,
        reload: 400,
    };
    /// While a flash erase stalls the CPU (≥ 8.2 s against 2 s worst case at x32).
    pub const STALL: Self = Self {
        prescaler: 256,
        reload: 1500,
    };
    /// In the panic and hard-fault loops: the LED blinks for ≥ 22 s, then the reset.
    pub const FAULT: Self = Self {
        prescaler: 256,
        reload: 4096,
    };

    /// The timeout in µs at an LSI of `lsi_hz`.
    pub const fn us_at(self, lsi_hz: u32) -> u32 {
        let ticks = self.prescaler as u64 * self.reload as u64 * 1_000_000;
        (ticks / lsi_hz as u64) as u32
    }

    fn pr(self) -> Pr {
        // /4 = 0 … /256 = 6.
        let log2 = 31u32.saturating_sub(u32::from(self.prescaler).leading_zeros());
        Pr::from_bits(log2.saturating_sub(2).min(6) as u8)
    }

    fn rl(self) -> u16 {
        self.reload.clamp(1, 4096) - 1
    }
}

// The table above, checked at compile time at the LSI extremes.
const _: () = {
    assert!(Timeout::BOOT.us_at(17_000) < 1_000_000);
    assert!(Timeout::TICK.us_at(47_000) > 30_000);
    assert!(Timeout::STALL.us_at(47_000) > 8_000_000);
    assert!(Timeout::FAULT.us_at(47_000) > 22_000_000);
};

/// Starts the watchdog with `t` (the first statement of `main`: no clock is needed, the
/// IWDG runs on the LSI, which starting it switches on).
pub fn start(t: Timeout) {
    pac::IWDG.kr().write(|w| w.set_key(Key::START));
    set(t);
}

/// Reloads the counter (feeds the watchdog).
#[inline(always)]
pub fn pet() {
    pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
}

/// Changes the timeout: reloads first (the present timeout to make the change in),
/// writes prescaler and reload, waits until the LSI domain has taken them (a few LSI
/// cycles, < 0.5 ms; bounded), reloads with the new values. Returns whether the update
/// completed within the bound (if not, the old timeout still applies at the next reload
/// until the hardware finishes).
pub fn set(t: Timeout) -> bool {
    let iwdg = pac::IWDG;
    pet();
    iwdg.kr().write(|w| w.set_key(Key::ENABLE));
    iwdg.pr().write(|w| w.set_pr(t.pr()));
    iwdg.rlr().write(|w| w.set_rl(t.rl()));
    // ≤ 5 LSI cycles at 17 kHz = 294 µs; 100 000 polls of ≥ 4 cycles at 168 MHz ≥ 2.4 ms.
    let mut done = false;
    for _ in 0..100_000u32 {
        let sr = iwdg.sr().read();
        if !sr.pvu() && !sr.rvu() {
            done = true;
            break;
        }
    }
    pet();
    done
}

/// The timeout now in force (read back from the registers).
#[cfg_attr(feature = "console", allow(dead_code))]
pub fn current() -> Timeout {
    let iwdg = pac::IWDG;
    let pr = iwdg.pr().read().pr().to_bits();
    let rl = iwdg.rlr().read().rl();
    Timeout {
        prescaler: 4u16 << pr.min(6),
        reload: rl.saturating_add(1),
    }
}
