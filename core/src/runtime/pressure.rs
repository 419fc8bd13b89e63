//! Pressure transducer scaling: ADC code → bar.
//!
//! ```text
//! p = p_lo + (code − code_lo) · (p_hi − p_lo) / (code_hi − code_lo)      [bar]
//! ```
//!
//! computed per tick as one product: `p = p_lo + (code − code_lo) · g`, with the gain
//! `g` in bar per LSB as `I8F24` raw (resolution 6e-8 bar/LSB, |g| ≤ 100) and the result in
//! [`PressureBar`] (`I16F16`). The reference transducers read 0–250 bar over the
//! 12-bit ADC's full scale (0 … 4095).

use crate::fixed_point::mul_shr_floor_sat;
use crate::units::PressureBar;
use fixed::types::I8F24;

/// Two-point calibration of one transducer channel.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressureCal {
    /// ADC code of the low calibration point (0 … 4095).
    pub code_lo: u16,
    /// Pressure at `code_lo`, bar (|x| ≤ 10 000).
    pub bar_lo: f32,
    /// ADC code of the high calibration point (> `code_lo`, ≤ 4095).
    pub code_hi: u16,
    /// Pressure at `code_hi`, bar (|x| ≤ 10 000).
    pub bar_hi: f32,
}

impl Default for PressureCal {
    fn default() -> Self {
        Self {
            code_lo: 0,
            bar_lo: 0.0,
            code_hi: 4095,
            bar_hi: 250.0,
        }
    }
}

/// A calibration that cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PressureCalError {
    /// Codes not 0 ≤ lo < hi ≤ 4095.
    Codes,
    /// A pressure not finite or beyond ±10 000 bar.
    Pressure,
    /// More than 100 bar per LSB.
    Gain,
}

/// Validated scaling (hot path: [`PressureScale::bar`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressureScale {
    code_lo: i32,
    bar_lo: PressureBar,
    gain_q24: i32, // bar/LSB, I8F24 raw
}

impl PressureCal {
    /// Validates the calibration.
    pub fn build(&self) -> Result<PressureScale, PressureCalError> {
        if self.code_lo >= self.code_hi || self.code_hi > 4095 {
            return Err(PressureCalError::Codes);
        }
        let ok = |x: f32| x.is_finite() && x.abs() <= 10_000.0;
        if !ok(self.bar_lo) || !ok(self.bar_hi) {
            return Err(PressureCalError::Pressure);
        }
        let span = f64::from(self.code_hi) - f64::from(self.code_lo);
        let gain = (f64::from(self.bar_hi) - f64::from(self.bar_lo)) / span;
        if gain.abs() > 100.0 {
            return Err(PressureCalError::Gain);
        }
        Ok(PressureScale {
            code_lo: i32::from(self.code_lo),
            bar_lo: PressureBar::saturating_from_num(self.bar_lo),
            gain_q24: I8F24::saturating_from_num(gain).to_bits(),
        })
    }
}

impl PressureScale {
    /// Pressure for an ADC code (`code` may carry fraction bits: `code_q4` is the code
    /// in 1/16 LSB, so an average of up to 16 samples keeps its resolution).
    #[inline]
    pub fn bar(&self, code_q4: u32) -> PressureBar {
        // code ≤ 4095·16 < 2^16: offset difference in 1/16 LSB fits i32.
        let code_q4 = i32::try_from(code_q4).unwrap_or(i32::MAX);
        let d_q4 = code_q4.saturating_sub(self.code_lo.saturating_mul(16));
        // d (Q.4) · g (Q.24) >> 12 = bar in Q.16; |d·g| < 2^17·2^31.
        let p = mul_shr_floor_sat(d_q4, self.gain_q24, 12);
        PressureBar::from_bits(p).saturating_add(self.bar_lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_maps_full_scale_to_250_bar() {
        let s = PressureCal::default().build().unwrap();
        assert_eq!(s.bar(0), PressureBar::ZERO);
        let top = s.bar(4095 * 16).to_num::<f64>();
        assert!((top - 250.0).abs() < 1e-3, "{top}");
        let mid = s.bar(2048 * 16 + 8).to_num::<f64>();
        assert!((mid - 2048.5 * 250.0 / 4095.0).abs() < 1e-3, "{mid}");
    }

    #[test]
    fn live_zero_transducer() {
        // 4–20 mA over 150 Ω into 3.3 V: 4 mA = 745, 20 mA = 3724 → 0–400 bar.
        let cal = PressureCal {
            code_lo: 745,
            bar_lo: 0.0,
            code_hi: 3724,
            bar_hi: 400.0,
        };
        let s = cal.build().unwrap();
        assert!(s.bar(745 * 16).saturating_abs() < PressureBar::from_num(1e-3));
        assert!((s.bar(3724 * 16).to_num::<f64>() - 400.0).abs() < 1e-2);
        // Below the live zero (broken loop): negative, visible to the host.
        assert!(s.bar(0) < PressureBar::from_num(-50));
    }

    #[test]
    fn rejects_bad_calibration() {
        let c = PressureCal {
            code_lo: 100,
            code_hi: 100,
            ..Default::default()
        };
        assert_eq!(c.build(), Err(PressureCalError::Codes));
        let c = PressureCal {
            bar_hi: f32::INFINITY,
            ..Default::default()
        };
        assert_eq!(c.build(), Err(PressureCalError::Pressure));
        let c = PressureCal {
            code_lo: 0,
            code_hi: 1,
            bar_lo: 0.0,
            bar_hi: 200.0,
        };
        assert_eq!(c.build(), Err(PressureCalError::Gain));
    }
}
