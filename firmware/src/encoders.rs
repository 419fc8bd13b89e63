//! Quadrature encoders on timers in encoder mode (×4 counting, QEI mode 3), and the
//! slaves' reference inputs (encoder index or reference switch) captured in hardware.
//!
//! TIM2 and TIM5 are 32-bit: their counter *is* the count. TIM3 is 16-bit: its reading
//! is extended to 32 bits with `hydra_core::runtime::encoder::Extender16` (wrapping
//! difference, exact while the axis moves less than 32 767 counts per tick). All three
//! counters are read back to back at the start of the tick (three bus reads, ~20 cycles
//! ≈ 0.12 µs apart) before any other work.
//!
//! **The master's edges** are timestamped by TIM8 (`crate::edge_timer`), read right after
//! the three counters.
//!
//! **Reference inputs.** Each slave's index (Z) or reference switch drives its encoder
//! timer's channel 3 in input-capture mode (slave 0: PA2 = TIM2_CH3, AF1; slave 1: PC8 =
//! TIM3_CH3, AF2; rising edge, 8-sample filter at 84 MHz = 95 ns): the timer copies the
//! count into CCR3 *at the edge*, whatever the tick is doing, so homing is exact to the
//! count at any speed. The tick reads the capture flag after latching the counters
//! (`EncoderInput::reference_edges`); TIM3's 16-bit capture is extended from the same
//! tick's reading (`Extender16::extend_past`).

use crate::edge_timer::EdgeTimer;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::{TimGp16, TimGp32};
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::timer::GeneralInstance4Channel;
use hydra_core::runtime::encoder::{counts_from_u32, Extender16};
use hydra_core::runtime::EncoderSample;
use hydra_core::units::Counts;

/// An encoder on a 32-bit timer.
pub struct Encoder32<T: GeneralInstance4Channel> {
    _qei: Qei<'static, T>,
    regs: TimGp32,
}

impl<T: GeneralInstance4Channel> Encoder32<T> {
    /// Takes a configured QEI and the same timer's 32-bit register block; sets the
    /// full 32-bit auto-reload so the counter wraps at 2^32, and channel 3 to capture
    /// the count at the reference edge.
    pub fn new(qei: Qei<'static, T>, regs: TimGp32) -> Self {
        regs.arr().write_value(u32::MAX);
        capture_ch3!(regs);
        Self { _qei: qei, regs }
    }

    /// The count latched at the last reference edge, if one came since the last call
    /// (reading CCR3 clears the flag).
    #[inline(always)]
    pub fn reference_edge(&self) -> Option<u32> {
        self.regs
            .sr()
            .read()
            .ccif(2)
            .then(|| self.regs.ccr(2).read())
    }

    /// The raw 32-bit counter.
    #[inline(always)]
    pub fn raw(&self) -> u32 {
        self.regs.cnt().read()
    }
}

/// Channel 3 of a general-purpose timer as the reference-edge capture: CC3 input on
/// TI3 (CCMR2.CC3S = 01), filter f_CK_INT/1 × 8, rising edge, capture enabled.
macro_rules! capture_ch3 {
    ($regs:expr) => {{
        let regs = $regs;
        regs.ccmr_input(1).modify(|w| {
            w.set_ccs(0, embassy_stm32::pac::timer::vals::CcmrInputCcs::TI4);
            w.set_icf(0, embassy_stm32::pac::timer::vals::FilterValue::FCK_INT_N8);
        });
        regs.ccer().modify(|w| {
            w.set_ccp(2, false);
            w.set_cce(2, true);
        });
    }};
}
use capture_ch3;

/// Routes a pin to its timer's channel 3 (alternate function `af`, pulled down so an
/// unconnected input never fires).
fn reference_pin(port: pac::gpio::Gpio, pin: usize, af: u8) {
    port.pupdr()
        .modify(|w| w.set_pupdr(pin, pac::gpio::vals::Pupdr::PULL_DOWN));
    port.afr(pin / 8).modify(|w| w.set_afr(pin % 8, af));
    port.moder()
        .modify(|w| w.set_moder(pin, pac::gpio::vals::Moder::ALTERNATE));
}

/// The reference inputs' pins: PA2 (TIM2_CH3, AF1) for slave 0, PC8 (TIM3_CH3, AF2)
/// for slave 1. Call after the encoders (their GPIO clocks are on).
pub fn reference_pins() {
    pac::RCC.ahb1enr().modify(|w| {
        w.set_gpioaen(true);
        w.set_gpiocen(true);
    });
    reference_pin(pac::GPIOA, 2, 1);
    reference_pin(pac::GPIOC, 8, 2);
}

/// An encoder on a 16-bit timer, extended in software.
pub struct Encoder16<T: GeneralInstance4Channel> {
    qei: Qei<'static, T>,
    regs: TimGp16,
    ext: Extender16,
}

impl<T: GeneralInstance4Channel> Encoder16<T> {
    /// Takes a configured QEI and the same timer's register block; the count starts at
    /// 0 for the current reading; channel 3 captures the reference edge.
    pub fn new(qei: Qei<'static, T>, regs: TimGp16) -> Self {
        let ext = Extender16::new(qei.count(), 0);
        capture_ch3!(regs);
        Self { qei, regs, ext }
    }

    /// The 16-bit count latched at the last reference edge, if one came since the last
    /// call.
    #[inline(always)]
    pub fn reference_edge(&self) -> Option<u16> {
        self.regs
            .sr()
            .read()
            .ccif(2)
            .then(|| self.regs.ccr(2).read().ccr())
    }

    /// The raw 16-bit counter.
    #[inline(always)]
    pub fn raw(&self) -> u16 {
        self.qei.count()
    }

    /// Extends a raw reading (call once per tick).
    #[inline(always)]
    pub fn extend(&mut self, raw: u16) -> Counts {
        self.ext.update(raw)
    }
}

/// The board's three encoders: the master and two slaves.
pub struct Encoders<M, A, B>
where
    M: GeneralInstance4Channel,
    A: GeneralInstance4Channel,
    B: GeneralInstance4Channel,
{
    master: Encoder32<M>,
    slave0: Encoder32<A>,
    slave1: Encoder16<B>,
    edges: EdgeTimer,
}

impl<M, A, B> Encoders<M, A, B>
where
    M: GeneralInstance4Channel,
    A: GeneralInstance4Channel,
    B: GeneralInstance4Channel,
{
    /// Groups the encoders and the master's edge timer.
    pub fn new(
        master: Encoder32<M>,
        slave0: Encoder32<A>,
        slave1: Encoder16<B>,
        edges: EdgeTimer,
    ) -> Self {
        Self {
            master,
            slave0,
            slave1,
            edges,
        }
    }

    /// The counts at the slaves' reference edges since the last call (after
    /// [`Encoders::latch`], whose TIM3 reading extends the 16-bit capture).
    #[inline(always)]
    pub fn reference_edges(&mut self) -> [Option<Counts>; 2] {
        [
            self.slave0.reference_edge().map(counts_from_u32),
            self.slave1
                .reference_edge()
                .map(|c| self.slave1.ext.extend_past(c)),
        ]
    }

    /// Reads every counter back to back, then the master's edge timer, then extends.
    #[inline(always)]
    pub fn latch(&mut self) -> EncoderSample<2> {
        let m = self.master.raw();
        let a = self.slave0.raw();
        let b = self.slave1.raw();
        let edges = self.edges.read();
        EncoderSample {
            master: counts_from_u32(m),
            slaves: [counts_from_u32(a), self.slave1.extend(b)],
            master_edges: Some(edges),
        }
    }
}
