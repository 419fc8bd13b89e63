//! The valve DAC's usable output range: a property of the board (its analog supply) and
//! of the converter's output buffer, applied after the valve calibration.
//!
//! A 12-bit DAC with its output buffer on (the STM32F407's, DS8626 "DAC characteristics")
//! swings only from ≈ 0.2 V to VDDA − 0.2 V, and code 2048 — [`DacCode`] 0 — is
//! VDDA/2 (1.500 V on a 3.0 V board, not 1.65 V). Codes beyond the swing do not move the
//! output: a command there is silently saturated by the hardware, and the valve
//! amplifier's null must be set against VDDA/2. [`DacRange`] turns the board's VDDA and
//! swing margin into the usable signed code range and clamps to it, so what the law
//! commands is what the pin outputs.
//!
//! Units: millivolts (`u32`), codes in [`DacCode`] LSB (0 = mid-scale). One LSB =
//! VDDA/4095 (0.733 mV at 3.0 V).

use crate::units::DacCode;

/// Why a DAC range was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DacRangeError {
    /// VDDA outside 1 800 … 3 600 mV (the F407's analog supply range).
    Vdda,
    /// The swing margin leaves no range either side of mid-scale (margin ≥ VDDA/2).
    Margin,
}

/// The usable signed code range of a valve DAC: ±`max_code` around mid-scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DacRange {
    vdda_mv: u32,
    /// Largest |code| the output follows, LSB (≤ 2047).
    max_code: i16,
}

impl DacRange {
    /// The range of a board with analog supply `vdda_mv` whose output swings to within
    /// `margin_mv` of either rail: codes c with 2048 + c ∈ [⌈4095·m/V⌉, 4095 − ⌈4095·m/V⌉]
    /// and symmetric about mid-scale, so max_code = 2047 − ⌈4095·m/V⌉.
    pub const fn new(vdda_mv: u32, margin_mv: u32) -> Result<Self, DacRangeError> {
        if vdda_mv < 1800 || vdda_mv > 3600 {
            return Err(DacRangeError::Vdda);
        }
        if margin_mv.saturating_mul(2) >= vdda_mv {
            return Err(DacRangeError::Margin);
        }
        // ⌈4095·m/V⌉ ≤ 2047 here (m < V/2); both products < 2^32.
        let lost = 4095u32.saturating_mul(margin_mv).div_ceil(vdda_mv);
        let max = 2047u32.saturating_sub(lost);
        if max == 0 {
            return Err(DacRangeError::Margin);
        }
        Ok(Self {
            vdda_mv,
            max_code: max as i16,
        })
    }

    /// Largest usable |code|, LSB.
    pub const fn max_code(&self) -> i16 {
        self.max_code
    }

    /// Mid-scale (code 0) voltage, mV: VDDA/2.
    pub const fn mid_mv(&self) -> u32 {
        self.vdda_mv / 2
    }

    /// The output voltage of `code`, mV (rounded down): VDDA·(2048 + code)/4095.
    pub const fn code_mv(&self, code: DacCode) -> u32 {
        let u = code.to_unipolar() as u32;
        // vdda ≤ 3600, u ≤ 4095: the product fits u32.
        self.vdda_mv.saturating_mul(u) / 4095
    }

    /// `code` clamped to the usable range.
    #[inline(always)]
    pub fn clamp(&self, code: DacCode) -> DacCode {
        let c = code.get();
        // max_code ∈ [1, 2047]: its negation cannot overflow.
        let lo = self.max_code.saturating_neg();
        DacCode::new_clamped(i32::from(c.clamp(lo, self.max_code)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_at_3v0_with_a_200mv_margin() {
        let r = DacRange::new(3000, 200).unwrap();
        // ⌈4095·200/3000⌉ = 273 codes lost at each end.
        assert_eq!(r.max_code(), 2047 - 273);
        assert_eq!(r.mid_mv(), 1500);
        assert_eq!(r.code_mv(DacCode::NULL), 1500);
        // The ends of the range are inside the swing, the next code out is not.
        assert!(r.code_mv(DacCode::new_clamped(-i32::from(r.max_code()))) >= 200);
        assert!(r.code_mv(DacCode::new_clamped(i32::from(r.max_code()))) <= 2800);
        assert_eq!(
            r.clamp(DacCode::new_clamped(2047)),
            DacCode::new_clamped(1774)
        );
        assert_eq!(
            r.clamp(DacCode::new_clamped(-2047)),
            DacCode::new_clamped(-1774)
        );
        assert_eq!(r.clamp(DacCode::new_clamped(-7)), DacCode::new_clamped(-7));
    }

    #[test]
    fn impossible_ranges_are_refused() {
        assert_eq!(DacRange::new(1000, 0), Err(DacRangeError::Vdda));
        assert_eq!(DacRange::new(5000, 0), Err(DacRangeError::Vdda));
        assert_eq!(DacRange::new(3000, 1500), Err(DacRangeError::Margin));
        assert_eq!(DacRange::new(3300, 0).unwrap().max_code(), 2047);
    }

    #[test]
    fn clamping_never_widens() {
        let r = DacRange::new(3300, 200).unwrap();
        for c in -2047..=2047 {
            let out = r.clamp(DacCode::new_clamped(c)).get();
            assert!(out.abs() <= r.max_code() && out.abs() <= c.unsigned_abs() as i16);
        }
    }
}
