//! The discrete tracking differentiator (TD) of SPEC §D.
//!
//! ```text
//! z1(k+1) = z1(k) + h·z2(k)
//! z2(k+1) = z2(k) + h·fhan(z1(k) − v(k), z2(k), r, h0)
//! ```
//!
//! `z1` tracks the input `v` (µm) as fast as an acceleration bound `r` allows and `z2`
//! is its derivative (µm/s), obtained without differentiating noise. Per step `|Δz2| ≤
//! r·h` exactly (|fhan| ≤ r). For a step of height `A` from rest the time-optimal
//! trajectory peaks at `|z2| = √(r·A)`; the tests check the discrete TD never exceeds it
//! by more than one step's `r·h`.
//!
//! In steady ramp tracking (v = V·t) the TD lags by `2·h0·V` (`fhan = 0` needs `a = 0`,
//! i.e. `z1 − v = −2·h0·z2`): the nonlinear PID runs the same TD on reference and
//! measurement so the lags cancel in `e1 = z11 − z21`.
//!
//! Formats: `z1` µm Q16 (`i64`) clamped to ±2⁴¹ (±2²⁵ µm ≈ 33.5 m, four times the
//! ±8.4 m of [`crate::units::PosUm`]), `z2` µm/s Q16 clamped to
//! ±[`super::V_MAX_UM_PER_S`], `h` a Q24 number of seconds. With these clamps every
//! product of a step is an `i64` product bounded below 2⁶³ (stated at each line): no
//! `i128` routine on a 32-bit CPU.

use super::fhan::{fhan_a, FhanCoeffs, FhanConfig, V_MAX_Q16};
use super::fxmath::{mul_bounded_shr, mul_shr};
use super::TdError;

/// Largest |z1| and |v| of a step, µm Q16 (2⁴¹).
const Z1_MAX_Q16: i64 = 1 << 41;

/// TD parameters in engineering units (validated by [`TdConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TdConfig {
    /// Speed factor r, µm/s² (see [`FhanConfig`]).
    pub r_um_per_s2: f64,
    /// Filter factor h0, s (≥ h; Han's recommendation against chattering).
    pub h0_s: f64,
    /// Integration step h, s (the control period, 10 µs … 10 ms).
    pub h_s: f64,
}

/// Validated TD coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TdCoeffs {
    fhan: FhanCoeffs,
    /// h, s, Q24.
    h_q24: i64,
    /// r·h, µm/s, Q16: the z2 step where fhan saturates (|a| > d).
    rh_q16: i64,
    /// h/h0, Q24 (≤ 1): the z2 step in fhan's linear zone is −a·h/h0.
    h_over_h0_q24: i64,
}

impl TdConfig {
    /// Validates the parameters (see [`FhanConfig::build`] and the field docs).
    pub fn build(&self) -> Result<TdCoeffs, TdError> {
        let h = self.h_s;
        if !(h.is_finite() && (1e-5..=0.01).contains(&h)) {
            return Err(TdError::Step);
        }
        let fhan = FhanConfig {
            r_um_per_s2: self.r_um_per_s2,
            h0_s: self.h0_s,
        }
        .build()?;
        if self.h0_s < h * (1.0 - 1e-9) {
            return Err(TdError::FilterBelowStep);
        }
        let h_q24 = (h * 16_777_216.0 + 0.5) as i64;
        // r_q16 < 2^46, h_q24 < 2^18; h_q24 < 2^18 so h_q24·2^24 < 2^42; h0_q24 ≥ 167.
        let rh_q16 = mul_shr(fhan.r_q16_raw(), h_q24, 24);
        // h/h0 as h·(1/h0) from fhan's own quantised 1/h0 (Q16), i.e. the same factor
        // the step had as fhan·h; < 2^18·2^33 before the shift.
        let h_over_h0_q24 = mul_shr(fhan.inv_h0_q16_raw(), h_q24, 16);
        Ok(TdCoeffs {
            fhan,
            h_q24,
            rh_q16,
            h_over_h0_q24,
        })
    }
}

impl TdCoeffs {
    /// The `fhan` coefficients.
    pub fn fhan(&self) -> &FhanCoeffs {
        &self.fhan
    }
    /// The quantised step h, s.
    pub fn h_s(&self) -> f64 {
        self.h_q24 as f64 / 16_777_216.0
    }
    /// h in Q24 seconds.
    pub(crate) fn h_q24(&self) -> i64 {
        self.h_q24
    }
}

/// TD state: `z1` (µm, Q16) and `z2` (µm/s, Q16).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Td {
    z1_um_q16: i64,
    z2_um_per_s_q16: i64,
}

impl Td {
    /// A TD at rest at `z1_um_q16` (µm, Q16; clamped to ±2⁴¹, ±33.5 m).
    pub const fn at_rest(z1_um_q16: i64) -> Self {
        let z1 = if z1_um_q16 > Z1_MAX_Q16 {
            Z1_MAX_Q16
        } else if z1_um_q16 < -Z1_MAX_Q16 {
            -Z1_MAX_Q16
        } else {
            z1_um_q16
        };
        Self {
            z1_um_q16: z1,
            z2_um_per_s_q16: 0,
        }
    }

    /// One step toward `v_um_q16` (µm, Q16; clamped to ±2⁴¹). Never fails.
    #[inline]
    pub fn step(&mut self, c: &TdCoeffs, v_um_q16: i64) {
        self.step_bounded(c, v_um_q16.clamp(-Z1_MAX_Q16, Z1_MAX_Q16));
    }

    /// One step toward a position from [`crate::units::PosUm`] (|v| < 2²³ µm ≤ 2³⁹ in
    /// Q16): no clamp needed on the input.
    #[inline(always)]
    pub(crate) fn step_pos(&mut self, c: &TdCoeffs, v: crate::units::PosUm) {
        self.step_bounded(c, super::q16_from_pos(v));
    }

    /// The step for `|v| ≤ 2⁴¹` (µm Q16).
    #[inline(always)]
    fn step_bounded(&mut self, c: &TdCoeffs, v: i64) {
        let (z1, z2) = (self.z1_um_q16, self.z2_um_per_s_q16);
        // |z1|, |v| ≤ 2^41: |x1| ≤ 2^42 = fhan_bounded's range; |z2| ≤ V_MAX_Q16.
        // h·fhan from fhan's switching variable a: −r·h·sign(a) if |a| > d, else
        // −a·h/h0 (one product instead of fhan's and then h's).
        let a = fhan_a(&c.fhan, z1.wrapping_sub(v), z2);
        let d = c.fhan.d_q16();
        let dz2 = if a > d {
            c.rh_q16.wrapping_neg()
        } else if a < d.wrapping_neg() {
            c.rh_q16
        } else {
            // |a| ≤ d ≤ 2^38 (Q16), h/h0 ≤ 1 (+1 LSB): |a·h_over_h0_q24| ≤ 2^62.
            mul_bounded_shr(a.wrapping_neg(), c.h_over_h0_q24, 24)
        };
        // |z2·h_q24| ≤ 2^39·2^18 = 2^57 (h ≤ 10 ms < 2^18 in Q24).
        let z1 = z1.wrapping_add(mul_bounded_shr(z2, c.h_q24, 24));
        // |dz2| ≤ r·h ≤ r·h0 = d ≤ 2^22 µm/s (validated).
        let z2 = z2.wrapping_add(dz2);
        self.z1_um_q16 = z1.clamp(-Z1_MAX_Q16, Z1_MAX_Q16);
        self.z2_um_per_s_q16 = z2.clamp(-V_MAX_Q16, V_MAX_Q16);
    }

    /// Tracked position z1, µm Q16.
    pub const fn position_um_q16(&self) -> i64 {
        self.z1_um_q16
    }

    /// Tracked derivative z2, µm/s Q16.
    pub const fn velocity_um_per_s_q16(&self) -> i64 {
        self.z2_um_per_s_q16
    }
}

#[cfg(test)]
mod tests {
    use super::super::fhan::reference::fhan_old;
    use super::*;

    fn coeffs(r: f64, h0: f64, h: f64) -> TdCoeffs {
        TdConfig {
            r_um_per_s2: r,
            h0_s: h0,
            h_s: h,
        }
        .build()
        .unwrap()
    }

    #[test]
    fn step_within_speed_bound_and_no_overshoot() {
        for &(r, h0, a) in &[(1e7, 1e-3, 1000.0), (1e6, 2e-3, 5e4), (5e7, 1e-3, 10.0)] {
            let c = coeffs(r, h0, 1e-3);
            let mut td = Td::at_rest(0);
            let v = (a * 65536.0) as i64;
            let bound = (r * a).sqrt() + r * 1e-3;
            let mut vmax: f64 = 0.0;
            let mut prev_z2 = 0i64;
            let t_settle = 2.0 * (a / r).sqrt() + 20e-3;
            let n = (t_settle / 1e-3) as usize + 50;
            for _ in 0..n {
                td.step(&c, v);
                let z2 = td.velocity_um_per_s_q16();
                // |Δz2| ≤ r·h (+ rounding).
                assert!(((z2 - prev_z2) as f64 / 65536.0).abs() <= r * 1e-3 + 1e-3);
                prev_z2 = z2;
                vmax = vmax.max(z2 as f64 / 65536.0);
                let z1 = td.position_um_q16() as f64 / 65536.0;
                assert!(z1 <= a * 1.001 + 1e-3, "overshoot {z1} > {a}");
            }
            assert!(vmax <= bound, "peak speed {vmax} > {bound}");
            if a > 10.0 * r * h0 * h0 {
                // Outside the linear zone the TD runs (nearly) bang-bang.
                assert!(vmax >= 0.5 * (r * a).sqrt(), "too slow: {vmax}");
            }
            let z1 = td.position_um_q16() as f64 / 65536.0;
            assert!((z1 - a).abs() <= 1e-3 * a + 1e-3, "settled at {z1} for {a}");
        }
    }

    #[test]
    fn matches_f64_td() {
        let c = coeffs(2e6, 2e-3, 1e-3);
        let (r, h0, h) = (c.fhan().r_um_per_s2(), c.fhan().h0_s(), c.h_s());
        let mut td = Td::at_rest(0);
        let (mut z1, mut z2) = (0.0f64, 0.0f64);
        let mut worst: f64 = 0.0;
        for k in 0..3000 {
            let t = k as f64 * 1e-3;
            let v = 20_000.0 * (2.0 * t).sin() + if t > 1.5 { 3000.0 } else { 0.0 };
            let vq = (v * 65536.0).round() as i64;
            td.step(&c, vq);
            let f = fhan_old(z1 - vq as f64 / 65536.0, z2, r, h0);
            z1 += h * z2;
            z2 += h * f;
            worst = worst.max((td.position_um_q16() as f64 / 65536.0 - z1).abs());
        }
        assert!(worst < 0.05, "TD diverges from f64 by {worst} µm");
    }

    #[test]
    fn rejects_bad_step() {
        let bad = TdConfig {
            r_um_per_s2: 1e7,
            h0_s: 1e-3,
            h_s: 2e-3,
        };
        assert_eq!(bad.build(), Err(TdError::FilterBelowStep));
        let bad = TdConfig { h_s: 0.0, ..bad };
        assert_eq!(bad.build(), Err(TdError::Step));
    }

    #[test]
    fn rest_stays_at_rest() {
        let c = coeffs(1e7, 1e-3, 1e-3);
        let mut td = Td::at_rest(123 << 16);
        for _ in 0..100 {
            td.step(&c, 123 << 16);
        }
        assert_eq!(td, Td::at_rest(123 << 16));
    }
}
