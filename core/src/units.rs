//! Units and fixed-point formats of every quantity in the control loop.
//!
//! `IaFb` is a two's-complement fixed-point number with `a` integer and `b` fractional
//! bits (the `fixed` crate's types): resolution 2^-b, range [−2^(a−1), 2^(a−1) − 2^-b].
//! Quantities that share a format are distinct types (`repr(transparent)` newtypes, free
//! at run time), so one is never passed where another is expected: position, velocity
//! and force (`I24F8`: [`PosUm`], [`VelUmPerS`], [`ForceN`]), master position and speed
//! (`I48F16`: [`Master`], [`MasterRate`]), valve command and pressure (`I16F16`:
//! [`CmdLsb`], [`PressureBar`]).
//! Names carry units (`_um`, `_mdeg`, `_per_s`, `_lsb`, `_n`, `_bar`).
//!
//! | quantity | type | unit | resolution | range | why it cannot overflow |
//! |---|---|---|---|---|---|
//! | slave position, target, error | [`PosUm`] (newtype over `I24F8`) | µm | 3.9 nm | ±8.39 m | strokes ≤ 8 m validated in the table and axis scale; differences saturate |
//! | slave velocity (feed-forward) | [`VelUmPerS`] (newtype over `I24F8`) | µm/s | 3.9 nm/s | ±8.39 m/s | product saturates to the range |
//! | slave acceleration | [`AccUmPerS2`] = `I32F0` | µm/s² | 1 µm/s² | ±2147 m/s² | product saturates |
//! | master position (count of the master encoder, or a time master's tick) | [`Master`] (newtype over `I48F16`) | master count (mdeg for the rotary table) | 1/65536 count | ±1.4e14 counts | prediction in difference form; the filter, predictor and in-segment test work modulo 2^64 raw (`wrapping_*`: a wrapping counter is followed through the wrap) |
//! | master edge time, sample time | `u32` | edge-timer tick (1 µs on the board) | 1 tick | wrapping 2^32 (differences only; a 16-bit timer extended by [`crate::runtime::encoder::Extender16`]) | only differences below 2^15 ticks (interval) and 2^16 (age) are used ([`crate::master::EdgeEstimator`]) |
//! | sub-count fraction (age / edge interval) | `u32` Q16 | 1 | 1.5e-5 | [0, 2) | age ≤ 2·interval < 2^16 ticks: `age << 16` < 2^32 |
//! | master speed | [`MasterRate`] (newtype over `I48F16`) | counts/s | 1.5e-5 counts/s | ±1.4e14 | derived from the filter state by one shift |
//! | master-filter velocity per tick | `I32F32` (`i64`) | counts/tick | 2.3e-10 | ±2^31 | residual clamped to ±2^14 counts before the gain product; saturating adds |
//! | master-filter acceleration per tick | `I0F32` (`i32`) | counts/tick² | 2.3e-10 | ±0.5 (±5·10⁵ counts/s² at 1 kHz) | saturating add |
//! | master-filter gains g, 2k / h | `i32` Q1.31 / Q2.30 | 1 | 4.7e-10 / 9.3e-10 | (0, 1) / (0, 1.5) | validated; products with the `i32` residual < 2^61 |
//! | segment fraction | `u32` Q0.32 | 1 | 2.3e-10 | [0, 1) | product < 2^64 by construction (see [`crate::table`]) |
//! | segment rate (master speed / segment length) | `i32` Q16.16 | segments/s | 1.5e-5 | ±32768 | saturated |
//! | valve command before the DAC | [`CmdLsb`] (newtype over `I16F16`) | DAC LSB | 1.5e-5 LSB | ±32768 LSB | every term saturates; clamped to ±2047 before output |
//! | valve DAC code | [`DacCode`] | LSB of the 12-bit DAC, 0 = null | 1 LSB | [−2047, 2047] | clamped |
//! | encoder count | [`Counts`] | count | 1 | ±2^31 | 16-bit timers extended with wrapping differences |
//! | chamber pressure | [`PressureBar`] (newtype over `I16F16`) | bar | 1.5e-5 bar | ±32768 bar | ADC 0–250 bar |
//! | cylinder force | [`ForceN`] (newtype over `I24F8`) | N | 3.9 mN | ±8.39 MN | p · A ≤ 250 bar · 0.05 m² = 1.25 MN |
//! | proportional gain `kp` | `I16F16` | LSB/µm | 1.5e-5 | ±32768 | validated |
//! | integral gain per tick `ki·T` | `I8F24` | LSB/(µm·tick) | 6e-8 | ±128 | validated |
//! | derivative gain per tick `kd/T` | `I16F16` | LSB/(µm/tick) | 1.5e-5 | ±32768 | validated |
//! | velocity feed-forward `kv` | `I8F24` | LSB/(µm/s) | 6e-8 | ±128 | validated |
//! | acceleration feed-forward `ka` | `I0F32` | LSB/(µm/s²) | 2.3e-10 | ±0.5 | validated |
//! | force gains `kp_f`, `ki_f·T` | `I8F24` | LSB/N, LSB/(N·tick) | 6e-8 | ±128 | validated |
//!
//! Every product of two 32-bit raw values is formed in an `i64` (exact: |a·b| ≤ 2^62),
//! shifted back to the result's format and saturated to 32 bits ([`crate::fixed_point`]).
//! Rounding: the worst-case rounding of one tick is below 0.01 µm and 0.001 LSB, two
//! orders of magnitude under the encoder's 1 µm resolution, so it does not enter the
//! error budget of SPEC §A eq. 17.

use fixed::types::{I16F16, I24F8, I32F0, I48F16};

/// Slave acceleration in µm/s² (`I32F0`).
pub type AccUmPerS2 = I32F0;

/// A quantity with its own type over a fixed-point format: it converts like the format
/// (`from_num`, `from_bits`, `to_num`, …) but is never mixed with another quantity of the
/// same format by accident (a velocity where a position is expected does not compile).
/// [`Self::get`] / the public field give the format for arithmetic inside a kernel.
macro_rules! quantity {
    ($(#[$m:meta])* $name:ident($inner:ty, $bits:ty, $unsigned:ty)) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(transparent)]
        pub struct $name(pub $inner);

        impl $name {
            /// Zero.
            pub const ZERO: Self = Self(<$inner>::ZERO);
            /// The largest value.
            pub const MAX: Self = Self(<$inner>::MAX);
            /// The smallest value.
            pub const MIN: Self = Self(<$inner>::MIN);
            /// The resolution: the smallest positive value.
            pub const DELTA: Self = Self(<$inner>::DELTA);

            /// From the raw bits of the format.
            #[inline(always)]
            pub const fn from_bits(b: $bits) -> Self {
                Self(<$inner>::from_bits(b))
            }
            /// The raw bits of the format.
            #[inline(always)]
            pub const fn to_bits(self) -> $bits {
                self.0.to_bits()
            }
            /// The value in the format.
            #[inline(always)]
            pub const fn get(self) -> $inner {
                self.0
            }
            /// From a number (the format's `from_num`: the value must be in range).
            #[inline]
            pub fn from_num<T: fixed::traits::ToFixed>(v: T) -> Self {
                Self(<$inner>::from_num(v))
            }
            /// From a number, saturated to the range (the number must not be NaN).
            #[inline]
            pub fn saturating_from_num<T: fixed::traits::ToFixed>(v: T) -> Self {
                Self(<$inner>::saturating_from_num(v))
            }
            /// From a number, `None` if out of range.
            #[inline]
            pub fn checked_from_num<T: fixed::traits::ToFixed>(v: T) -> Option<Self> {
                <$inner>::checked_from_num(v).map(Self)
            }
            /// To a number.
            #[inline]
            pub fn to_num<T: fixed::traits::FromFixed>(self) -> T {
                self.0.to_num()
            }
            /// |self| in the unsigned format (exact: no saturation needed).
            #[inline(always)]
            pub fn unsigned_abs(self) -> $unsigned {
                self.0.unsigned_abs()
            }
            /// −self, saturated.
            #[inline(always)]
            pub fn saturating_neg(self) -> Self {
                Self(self.0.saturating_neg())
            }
            /// `self + o`, wrapping.
            #[inline(always)]
            pub fn wrapping_add(self, o: Self) -> Self {
                Self(self.0.wrapping_add(o.0))
            }
            /// `self − o`, wrapping.
            #[inline(always)]
            pub fn wrapping_sub(self, o: Self) -> Self {
                Self(self.0.wrapping_sub(o.0))
            }
            /// |self|, saturated.
            #[inline(always)]
            pub fn saturating_abs(self) -> Self {
                Self(self.0.saturating_abs())
            }
            /// `self + o`, saturated.
            #[inline(always)]
            pub fn saturating_add(self, o: Self) -> Self {
                Self(self.0.saturating_add(o.0))
            }
            /// `self − o`, saturated.
            #[inline(always)]
            pub fn saturating_sub(self, o: Self) -> Self {
                Self(self.0.saturating_sub(o.0))
            }
        }

        /// Saturating, as [`Self::saturating_add`].
        impl core::ops::Add for $name {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                self.saturating_add(o)
            }
        }

        /// Saturating, as [`Self::saturating_sub`].
        impl core::ops::Sub for $name {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                self.saturating_sub(o)
            }
        }

        /// Saturating, as [`Self::saturating_neg`].
        impl core::ops::Neg for $name {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                self.saturating_neg()
            }
        }

        impl core::fmt::Display for $name {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                core::fmt::Display::fmt(&self.0, f)
            }
        }
    };
}

quantity!(
    /// Master position in master counts (`I48F16`: 1/65536 count, ±1.4e14 counts). For
    /// the rotary table one count is 0.001° (so the value is in mdeg); for a time master
    /// one count is one period tick.
    Master(I48F16, i64, fixed::types::U48F16)
);

quantity!(
    /// Master speed in master counts per second (`I48F16`): its own type, not a
    /// [`Master`] position — this does not compile:
    ///
    /// ```compile_fail
    /// use hydra_core::units::{Master, MasterRate};
    /// let m: Master = MasterRate::from_num(60_000);
    /// ```
    MasterRate(I48F16, i64, fixed::types::U48F16)
);

quantity!(
    /// Valve command in DAC LSB before output conversion (`I16F16`).
    CmdLsb(I16F16, i32, fixed::types::U16F16)
);

quantity!(
    /// Chamber pressure in bar (`I16F16`): its own type, not a [`CmdLsb`] — this does
    /// not compile:
    ///
    /// ```compile_fail
    /// use hydra_core::units::{CmdLsb, PressureBar};
    /// fn command(u: CmdLsb) {}
    /// command(PressureBar::from_num(210));
    /// ```
    PressureBar(I16F16, i32, fixed::types::U16F16)
);

quantity!(
    /// Slave position, target or error in µm (`I24F8`: 3.9 nm resolution, ±8.39 m).
    PosUm(I24F8, i32, fixed::types::U24F8)
);

quantity!(
    /// Slave velocity in µm/s (`I24F8`: 3.9 nm/s resolution, ±8.39 m/s): its own type,
    /// not a [`PosUm`] — this does not compile:
    ///
    /// ```compile_fail
    /// use hydra_core::units::{PosUm, VelUmPerS};
    /// let v = VelUmPerS::from_num(5);
    /// let p: PosUm = v;
    /// ```
    VelUmPerS(I24F8, i32, fixed::types::U24F8)
);

quantity!(
    /// Force in N (`I24F8`: 3.9 mN resolution, ±8.39 MN): its own type, not a [`PosUm`]
    /// nor a [`VelUmPerS`] — this does not compile:
    ///
    /// ```compile_fail
    /// use hydra_core::units::{ForceN, VelUmPerS};
    /// fn speed(v: VelUmPerS) {}
    /// speed(ForceN::from_num(20_000));
    /// ```
    ForceN(I24F8, i32, fixed::types::U24F8)
);

/// A count of a quadrature encoder, extended to 32 bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counts(pub i32);

/// A signed valve DAC code: 0 is the valve's null, ±2047 full opening. The 12-bit DAC
/// writes `2048 + code` ([`DacCode::to_unipolar`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DacCode(i16);

impl DacCode {
    /// Largest magnitude of a code (12-bit DAC, bipolar).
    pub const MAX: i16 = 2047;
    /// The valve's null (spool centred).
    pub const NULL: DacCode = DacCode(0);

    /// A code, clamped to ±[`DacCode::MAX`].
    pub const fn new_clamped(code: i32) -> Self {
        const LIM: i32 = DacCode::MAX as i32;
        let c = if code > LIM {
            LIM
        } else if code < -LIM {
            -LIM
        } else {
            code
        };
        // In range of i16 after the clamp.
        DacCode(c as i16)
    }

    /// A code the caller has already limited to ±[`DacCode::MAX`] (the valve output
    /// stage's fast path, which clamps to its own `clamp_lsb` ≤ 2047 first): no second
    /// clamp. Crate-private, since the range is the caller's proof.
    #[inline(always)]
    pub(crate) const fn from_in_range(code: i32) -> Self {
        debug_assert!(code.unsigned_abs() <= DacCode::MAX as u32);
        DacCode(code as i16)
    }

    /// The signed code.
    pub const fn get(self) -> i16 {
        self.0
    }

    /// The normalised command u = code / 2047 ∈ [−1, 1] (host side, for the plant).
    #[cfg(feature = "std")]
    pub fn to_unit(self) -> f64 {
        f64::from(self.0) / f64::from(Self::MAX)
    }

    /// The unipolar 12-bit value written to the DAC register, 2048 + code ∈ [1, 4095].
    pub const fn to_unipolar(self) -> u16 {
        // code ∈ [−2047, 2047] ⇒ result ∈ [1, 4095].
        (self.0 as i32).wrapping_add(2048) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantities_convert_like_their_format() {
        let v = VelUmPerS::from_num(1.5);
        assert_eq!(v.to_bits(), 384);
        assert_eq!(v.get(), I24F8::from_num(1.5));
        assert_eq!(VelUmPerS::from_bits(384), v);
        assert_eq!(v.to_num::<f64>(), 1.5);
        assert_eq!(VelUmPerS::saturating_from_num(1e12), VelUmPerS::MAX);
        assert_eq!(VelUmPerS::checked_from_num(1e12), None);
        assert_eq!(ForceN::from_num(-3).saturating_abs(), ForceN::from_num(3));
        assert_eq!(ForceN::MAX.saturating_add(ForceN::from_num(1)), ForceN::MAX);
        assert!(VelUmPerS::ZERO < v);
        assert_eq!(std::format!("{v}"), "1.5");
    }

    #[test]
    fn dac_code_clamps_and_maps() {
        assert_eq!(DacCode::new_clamped(5000).get(), 2047);
        assert_eq!(DacCode::new_clamped(-5000).get(), -2047);
        assert_eq!(DacCode::new_clamped(12).get(), 12);
        assert_eq!(DacCode::NULL.to_unipolar(), 2048);
        assert_eq!(DacCode::new_clamped(2047).to_unipolar(), 4095);
        assert_eq!(DacCode::new_clamped(-2047).to_unipolar(), 1);
    }
}
