//! Valve outputs: one [`ValveChannel`] per slave axis plus the valve-power enable.
//!
//! The runtime hands over calibrated signed codes (`DacCode`, 0 = DAC mid-scale; the
//! per-axis calibration — null, gain per direction, polarity, overlap, clamp — is
//! `hydra_core::valve`, applied by the control law). A channel turns a code into its
//! converter's format. The two on-chip DAC channels are [`OnChipDac`]; an external SPI
//! DAC adds axes by implementing [`ValveChannel`] (one blocking SPI frame per tick,
//! ~1.5 µs at 21 MHz for a 24-bit frame) and joining the [`ValveBank`].
//!
//! The null codes are also published in [`SAFE_CODES`] for the panic and hard-fault
//! handlers, which write the on-chip DAC registers directly (`crate::panic`).

use core::sync::atomic::{AtomicU16, Ordering};
use embassy_stm32::dac::{DacChannel, Value};
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Blocking;
use hydra_core::units::DacCode;

use crate::consts::DAC_RANGE;

/// A converter channel that drives one proportional valve.
pub trait ValveChannel {
    /// Outputs a signed code (0 = mid-scale, ±2047 full scale).
    fn write(&mut self, code: DacCode);
}

/// The unipolar register value of each on-chip DAC channel's safe (null) output, read by
/// the panic handler. Starts at mid-scale (2048).
pub static SAFE_CODES: [AtomicU16; 2] = [AtomicU16::new(2048), AtomicU16::new(2048)];

/// One channel of the F407's 12-bit DAC (right-aligned data register).
pub struct OnChipDac {
    ch: DacChannel<'static, Blocking>,
}

impl OnChipDac {
    /// Wraps a channel and writes mid-scale.
    pub fn new(mut ch: DacChannel<'static, Blocking>) -> Self {
        ch.set(Value::Bit12Right(DacCode::NULL.to_unipolar()));
        Self { ch }
    }
}

impl ValveChannel for OnChipDac {
    #[inline]
    fn write(&mut self, code: DacCode) {
        self.ch.set(Value::Bit12Right(code.to_unipolar()));
    }
}

/// A valve channel of any kind (static dispatch over the kinds this board has).
pub enum AnyValve {
    /// On-chip DAC.
    OnChip(OnChipDac),
}

impl From<OnChipDac> for AnyValve {
    fn from(d: OnChipDac) -> Self {
        AnyValve::OnChip(d)
    }
}

impl ValveChannel for AnyValve {
    #[inline]
    fn write(&mut self, code: DacCode) {
        match self {
            AnyValve::OnChip(d) => d.write(code),
        }
    }
}

/// `S` valve channels and the valve-power enable output.
pub struct ValveBank<const S: usize> {
    ch: [AnyValve; S],
    enable: Output<'static>,
}

impl<const S: usize> ValveBank<S> {
    /// A bank with the enable off.
    pub fn new(ch: [AnyValve; S], mut enable: Output<'static>) -> Self {
        enable.set_low();
        Self { ch, enable }
    }

    /// Publishes the calibrated null codes for the panic handler (on-chip channels).
    pub fn publish_safe_codes(codes: &[DacCode; S]) {
        for (slot, c) in SAFE_CODES.iter().zip(codes.iter()) {
            slot.store(DAC_RANGE.clamp(*c).to_unipolar(), Ordering::Relaxed);
        }
    }

    /// Writes every channel's code, clamped to the board's usable range
    /// ([`crate::consts::DAC_RANGE`]: beyond it the buffered output cannot follow).
    #[inline]
    pub fn write(&mut self, codes: &[DacCode; S]) {
        for (ch, &c) in self.ch.iter_mut().zip(codes.iter()) {
            ch.write(DAC_RANGE.clamp(c));
        }
    }

    /// Switches the valve power.
    #[inline]
    pub fn set_enable(&mut self, on: bool) {
        if on {
            self.enable.set_high();
        } else {
            self.enable.set_low();
        }
    }
}
