//! Han's time-optimal synthesis function `fhan` (SPEC §D), in fixed point.
//!
//! ```text
//! d = r·h0;  d0 = h0·d;  y = x1 + h0·x2;  a0 = √(d² + 8·r·|y|)
//! a = x2 + (a0 − d)/2·sign(y)   if |y| > d0,   else   a = x2 + y/h0
//! fhan = −r·sign(a)             if |a| > d,    else   fhan = −r·a/d  (= −a/h0)
//! ```
//!
//! `x1` is a position error (µm), `x2` a velocity (µm/s), `r` the speed factor (the
//! acceleration bound, µm/s²), `h0` the filter factor (s); `fhan` is an acceleration
//! (µm/s²) with `|fhan| ≤ r`. This is the older form; Han's 2009 form (`d = r·h0²`,
//! `a` scaled by `h0`, `fsg` switching functions) is the same function: the tests check
//! one against the other in `f64`.
//!
//! **Formats.** `x1`: µm in Q16 (`i64`, resolution 1.5·10⁻⁵ µm); `x2`: µm/s in Q16,
//! clamped on entry to ±[`V_MAX_UM_PER_S`]; result µm/s² in Q16. `r` is an integer number
//! of µm/s² (its rounding is < 5·10⁻⁴ relative for r ≥ 10³ µm/s²), `h0` a Q24 number of
//! seconds (6·10⁻⁸ s), `1/h0` a Q16 number of 1/s computed from the same quantised `h0`.
//!
//! **Square root.** `a0 = √(d² + 8·r·|y|)` is formed from the argument in Q2 (µm/s)²
//! (`u64`, below 2⁶³ for the validated ranges) by [`super::fxmath`]'s table + one Newton
//! step: relative error ≤ 2·10⁻⁸ (measured 0.9·10⁻⁸), plus the argument's quantisation
//! (< 1 LSB of Q2 on ≥ 9·d² ≥ 9·10⁴ (µm/s)², i.e. < 3·10⁻⁶) and `d`'s (1.5·10⁻⁵ µm/s):
//! a0's relative error is below 5·10⁻⁶, two hundred times under the 10⁻³ budget.
//!
//! **Cost.** No `i128` and no 64-bit division on the per-tick path: every product is an
//! `i64` product bounded below 2⁶³ by the validated ranges (each line states the bound),
//! the square root is a table lookup, a `umull` residual and one 32-bit `sdiv`. The
//! internal [`fhan_bounded`] (used by the TD, whose state is already in range) skips the
//! entry clamps of the public [`fhan`].

use super::fxmath::{mul_bounded_shr, mul_shr, sqrt_u64};
use super::TdError;

/// Largest |velocity| the TD state and `fhan` accept, µm/s (2²³ µm/s ≈ 8.4 m/s).
pub const V_MAX_UM_PER_S: i64 = 1 << 23;
/// Same bound in Q16.
pub(crate) const V_MAX_Q16: i64 = V_MAX_UM_PER_S << 16;
/// Largest |x1| [`fhan_bounded`] accepts, µm Q16 (2⁴² = 2²⁶ µm ≈ 67 m, eight times
/// the ±8.4 m of [`crate::units::PosUm`]); [`fhan`] clamps to it.
pub(crate) const X1_MAX_Q16: i64 = 1 << 42;

/// Parameters of `fhan` in engineering units (validated by [`FhanConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FhanConfig {
    /// Speed factor r: the acceleration bound, µm/s² (10³ … 10⁹, i.e. 1 mm/s² … 1000 m/s²).
    pub r_um_per_s2: f64,
    /// Filter factor h0, s (10⁻⁵ … 0.1).
    pub h0_s: f64,
}

/// Validated `fhan` coefficients (hot path: [`fhan`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FhanCoeffs {
    /// r, µm/s² (integer).
    r: i64,
    /// h0, s, Q24.
    h0_q24: i64,
    /// 1/h0, 1/s, Q16.
    inv_h0_q16: i64,
    /// d = r·h0, µm/s, Q16.
    d_q16: i64,
    /// d0 = h0·d, µm, Q16.
    d0_q16: i64,
    /// r, µm/s², Q16 (|fhan| in the saturated zone).
    r_q16: i64,
    /// d², (µm/s)², Q2 (from the quantised `d_q16`).
    d2_q2: u64,
}

impl FhanConfig {
    /// Validates `r` and `h0` and quantises them. Besides the ranges of each field,
    /// `d = r·h0` must lie in 100 µm/s … 2²² µm/s and `d0 = r·h0²` must be ≥ 0.05 µm
    /// (both keep the square root's relative error under 10⁻³).
    pub fn build(&self) -> Result<FhanCoeffs, TdError> {
        let r = self.r_um_per_s2;
        if !(r.is_finite() && (1e3..=1e9).contains(&r)) {
            return Err(TdError::SpeedFactor);
        }
        let h0 = self.h0_s;
        if !(h0.is_finite() && (1e-5..=0.1).contains(&h0)) {
            return Err(TdError::FilterFactor);
        }
        let r_int = (r + 0.5) as i64;
        let h0_q24 = (h0 * 16_777_216.0 + 0.5) as i64;
        let d_q16 = mul_shr(r_int, h0_q24, 8);
        let d0_q16 = mul_shr(d_q16, h0_q24, 24);
        if !((100 << 16)..=(1 << 38)).contains(&d_q16) || d0_q16 < 3277 {
            return Err(TdError::Boundary);
        }
        // 2^40 / h0_q24 = (1/h0) in Q16; h0_q24 ≥ 167.
        let inv_h0_q16 = (1i64 << 40).checked_div(h0_q24).unwrap_or(i64::MAX);
        // d ≤ 2^22 µm/s: d_q16² < 2^76, so square d in Q8 (d_q16 >> 8 < 2^30) → Q16, >> 14.
        let d_q8 = d_q16 >> 8;
        let d2_q2 = (d_q8 as u64).wrapping_mul(d_q8 as u64) >> 14;
        Ok(FhanCoeffs {
            r: r_int,
            h0_q24,
            inv_h0_q16,
            d_q16,
            d0_q16,
            r_q16: r_int << 16,
            d2_q2,
        })
    }
}

impl FhanCoeffs {
    /// The quantised speed factor r, µm/s².
    pub fn r_um_per_s2(&self) -> f64 {
        self.r as f64
    }
    /// The quantised filter factor h0, s.
    pub fn h0_s(&self) -> f64 {
        self.h0_q24 as f64 / 16_777_216.0
    }
    /// d = r·h0 in Q16 µm/s (> 0).
    pub(crate) fn d_q16(&self) -> i64 {
        self.d_q16
    }
    /// 1/h0 in Q16 1/s.
    pub(crate) fn inv_h0_q16_raw(&self) -> i64 {
        self.inv_h0_q16
    }
    /// r in Q16 µm/s².
    pub(crate) fn r_q16_raw(&self) -> i64 {
        self.r_q16
    }
    /// r in Q16 µm/s².
    #[cfg(test)]
    pub(crate) fn r_q16(&self) -> i64 {
        self.r_q16
    }
}

/// `fhan(x1, x2, r, h0)`: µm (Q16) and µm/s (Q16) in, µm/s² (Q16) out, |result| ≤ r.
/// `x1` is clamped to ±2²⁶ µm and `x2` to ±[`V_MAX_UM_PER_S`] first.
#[inline]
pub fn fhan(c: &FhanCoeffs, x1_um_q16: i64, x2_um_per_s_q16: i64) -> i64 {
    fhan_bounded(
        c,
        x1_um_q16.clamp(-X1_MAX_Q16, X1_MAX_Q16),
        x2_um_per_s_q16.clamp(-V_MAX_Q16, V_MAX_Q16),
    )
}

/// [`fhan`] for `|x1| ≤ 2⁴²` (µm Q16, [`X1_MAX_Q16`]) and `|x2| ≤` [`V_MAX_Q16`]: the
/// bounds below hold only then (larger inputs wrap, they never panic).
#[inline(always)]
fn fhan_bounded(c: &FhanCoeffs, x1: i64, x2: i64) -> i64 {
    let a = fhan_a(c, x1, x2);
    if a > c.d_q16 {
        c.r_q16.wrapping_neg()
    } else if a < c.d_q16.wrapping_neg() {
        c.r_q16
    } else {
        // |a| ≤ d = r·h0: |a_q16·inv_h0_q16| ≤ r·2^32 < 2^62.
        mul_bounded_shr(a, c.inv_h0_q16, 16).wrapping_neg()
    }
}

/// The switching variable `a` of `fhan` (µm/s Q16) for the ranges of [`fhan_bounded`]:
/// `fhan = −r·sign(a)` if `|a| > d`, else `−a/h0` (the TD scales that by `h` itself).
#[inline(always)]
pub(crate) fn fhan_a(c: &FhanCoeffs, x1: i64, x2: i64) -> i64 {
    // |x2·h0_q24| ≤ 2^39·0.1·2^24 < 2^60; |y| ≤ 2^42 + 2^36 < 2^43.
    let y = x1.wrapping_add(mul_bounded_shr(x2, c.h0_q24, 24));
    let ay = y.unsigned_abs();
    // d0 > 0 (validated).
    if ay > c.d0_q16 as u64 {
        // Q2 (µm/s)²: d² + 8·r·|y| = d² + r·|y_q16| >> 11, split at bit 16 of |y| so
        // both products stay in 64 bits: r < 2^30, |y| >> 16 < 2^27 → (·) << 5 < 2^62;
        // (|y| & 0xFFFF)·r < 2^46. Sum < 2^63.
        // r < 2^30 and both halves of |y| fit a u32: two `umull`.
        let r = c.r as u32;
        let ry_hi = u64::from(r).wrapping_mul(u64::from((ay >> 16) as u32));
        let ry_lo = u64::from(r).wrapping_mul(u64::from(ay as u32 & 0xFFFF));
        let arg = c.d2_q2.wrapping_add(ry_hi << 5).wrapping_add(ry_lo >> 11);
        // √(Q2) = Q1 = s·2^(1−k); in Q16: s·2^(16−k). s ≤ 2^31: < 2^47.
        let (s, k) = sqrt_u64(arg);
        let a0_q16 = (i64::from(s) << 16).wrapping_shr(k);
        let half = a0_q16.wrapping_sub(c.d_q16).wrapping_shr(1);
        if y < 0 {
            x2.wrapping_sub(half)
        } else {
            x2.wrapping_add(half)
        }
    } else {
        // |y| ≤ d0 and d0·(1/h0) = d ≤ 2^22 µm/s: |y_q16·inv_h0_q16| ≤ 2^54.
        x2.wrapping_add(mul_bounded_shr(y, c.inv_h0_q16, 16))
    }
}

/// `f64` references for the tests (both published forms).
#[cfg(test)]
pub(crate) mod reference {
    /// sign with sign(0) = 0 (Rust's `f64::signum(0.0)` is +1, which is *not* what the
    /// formulas mean).
    pub fn sgn(x: f64) -> f64 {
        if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        }
    }

    /// The older form (SPEC §D).
    pub fn fhan_old(x1: f64, x2: f64, r: f64, h0: f64) -> f64 {
        let d = r * h0;
        let d0 = h0 * d;
        let y = x1 + h0 * x2;
        let a0 = (d * d + 8.0 * r * y.abs()).sqrt();
        let a = if y.abs() > d0 {
            x2 + (a0 - d) / 2.0 * sgn(y)
        } else {
            x2 + y / h0
        };
        if a.abs() > d {
            -r * sgn(a)
        } else {
            -r * a / d
        }
    }

    /// Han's 2009 form with `fsg(x, d) = (sign(x + d) − sign(x − d))/2`.
    pub fn fhan_2009(x1: f64, x2: f64, r: f64, h0: f64) -> f64 {
        let fsg = |x: f64, d: f64| (sgn(x + d) - sgn(x - d)) / 2.0;
        let d = r * h0 * h0;
        let a0 = h0 * x2;
        let y = x1 + a0;
        let a1 = (d * (d + 8.0 * y.abs())).sqrt();
        let a2 = a0 + sgn(y) * (a1 - d) / 2.0;
        let sy = fsg(y, d);
        let a = (a0 + y - a2) * sy + a2;
        let sa = fsg(a, d);
        -r * (a / d - sgn(a)) * sa - r * sgn(a)
    }
}

#[cfg(test)]
mod tests {
    use super::reference::*;
    use super::*;
    use proptest::prelude::*;

    fn q16(x: f64) -> i64 {
        (x * 65536.0).round() as i64
    }

    #[test]
    fn forms_agree_in_f64() {
        let (r, h0) = (1e7, 2e-3);
        for i in -300..=300 {
            for j in -300..=300 {
                let x1 = f64::from(i) * 3.7;
                let x2 = f64::from(j) * 211.0;
                let a = fhan_old(x1, x2, r, h0);
                let b = fhan_2009(x1, x2, r, h0);
                assert!((a - b).abs() <= 1e-6 * r, "{x1} {x2}: {a} vs {b}");
            }
        }
        // At the origin and on the switching lines both give 0 / the same value.
        assert_eq!(fhan_old(0.0, 0.0, r, h0), 0.0);
        assert_eq!(fhan_2009(0.0, 0.0, r, h0), 0.0);
        // On the switching lines (|y| = d0, |a| = d) the 2009 form's fsg is ½ with
        // sign(0) = 0 and mixes both branches; the function is continuous there, so the
        // two forms still agree. (With `f64::signum`, sign(0) = +1 and fsg is 0 or 1 on
        // one side: the value happens to agree too, but only by continuity.)
        let d = r * h0;
        let d0 = r * h0 * h0;
        for &x2 in &[0.0, 123.0, -4567.0] {
            for &y in &[d0, -d0] {
                let x1 = y - h0 * x2;
                let a = fhan_old(x1, x2, r, h0);
                let b = fhan_2009(x1, x2, r, h0);
                assert!((a - b).abs() <= 1e-6 * r);
            }
            // |a| = d in the linear zone: a = x2 + y/h0 = d.
            let y = (d - x2) * h0;
            let x1 = y - h0 * x2;
            assert!((fhan_old(x1, x2, r, h0) - fhan_2009(x1, x2, r, h0)).abs() <= 1e-6 * r);
        }
        let c = FhanConfig {
            r_um_per_s2: r,
            h0_s: h0,
        }
        .build()
        .unwrap();
        assert_eq!(fhan(&c, 0, 0), 0);
    }

    #[test]
    fn fixed_point_matches_reference_on_a_grid() {
        for &(r, h0) in &[(1e7, 1e-3), (2e5, 1e-3), (2e6, 5e-3), (5e8, 1e-4)] {
            let c = FhanConfig {
                r_um_per_s2: r,
                h0_s: h0,
            }
            .build()
            .unwrap();
            let (rq, hq) = (c.r_um_per_s2(), c.h0_s());
            let d0 = rq * hq * hq;
            let d = rq * hq;
            for i in -200..=200 {
                for j in -200..=200 {
                    let x1 = f64::from(i) * d0 * 0.173;
                    let x2 = f64::from(j) * d * 0.0611;
                    let x1q = q16(x1) as f64 / 65536.0;
                    let x2q = q16(x2) as f64 / 65536.0;
                    let want = fhan_old(x1q, x2q, rq, hq);
                    let got = fhan(&c, q16(x1), q16(x2)) as f64 / 65536.0;
                    assert!(
                        (got - want).abs() <= 1e-3 * rq,
                        "r {r} h0 {h0} x1 {x1} x2 {x2}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn rejects_bad_parameters() {
        let ok = FhanConfig {
            r_um_per_s2: 1e7,
            h0_s: 1e-3,
        };
        assert!(ok.build().is_ok());
        let bad_r = FhanConfig {
            r_um_per_s2: f64::NAN,
            ..ok
        };
        assert_eq!(bad_r.build(), Err(TdError::SpeedFactor));
        let bad_h = FhanConfig { h0_s: 0.0, ..ok };
        assert_eq!(bad_h.build(), Err(TdError::FilterFactor));
        let tiny_d = FhanConfig {
            r_um_per_s2: 1e3,
            h0_s: 1e-3,
        };
        assert_eq!(tiny_d.build(), Err(TdError::Boundary));
    }

    proptest! {
        #[test]
        fn bounded_and_odd(x1 in any::<i64>(), x2 in any::<i64>()) {
            let c = FhanConfig { r_um_per_s2: 3e6, h0_s: 2e-3 }.build().unwrap();
            let f = fhan(&c, x1, x2);
            prop_assert!(f.abs() <= c.r_q16());
            if x1 > i64::MIN && x2 > i64::MIN {
                // fhan(−x) = −fhan(x) up to the floor of the shifts.
                let g = fhan(&c, -x1, -x2);
                prop_assert!((f + g).abs() <= c.r_q16() / 500 + 2);
            }
        }

        #[test]
        fn matches_reference_random(x1 in -5e5f64..5e5, x2 in -2e6f64..2e6) {
            let c = FhanConfig { r_um_per_s2: 3e6, h0_s: 2e-3 }.build().unwrap();
            let want = fhan_old(q16(x1) as f64 / 65536.0, q16(x2) as f64 / 65536.0,
                c.r_um_per_s2(), c.h0_s());
            let got = fhan(&c, q16(x1), q16(x2)) as f64 / 65536.0;
            prop_assert!((got - want).abs() <= 1e-3 * c.r_um_per_s2());
        }
    }
}
