//! The master encoder's edge timer: every rising edge of channel A timestamped in
//! hardware, so the runtime can place the master below one count at the sample instant
//! (`hydra_core::master::EdgeEstimator`).
//!
//! Wiring inside the MCU, no extra pin (RM0090 §18.3.5 input capture, §18.3.15 timer
//! synchronisation, Table 86 internal trigger connections):
//!
//! | timer | set-up | at a rising A edge |
//! |---|---|---|
//! | TIM5 (the master's ×4 encoder) | CC1S = 01 (IC1 on TI1, as encoder mode needs), CC1P = 0 (rising; both edges are not allowed in encoder mode), CC1E = 1; CR2.MMS = 011 (compare pulse) | CCR1 ← the count, CC1IF; TRGO pulses |
//! | TIM8 (free-running, 16-bit) | PSC 167: 1 MHz from its 168 MHz APB2 kernel clock (1 µs, wraps every 65.5 ms); SMCR.TS = ITR3 (TIM5_TRGO), slave mode off; CC1S = 11 (IC1 on TRC), CC1E = 1 | CCR1 ← its time |
//!
//! One capture pair per encoder line (4 counts): at 3 °/s every 1.33 ms. The tick reads
//! the pair after the counters, and only when both timers have captured (TIM5's and
//! TIM8's CC1IF: TIM8's capture follows TIM5's by a few clocks, and a pair read in
//! between would join an old time to a new count; then both flags wait for the next
//! tick): TIM8's CCR1, then TIM5's CCR1 (which clears its CC1IF), then TIM8's CCR1
//! again — if it changed, an edge came between the reads and this tick's pair is
//! dropped (the estimator extrapolates from the last one). The 16-bit time is extended
//! by the encoders' `Extender16` (the tick reads it every period, far below its 32.8 ms
//! limit; a capture after the counter's reading extends into the future, and the
//! estimator falls back for that one tick). Whether TIM5 latches
//! the count after or before the edge is learnt by the estimator. The first reading
//! after boot may be a stale pair (TIM5 captures from `Qei::new` on): the estimator
//! takes no edge on its first sample.

use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::{CcmrInputCcs, Mms, Sms, Ts};
use embassy_stm32::pac::timer::{TimAdv, TimGp32};
use embassy_stm32::peripherals;
use embassy_stm32::Peri;
use hydra_core::master::{EdgeCapture, EdgeReading};
use hydra_core::runtime::encoder::Extender16;
use hydra_core::units::Counts;

/// TIM8's prescaler: 168 MHz / (167 + 1) = 1 MHz.
const PSC_1MHZ: u16 = 167;

/// The edge timer (TIM8) and the master encoder's capture (TIM5 channel 1).
pub struct EdgeTimer {
    _tim8: Peri<'static, peripherals::TIM8>,
    tim8: TimAdv,
    tim5: TimGp32,
    clock: Extender16,
}

impl EdgeTimer {
    /// Sets up TIM5's capture and trigger output (after its encoder mode) and TIM8.
    pub fn new(tim8: Peri<'static, peripherals::TIM8>) -> Self {
        let (t5, t8) = (pac::TIM5, pac::TIM8);
        // TIM5: capture the count at rising A edges, pulse TRGO at each capture.
        t5.ccer().modify(|w| {
            w.set_ccp(0, false);
            w.set_cce(0, true);
        });
        t5.cr2().modify(|w| w.set_mms(Mms::COMPARE_PULSE));
        // TIM8: clock on and reset (embassy's helper: the errata's delay after a clock
        // enable), free-running at 1 MHz, channel 1 captures on TRC = ITR3.
        embassy_stm32::rcc::enable_and_reset::<peripherals::TIM8>();
        t8.psc().write_value(PSC_1MHZ);
        t8.arr().write(|w| w.set_arr(u16::MAX));
        t8.smcr().modify(|w| {
            w.set_sms(Sms::DISABLED);
            w.set_ts(Ts::ITR3);
        });
        t8.ccmr_input(0).modify(|w| w.set_ccs(0, CcmrInputCcs::TRC));
        t8.ccer().modify(|w| w.set_cce(0, true));
        // Load the prescaler, then count.
        t8.egr().write(|w| w.set_ug(true));
        t8.cr1().modify(|w| w.set_cen(true));
        let clock = Extender16::new(t8.cnt().read().cnt(), 0);
        Self {
            _tim8: tim8,
            tim8: t8,
            tim5: t5,
            clock,
        }
    }

    /// The reading of this tick: the time now and the newest capture pair since the last
    /// call (read right after the encoder counters).
    #[inline(always)]
    pub fn read(&mut self) -> EdgeReading {
        // The extended count read as a wrapping u32 time.
        let now = self.clock.update(self.tim8.cnt().read().cnt()).0 as u32;
        let edge = if self.tim5.sr().read().ccif(0) && self.tim8.sr().read().ccif(0) {
            let t = self.tim8.ccr(0).read().ccr();
            let count = self.tim5.ccr(0).read();
            let again = self.tim8.ccr(0).read().ccr();
            (again == t).then(|| EdgeCapture {
                at_ticks: self.clock.extend_past(t).0 as u32,
                count: Counts(count as i32),
            })
        } else {
            None
        };
        EdgeReading {
            now_ticks: now,
            edge,
        }
    }
}
