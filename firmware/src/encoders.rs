//! Quadrature encoders on timers in encoder mode (×4 counting, QEI mode 3).
//!
//! TIM2 and TIM5 are 32-bit: their counter *is* the count. TIM3 is 16-bit: its reading
//! is extended to 32 bits with `hydra_core::runtime::encoder::Extender16` (wrapping
//! difference, exact while the axis moves less than 32 767 counts per tick). All three
//! counters are read back to back at the start of the tick (three bus reads, ~20 cycles
//! ≈ 0.12 µs apart) before any other work.

use embassy_stm32::pac::timer::TimGp32;
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
    /// full 32-bit auto-reload so the counter wraps at 2^32.
    pub fn new(qei: Qei<'static, T>, regs: TimGp32) -> Self {
        regs.arr().write_value(u32::MAX);
        Self { _qei: qei, regs }
    }

    /// The raw 32-bit counter.
    #[inline(always)]
    pub fn raw(&self) -> u32 {
        self.regs.cnt().read()
    }
}

/// An encoder on a 16-bit timer, extended in software.
pub struct Encoder16<T: GeneralInstance4Channel> {
    qei: Qei<'static, T>,
    ext: Extender16,
}

impl<T: GeneralInstance4Channel> Encoder16<T> {
    /// Takes a configured QEI; the count starts at 0 for the current reading.
    pub fn new(qei: Qei<'static, T>) -> Self {
        let ext = Extender16::new(qei.count(), 0);
        Self { qei, ext }
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
}

impl<M, A, B> Encoders<M, A, B>
where
    M: GeneralInstance4Channel,
    A: GeneralInstance4Channel,
    B: GeneralInstance4Channel,
{
    /// Groups the encoders.
    pub fn new(master: Encoder32<M>, slave0: Encoder32<A>, slave1: Encoder16<B>) -> Self {
        Self {
            master,
            slave0,
            slave1,
        }
    }

    /// Reads every counter back to back, then extends.
    #[inline(always)]
    pub fn latch(&mut self) -> EncoderSample<2> {
        let m = self.master.raw();
        let a = self.slave0.raw();
        let b = self.slave1.raw();
        EncoderSample {
            master: counts_from_u32(m),
            slaves: [counts_from_u32(a), self.slave1.extend(b)],
        }
    }
}
