//! The linear PID of the classic cross-coupled controller (Koren's CCC), per axis and on
//! the contour error.
//!
//! ```text
//! e(k) = reference − measured  [µm]          (or the contour error ε)
//! P = kp·e
//! I(k) = clamp(I(k−1) + ki·h·e, ±i_max)      (not integrated further into a saturated output)
//! D(k) = D(k−1) + λ·(kd·(e(k) − e(k−1))/h − D(k−1)),   λ = h/(τ_d + h)
//! u = clamp(P + I + D, ±u_max)                 [DAC LSB]
//! ```
//!
//! kp in LSB/µm, ki in LSB/(µm·s), kd in LSB/(µm/s), τ_d the derivative filter's time
//! constant (s). Formats: gains in Q24 (`kp`, `ki·h`, `kd/h`), the integral and the
//! filtered derivative in LSB Q16, `λ` in Q24; errors µm Q16.

use super::{cmd_from_q16, q16_from_pos, ErrorLaw, NpidError};
use hydra_core::fixed_point::{mul64_shr_floor_sat, sign};
use hydra_core::units::{CmdLsb, PosUm};

/// Linear PID parameters (validated by [`PidConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidConfig {
    /// Control period h, s (10 µs … 10 ms).
    pub period_s: f64,
    /// Proportional gain kp, LSB/µm (0 … 10⁴).
    pub kp_lsb_per_um: f64,
    /// Integral gain ki, LSB/(µm·s) (0 … 10⁶).
    pub ki_lsb_per_um_s: f64,
    /// Derivative gain kd, LSB/(µm/s) (0 … 10).
    pub kd_lsb_s_per_um: f64,
    /// Derivative filter time constant τ_d, s (0 … 1).
    pub derivative_filter_s: f64,
    /// Clamp of the integral term, LSB (0 … 2047).
    pub integral_limit_lsb: f64,
    /// Clamp of |u|, LSB (1 … 2047).
    pub output_limit_lsb: f64,
}

/// Validated linear PID coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidCoeffs {
    kp_q24: i64,
    ki_h_q24: i64,
    kd_over_h_q24: i64,
    lambda_q24: i64,
    i_max_q16: i64,
    u_max_q16: i64,
}

impl PidConfig {
    /// Validates every parameter; the error names the first bad one.
    pub fn build(&self) -> Result<PidCoeffs, NpidError> {
        let h = self.period_s;
        if !(h.is_finite() && (1e-5..=0.01).contains(&h)) {
            return Err(NpidError::Period);
        }
        let in_range = |v: f64, hi: f64| v.is_finite() && (0.0..=hi).contains(&v);
        if !in_range(self.kp_lsb_per_um, 1e4) {
            return Err(NpidError::Gain(1));
        }
        if !in_range(self.ki_lsb_per_um_s, 1e6) {
            return Err(NpidError::Gain(0));
        }
        if !in_range(self.kd_lsb_s_per_um, 10.0) {
            return Err(NpidError::Gain(2));
        }
        if !in_range(self.derivative_filter_s, 1.0) {
            return Err(NpidError::DerivativeFilter);
        }
        if !in_range(self.integral_limit_lsb, 2047.0) {
            return Err(NpidError::IntegralLimit);
        }
        let ol = self.output_limit_lsb;
        if !(in_range(ol, 2047.0) && ol >= 1.0) {
            return Err(NpidError::OutputLimit);
        }
        let q24 = |v: f64| (v * 16_777_216.0 + 0.5) as i64;
        Ok(PidCoeffs {
            kp_q24: q24(self.kp_lsb_per_um),
            ki_h_q24: q24(self.ki_lsb_per_um_s * h),
            kd_over_h_q24: q24(self.kd_lsb_s_per_um / h),
            lambda_q24: q24(h / (self.derivative_filter_s + h)),
            i_max_q16: (self.integral_limit_lsb * 65536.0) as i64,
            u_max_q16: (ol * 65536.0) as i64,
        })
    }
}

/// Linear PID state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pid {
    /// Integral term, LSB Q16.
    i_q16: i64,
    /// Filtered derivative term, LSB Q16.
    d_q16: i64,
    /// Previous error, µm Q16.
    e_prev_q16: i64,
    /// −1/0/+1: last output clamped low / free / high.
    sat: i64,
}

impl Pid {
    /// One period on the error `e` (µm Q16).
    #[inline]
    fn law(&mut self, c: &PidCoeffs, e: i64) -> CmdLsb {
        let p = mul64_shr_floor_sat(e, c.kp_q24, 24);
        if self.sat == 0 || sign(e) != self.sat {
            self.i_q16 = self
                .i_q16
                .saturating_add(mul64_shr_floor_sat(e, c.ki_h_q24, 24))
                .clamp(c.i_max_q16.wrapping_neg(), c.i_max_q16);
        }
        let raw_d = mul64_shr_floor_sat(e.saturating_sub(self.e_prev_q16), c.kd_over_h_q24, 24);
        self.e_prev_q16 = e;
        let dd = mul64_shr_floor_sat(raw_d.saturating_sub(self.d_q16), c.lambda_q24, 24);
        self.d_q16 = self.d_q16.saturating_add(dd);
        let u = p.saturating_add(self.i_q16).saturating_add(self.d_q16);
        self.sat = if u > c.u_max_q16 {
            1
        } else if u < c.u_max_q16.wrapping_neg() {
            -1
        } else {
            0
        };
        cmd_from_q16(u.clamp(c.u_max_q16.wrapping_neg(), c.u_max_q16))
    }
}

impl ErrorLaw for Pid {
    type Coeffs = PidCoeffs;

    #[inline]
    fn track(&mut self, c: &PidCoeffs, reference_um: PosUm, measured_um: PosUm) -> CmdLsb {
        let e = q16_from_pos(reference_um).saturating_sub(q16_from_pos(measured_um));
        self.law(c, e)
    }

    #[inline]
    fn regulate(&mut self, c: &PidCoeffs, error_um: PosUm) -> CmdLsb {
        self.law(c, q16_from_pos(error_um))
    }

    fn reset(&mut self, _position_um: PosUm) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> PidConfig {
        PidConfig {
            period_s: 1e-3,
            kp_lsb_per_um: 0.8,
            ki_lsb_per_um_s: 5.0,
            kd_lsb_s_per_um: 0.0,
            derivative_filter_s: 2e-3,
            integral_limit_lsb: 200.0,
            output_limit_lsb: 2047.0,
        }
    }

    #[test]
    fn proportional_integral_and_limits() {
        let c = cfg().build().unwrap();
        let mut p = Pid::default();
        let u = p.regulate(&c, PosUm::from_num(100));
        // 0.8·100 + 5·1e-3·100 = 80.5 LSB.
        assert!((u.to_num::<f64>() - 80.5).abs() < 0.01, "{u}");
        for _ in 0..100_000 {
            p.regulate(&c, PosUm::from_num(100));
        }
        assert!((p.i_q16 - c.i_max_q16).abs() <= 1);
        let mut bad = cfg();
        bad.kd_lsb_s_per_um = f64::INFINITY;
        assert_eq!(bad.build(), Err(NpidError::Gain(2)));
        bad = cfg();
        bad.period_s = 0.1;
        assert_eq!(bad.build(), Err(NpidError::Period));
    }
}
