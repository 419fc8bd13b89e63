//! Valve output calibration: controller command (DAC LSB) → signed DAC code.
//!
//! ```text
//! u ≥ 0:  code = null + polarity · (overlap_pos + gain_pos · u)     (|u| ≥ w)
//! u < 0:  code = null + polarity · (−overlap_neg + gain_neg · u)
//! |u| < w: the overlap jump is replaced by a straight line through 0 of slope
//!          (overlap + w·gain)/w, so the compensation never chatters around null.
//! code clamped to ±clamp_lsb (≤ 2047)
//! ```
//!
//! `overlap_*` compensates a positive-overlap spool's deadband (LSB of the opening that
//! gives no flow), `gain_*` corrects a per-direction flow gain mismatch, `null` the
//! offset at which the spool is really centred. A critically lapped valve (the reference
//! machine) has zero overlap, unit gains and zero null.

use crate::fixed_point::{clamp_sym, mul_shr_floor_sat};
use crate::units::{CmdLsb, DacCode};
use fixed::types::I8F24;

/// Calibration of one valve channel in engineering units (validated by [`ValveCal::build`]).
/// With the `serde` feature it is what a scenario's `[axis.calibration]` table holds
/// (every field optional, defaults as below; unknown keys refused).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields, default)
)]
pub struct ValveCal {
    /// Code at which the spool is centred, LSB (|null| ≤ 500).
    pub null_lsb: f32,
    /// Deadband compensation added for positive commands, LSB (0 ≤ x ≤ 1000).
    pub overlap_pos_lsb: f32,
    /// Deadband compensation subtracted for negative commands, LSB (0 ≤ x ≤ 1000).
    pub overlap_neg_lsb: f32,
    /// Width of the linear zone around zero that replaces the overlap jump, LSB (> 0).
    pub overlap_zone_lsb: f32,
    /// Gain for positive commands (0.1 … 10).
    pub gain_pos: f32,
    /// Gain for negative commands (0.1 … 10).
    pub gain_neg: f32,
    /// `true` if the valve is wired so a positive code retracts the axis.
    pub invert: bool,
    /// Largest |code| ever output, LSB (1 … 2047).
    pub clamp_lsb: u16,
}

impl Default for ValveCal {
    fn default() -> Self {
        Self {
            null_lsb: 0.0,
            overlap_pos_lsb: 0.0,
            overlap_neg_lsb: 0.0,
            overlap_zone_lsb: 8.0,
            gain_pos: 1.0,
            gain_neg: 1.0,
            invert: false,
            clamp_lsb: 2047,
        }
    }
}

/// A calibration value out of its range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ValveCalError {
    /// `null_lsb` outside ±500 or not finite.
    Null,
    /// An overlap outside 0 … 1000 LSB or not finite.
    Overlap,
    /// `overlap_zone_lsb` not in (0, 1000].
    OverlapZone,
    /// A gain outside 0.1 … 10 or not finite.
    Gain,
    /// `clamp_lsb` not in 1 … 2047.
    Clamp,
}

/// Validated valve calibration in fixed point (hot path: [`ValveCoeffs::output`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ValveCoeffs {
    null: i32,      // LSB, Q16.16 raw
    ov_pos: i32,    // LSB, Q16.16 raw
    ov_neg: i32,    // LSB, Q16.16 raw
    zone: i32,      // LSB, Q16.16 raw (> 0)
    slope_pos: i32, // I8F24 raw: (overlap + zone·gain)/zone
    slope_neg: i32, // I8F24 raw
    gain_pos: i32,  // I8F24 raw
    gain_neg: i32,  // I8F24 raw
    invert: bool,
    clamp: i32, // LSB, Q16.16 raw
    /// No overlap and unit gains: the compensation is the identity (a fast path).
    linear: bool,
    /// `linear`, no inversion and a zero null: the code is the rounded command.
    identity: bool,
}

impl ValveCoeffs {
    /// Every byte zero: the placeholder of an unconfigured law buffer (a `const`, so a
    /// static buffer needs no construction at run time, and all-zero, so it is `.bss`). Never used for output: a
    /// law is configured ([`crate::follower::Follower::configure`]) before it runs.
    pub(crate) const UNSET: Self = Self {
        null: 0,
        ov_pos: 0,
        ov_neg: 0,
        zone: 0,
        slope_pos: 0,
        slope_neg: 0,
        gain_pos: 0,
        gain_neg: 0,
        invert: false,
        clamp: 0,
        linear: false,
        identity: false,
    };
}

fn in_range(x: f32, lo: f32, hi: f32) -> bool {
    x.is_finite() && x >= lo && x <= hi
}

fn q16(x: f32) -> i32 {
    CmdLsb::saturating_from_num(x).to_bits()
}

fn q24(x: f32) -> i32 {
    I8F24::saturating_from_num(x).to_bits()
}

impl ValveCal {
    /// Validates the calibration and converts it to fixed point.
    pub fn build(&self) -> Result<ValveCoeffs, ValveCalError> {
        if !in_range(self.null_lsb, -500.0, 500.0) {
            return Err(ValveCalError::Null);
        }
        if !in_range(self.overlap_pos_lsb, 0.0, 1000.0)
            || !in_range(self.overlap_neg_lsb, 0.0, 1000.0)
        {
            return Err(ValveCalError::Overlap);
        }
        if !in_range(self.overlap_zone_lsb, 1e-3, 1000.0) {
            return Err(ValveCalError::OverlapZone);
        }
        if !in_range(self.gain_pos, 0.1, 10.0) || !in_range(self.gain_neg, 0.1, 10.0) {
            return Err(ValveCalError::Gain);
        }
        if self.clamp_lsb == 0 || self.clamp_lsb > DacCode::MAX as u16 {
            return Err(ValveCalError::Clamp);
        }
        let z = self.overlap_zone_lsb;
        Ok(ValveCoeffs {
            null: q16(self.null_lsb),
            ov_pos: q16(self.overlap_pos_lsb),
            ov_neg: q16(self.overlap_neg_lsb),
            zone: q16(z),
            slope_pos: q24((self.overlap_pos_lsb + z * self.gain_pos) / z),
            slope_neg: q24((self.overlap_neg_lsb + z * self.gain_neg) / z),
            gain_pos: q24(self.gain_pos),
            gain_neg: q24(self.gain_neg),
            invert: self.invert,
            clamp: i32::from(self.clamp_lsb).wrapping_shl(16),
            linear: self.overlap_pos_lsb == 0.0
                && self.overlap_neg_lsb == 0.0
                && self.gain_pos == 1.0
                && self.gain_neg == 1.0,
            identity: self.overlap_pos_lsb == 0.0
                && self.overlap_neg_lsb == 0.0
                && self.gain_pos == 1.0
                && self.gain_neg == 1.0
                && !self.invert
                && q16(self.null_lsb) == 0,
        })
    }
}

impl ValveCoeffs {
    /// The compensated command before rounding, in LSB (`I16F16`), clamped to ±clamp.
    #[inline]
    pub fn compensate(&self, u: CmdLsb) -> CmdLsb {
        let u = u.to_bits();
        let y = if self.linear {
            u
        } else if u >= self.zone {
            self.ov_pos
                .saturating_add(mul_shr_floor_sat(u, self.gain_pos, 24))
        } else if u <= self.zone.wrapping_neg() {
            mul_shr_floor_sat(u, self.gain_neg, 24).saturating_sub(self.ov_neg)
        } else if u >= 0 {
            mul_shr_floor_sat(u, self.slope_pos, 24)
        } else {
            mul_shr_floor_sat(u, self.slope_neg, 24)
        };
        let y = if self.invert { y.saturating_neg() } else { y };
        CmdLsb::from_bits(clamp_sym(y.saturating_add(self.null), self.clamp))
    }

    /// The DAC code for a controller command `u` (rounded to the nearest LSB).
    #[inline(always)]
    pub fn output(&self, u: CmdLsb) -> DacCode {
        if self.identity {
            // Fast path (no overlap, unit gains, no inversion, zero null): the code is
            // round(clamp(u)). |y| ≤ clamp ≤ 2047·2^16, so y + 2^15 cannot overflow and
            // the rounded code of a value within ±clamp (whole LSB) stays within ±clamp.
            let y = clamp_sym(u.to_bits(), self.clamp);
            DacCode::from_in_range(y.wrapping_add(1 << 15) >> 16)
        } else {
            self.output_calibrated(u)
        }
    }

    /// [`ValveCoeffs::output`] for a command the caller has already limited to
    /// ±[`ValveCoeffs::clamp_lsb`] (the axis laws do): the identity fast path skips its
    /// clamp. Crate-private: the range is the caller's proof.
    #[inline(always)]
    pub(crate) fn output_within_clamp(&self, u: CmdLsb) -> DacCode {
        if self.identity {
            // |u| ≤ clamp ≤ 2047·2^16 (the caller's proof): as in `output`.
            DacCode::from_in_range(u.to_bits().wrapping_add(1 << 15) >> 16)
        } else {
            self.output_calibrated(u)
        }
    }

    /// [`ValveCoeffs::output`] through the full calibration (out of line: the identity
    /// fast path is the one inlined into the loop).
    #[inline(never)]
    fn output_calibrated(&self, u: CmdLsb) -> DacCode {
        let y = self.compensate(u).to_bits();
        // Round to nearest: (y + 0.5) >> 16; y is within ±2047·2^16, no overflow.
        DacCode::new_clamped(y.saturating_add(1 << 15) >> 16)
    }

    /// The largest |command| the output stage passes, LSB (for anti-windup).
    #[inline]
    pub fn clamp_lsb(&self) -> CmdLsb {
        CmdLsb::from_bits(self.clamp)
    }

    /// The DAC code that puts the spool at its null: the safe output.
    #[inline]
    pub fn null_code(&self) -> DacCode {
        DacCode::new_clamped(self.null.saturating_add(1 << 15) >> 16)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn lsb(x: f64) -> CmdLsb {
        CmdLsb::from_num(x)
    }

    #[test]
    fn default_is_identity_with_clamp() {
        let c = ValveCal::default().build().unwrap();
        assert_eq!(c.output(lsb(100.4)).get(), 100);
        assert_eq!(c.output(lsb(-100.6)).get(), -101);
        assert_eq!(c.output(lsb(5000.0)).get(), 2047);
        assert_eq!(c.output(lsb(-5000.0)).get(), -2047);
        assert_eq!(c.null_code().get(), 0);
    }

    #[test]
    fn overlap_null_polarity() {
        let cal = ValveCal {
            null_lsb: 10.0,
            overlap_pos_lsb: 50.0,
            overlap_neg_lsb: 40.0,
            overlap_zone_lsb: 10.0,
            gain_pos: 1.0,
            gain_neg: 2.0,
            invert: true,
            clamp_lsb: 1000,
        };
        let c = cal.build().unwrap();
        // +100 → −(50 + 100) + 10 = −140
        assert_eq!(c.output(lsb(100.0)).get(), -140);
        // −100 → −(−40 − 200) + 10 = 250
        assert_eq!(c.output(lsb(-100.0)).get(), 250);
        // 0 → null
        assert_eq!(c.output(lsb(0.0)).get(), 10);
        // inside the zone: linear, +5 → −(5·(50+10)/10) + 10 = −20
        assert_eq!(c.output(lsb(5.0)).get(), -20);
        assert_eq!(c.null_code().get(), 10);
    }

    #[test]
    fn rejects_bad_values() {
        let bad = |f: fn(&mut ValveCal)| {
            let mut c = ValveCal::default();
            f(&mut c);
            c.build()
        };
        assert_eq!(bad(|c| c.null_lsb = 600.0), Err(ValveCalError::Null));
        assert_eq!(
            bad(|c| c.overlap_pos_lsb = -1.0),
            Err(ValveCalError::Overlap)
        );
        assert_eq!(
            bad(|c| c.overlap_zone_lsb = 0.0),
            Err(ValveCalError::OverlapZone)
        );
        assert_eq!(bad(|c| c.gain_neg = f32::NAN), Err(ValveCalError::Gain));
        assert_eq!(bad(|c| c.clamp_lsb = 3000), Err(ValveCalError::Clamp));
    }

    proptest! {
        /// The identity fast path gives the general path's code for every command.
        #[test]
        fn identity_fast_path_matches_general_path(u in any::<i32>(), clamp in 1u16..=2047) {
            let c = ValveCal { clamp_lsb: clamp, ..ValveCal::default() }.build().unwrap();
            prop_assert!(c.identity);
            let general = ValveCoeffs { identity: false, ..c };
            let u = CmdLsb::from_bits(u);
            prop_assert_eq!(c.output(u), general.output(u));
        }

        #[test]
        fn output_always_within_clamp(u in any::<i32>(), clamp in 1u16..=2047, ov in 0.0f32..1000.0,
                                      null in -500.0f32..500.0, inv: bool) {
            let cal = ValveCal { null_lsb: null, overlap_pos_lsb: ov, overlap_neg_lsb: ov,
                                 invert: inv, clamp_lsb: clamp, ..ValveCal::default() };
            let c = cal.build().unwrap();
            let code = c.output(CmdLsb::from_bits(u)).get();
            prop_assert!(i32::from(code).abs() <= i32::from(clamp));
        }

        #[test]
        fn monotonic_without_inversion(a in -3000.0f64..3000.0, b in -3000.0f64..3000.0, ov in 0.0f32..200.0) {
            let cal = ValveCal { overlap_pos_lsb: ov, overlap_neg_lsb: ov, ..ValveCal::default() };
            let c = cal.build().unwrap();
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(c.compensate(lsb(lo)) <= c.compensate(lsb(hi)));
        }
    }
}
