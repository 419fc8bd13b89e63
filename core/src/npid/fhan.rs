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
//! **Square root.** `a0` is formed as `u64::isqrt` (exact floor) of `d² + 8·r·|y|` in
//! Q12 (µm/s)², i.e. to 1/64 µm/s. Its relative error is below `1/(64·d)` ≤ 1.6·10⁻⁴ for
//! the validated `d ≥ 100 µm/s`; with the quantisation of `d` (1/64 µm/s) and `y`
//! (2⁻¹⁶ µm against `d0 ≥ 0.05 µm`) the error of `a0` stays below 5·10⁻⁴ relative,
//! under the 10⁻³ budget. The argument saturates at 2⁶⁴ (a0 = 2²⁶ µm/s = 67 m/s); with
//! `d ≤ 2²²` and `|x2| ≤ 2²³` µm/s the sign of `a` is still that of `y` there, so the
//! saturated result is the correct `−r·sign(y)`.

use super::fxmath::{mul_shr, sat_i64, sign};
use super::TdError;

/// Largest |velocity| the TD state and `fhan` accept, µm/s (2²³ µm/s ≈ 8.4 m/s).
pub const V_MAX_UM_PER_S: i64 = 1 << 23;
/// Same bound in Q16.
pub(crate) const V_MAX_Q16: i64 = V_MAX_UM_PER_S << 16;

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
        Ok(FhanCoeffs {
            r: r_int,
            h0_q24,
            inv_h0_q16,
            d_q16,
            d0_q16,
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
    /// r in Q16 µm/s².
    pub(crate) fn r_q16(&self) -> i64 {
        self.r.wrapping_shl(16)
    }
}

/// `fhan(x1, x2, r, h0)`: µm (Q16) and µm/s (Q16) in, µm/s² (Q16) out, |result| ≤ r.
#[inline]
pub fn fhan(c: &FhanCoeffs, x1_um_q16: i64, x2_um_per_s_q16: i64) -> i64 {
    let x2 = x2_um_per_s_q16.clamp(-V_MAX_Q16, V_MAX_Q16);
    let y = x1_um_q16.saturating_add(mul_shr(x2, c.h0_q24, 24));
    let a = if y.unsigned_abs() > c.d0_q16.unsigned_abs() {
        // (µm/s)² in Q12: d (Q6)² + 8·r·|y| (Q0·Q16 → ·8 >> 4 = >> 1).
        let d_q6 = c.d_q16.wrapping_shr(10);
        let d2 = (d_q6 as i128).wrapping_mul(d_q6 as i128);
        let ry = (c.r as i128)
            .wrapping_mul(y.unsigned_abs() as i128)
            .wrapping_shr(1);
        let arg = d2.saturating_add(ry);
        let arg = if arg > u64::MAX as i128 {
            u64::MAX
        } else {
            arg as u64
        };
        let a0_q16 = (arg.isqrt() as i64).wrapping_shl(10);
        let half = a0_q16.saturating_sub(c.d_q16).wrapping_shr(1);
        x2.saturating_add(sign(y).wrapping_mul(half))
    } else {
        x2.saturating_add(mul_shr(y, c.inv_h0_q16, 16))
    };
    if a.unsigned_abs() > c.d_q16.unsigned_abs() {
        sign(a).wrapping_neg().wrapping_mul(c.r_q16())
    } else {
        sat_i64(
            (a as i128)
                .wrapping_mul(c.inv_h0_q16 as i128)
                .wrapping_shr(16)
                .wrapping_neg(),
        )
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
