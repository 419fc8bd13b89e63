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
//! Formats (all `i32`):
//!
//! | quantity | unit | format | resolution | range |
//! |---|---|---|---|---|
//! | `z1` | µm | Q40 (`i64`; its high word is µm Q8) | 9·10⁻¹³ µm | ±(2²³ − 2¹⁹) µm = ±7.86 m (clamped) |
//! | input `v` | µm | Q8 ([`PosUm`] bits) | 3.9·10⁻³ µm | ±2²³ µm = ±8.4 m |
//! | `z2` | µm/s | Q8 ([`VelUmPerS`] bits) | 3.9·10⁻³ µm/s | [−2²², 2²² − 2⁻⁸] µm/s = ±4.2 m/s ([`super::V_MAX_UM_PER_S`], clamped) |
//! | `h` | s | Q32 | 2.3·10⁻¹⁰ s | 10 µs … 10 ms |
//! | `r·h` | µm/s | Q8 | 3.9·10⁻³ µm/s | ≤ d ≤ 2²¹ µm/s |
//! | `h/h0` | 1 | Q30 | 9.3·10⁻¹⁰ | ≤ 1 |
//!
//! **Cost.** `z1 += h·z2` is one `smlal` (Q8 × Q32 = Q40, exact: `z1` has no rounding
//! drift), fhan reads only `z1`'s high word (µm Q8), `a·h/h0` is one `smull`, every other
//! sum a saturating 32-bit `qadd`/`qsub`; `z1` is clamped on its high word alone (a step
//! moves it by ≤ |z2|·h ≤ 2³⁰·0.01 Q8 = 42 mm, far less than the 520 mm margin to the
//! `i64` range, so it never wraps).

use super::fhan::{fhan_a, FhanCoeffs, FhanConfig, V_MAX_Q8};
use super::TdError;
use hydra_core::units::{PosUm, VelUmPerS};

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
    /// h, s, Q32 (≤ 0.01·2³² < 2²⁶).
    h_q32: i32,
    /// r·h, µm/s, Q8 (≤ d ≤ 2²⁹): the z2 step where fhan saturates (|a| > d).
    rh_q8: i32,
    /// h/h0, Q30 (≤ 2³⁰): the z2 step in fhan's linear zone is −a·h/h0.
    h_over_h0_q30: i32,
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
        let h_q32 = (h * 4_294_967_296.0 + 0.5) as i64;
        let h0_q32 = i64::from(fhan.h0_q32());
        // r < 2^30, h_q32 < 2^26: < 2^56; r·h ≤ r·h0 = d ≤ 2^29 in Q8. Rounded to
        // nearest: the saturated zone adds it every step.
        let rh_q8 = i64::from(fhan.r_raw())
            .saturating_mul(h_q32)
            .saturating_add(1 << 23)
            >> 24;
        // h/h0 from the quantised h0 (≥ 42 950) and h (h_q32 < 2^26, << 30 < 2^56);
        // h ≤ h0 up to the quantisation: at most 2^30 + 1.
        let h_over_h0_q30 = (h_q32 << 30).checked_div(h0_q32).unwrap_or(0).min(1 << 30);
        Ok(TdCoeffs {
            fhan,
            h_q32: h_q32 as i32,
            rh_q8: rh_q8 as i32,
            h_over_h0_q30: h_over_h0_q30 as i32,
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
        f64::from(self.h_q32) / 4_294_967_296.0
    }
    /// h in Q32 seconds.
    #[inline(always)]
    pub(crate) fn h_q32(&self) -> i32 {
        self.h_q32
    }
}

/// Largest |z1|, µm Q8 (high word of the Q40 state): 2³¹ − 2²⁷, ±7.86 m.
const Z1_MAX_Q8: i32 = i32::MAX - (1 << 27);

/// TD state: `z1` (µm, Q40) and `z2` (µm/s, Q8).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Td {
    z1_um_q40: i64,
    z2_um_per_s_q8: i32,
}

impl Td {
    /// A TD at rest at `position_um` (clamped to ±7.86 m).
    pub const fn at_rest(position_um: PosUm) -> Self {
        let p = position_um.to_bits();
        let p = if p > Z1_MAX_Q8 {
            Z1_MAX_Q8
        } else if p < -Z1_MAX_Q8 {
            -Z1_MAX_Q8
        } else {
            p
        };
        Self {
            z1_um_q40: (p as i64) << 32,
            z2_um_per_s_q8: 0,
        }
    }

    /// One step toward `v_um` (µm). Never fails.
    #[inline(always)]
    pub fn step(&mut self, c: &TdCoeffs, v_um: PosUm) {
        let (z1, z2) = (self.z1_q8(), self.z2_um_per_s_q8);
        // |z2| ≤ V_MAX_Q8 (clamped below): fhan_a's range. h·fhan from fhan's switching
        // variable a: −r·h·sign(a) if |a| > d, else −a·h/h0 (one product instead of
        // fhan's and then h's).
        let a = fhan_a(&c.fhan, z1.saturating_sub(v_um.to_bits()), z2);
        let d = c.fhan.d_q8();
        let dz2 = if a > d {
            c.rh_q8.wrapping_neg()
        } else if a < d.wrapping_neg() {
            c.rh_q8
        } else {
            // |a| ≤ d ≤ 2^29, h/h0 ≤ 2^30 (Q30): below 2^59.
            (i64::from(a).wrapping_mul(i64::from(c.h_over_h0_q30)) >> 30).wrapping_neg() as i32
        };
        // Q8·Q32 = Q40, exact (`smlal`); |z2·h| ≤ 2^30·0.01·2^32 < 2^56 and |z1| ≤
        // Z1_MAX·2^32 before: no wrap. Then the clamp on the high word.
        let z1 = self
            .z1_um_q40
            .wrapping_add(i64::from(z2).wrapping_mul(i64::from(c.h_q32)));
        // The high word clamped, the low word (a fraction of 2^-8 µm) kept.
        let hi = ((z1 >> 32) as i32).clamp(-Z1_MAX_Q8, Z1_MAX_Q8);
        self.z1_um_q40 = (i64::from(hi) << 32) | i64::from(z1 as u32);
        // |dz2| ≤ r·h ≤ d ≤ 2^29 and |z2| ≤ 2^30: no overflow before the clamp to
        // [−2^30, 2^30 − 1] (one `ssat`).
        self.z2_um_per_s_q8 = z2
            .saturating_add(dz2)
            .clamp(-V_MAX_Q8, V_MAX_Q8.wrapping_sub(1));
    }

    /// Tracked position z1, µm.
    pub const fn position_um(&self) -> PosUm {
        PosUm::from_bits(self.z1_q8())
    }

    /// Tracked derivative z2, µm/s.
    pub const fn velocity_um_per_s(&self) -> VelUmPerS {
        VelUmPerS::from_bits(self.z2_um_per_s_q8)
    }

    /// z1, µm Q8 (raw).
    #[inline(always)]
    pub(crate) const fn z1_q8(&self) -> i32 {
        (self.z1_um_q40 >> 32) as i32
    }

    /// z2, µm/s Q8 (raw).
    #[inline(always)]
    pub(crate) const fn z2_q8(&self) -> i32 {
        self.z2_um_per_s_q8
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
            let mut td = Td::at_rest(PosUm::ZERO);
            let v = PosUm::from_num(a);
            let bound = (r * a).sqrt() + r * 1e-3;
            let mut vmax: f64 = 0.0;
            let mut prev_z2 = 0i32;
            let t_settle = 2.0 * (a / r).sqrt() + 20e-3;
            let n = (t_settle / 1e-3) as usize + 50;
            for _ in 0..n {
                td.step(&c, v);
                let z2 = td.z2_q8();
                // |Δz2| ≤ r·h (+ rounding).
                assert!((f64::from(z2 - prev_z2) / 256.0).abs() <= r * 1e-3 + 1e-2);
                prev_z2 = z2;
                vmax = vmax.max(f64::from(z2) / 256.0);
                let z1 = td.position_um().to_num::<f64>();
                assert!(z1 <= a * 1.001 + 1e-3, "overshoot {z1} > {a}");
            }
            assert!(vmax <= bound, "peak speed {vmax} > {bound}");
            if a > 10.0 * r * h0 * h0 {
                // Outside the linear zone the TD runs (nearly) bang-bang.
                assert!(vmax >= 0.5 * (r * a).sqrt(), "too slow: {vmax}");
            }
            let z1 = td.position_um().to_num::<f64>();
            assert!((z1 - a).abs() <= 1e-3 * a + 1e-3, "settled at {z1} for {a}");
        }
    }

    #[test]
    fn matches_f64_td() {
        let c = coeffs(2e6, 2e-3, 1e-3);
        let (r, h0, h) = (c.fhan().r_um_per_s2(), c.fhan().h0_s(), c.h_s());
        let mut td = Td::at_rest(PosUm::ZERO);
        let (mut z1, mut z2) = (0.0f64, 0.0f64);
        let mut worst: f64 = 0.0;
        for k in 0..3000 {
            let t = k as f64 * 1e-3;
            let v = 20_000.0 * (2.0 * t).sin() + if t > 1.5 { 3000.0 } else { 0.0 };
            let vq = PosUm::from_num(v);
            td.step(&c, vq);
            let f = fhan_old(z1 - vq.to_num::<f64>(), z2, r, h0);
            z1 += h * z2;
            z2 += h * f;
            let e = (td.position_um().to_num::<f64>() - z1).abs();
            worst = worst.max(e);
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
        let p = PosUm::from_num(123);
        let mut td = Td::at_rest(p);
        for _ in 0..100 {
            td.step(&c, p);
        }
        assert_eq!(td, Td::at_rest(p));
    }
}
