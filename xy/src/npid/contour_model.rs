//! The contour-error model of SPEC §D for lines and circles, and its sign convention.
//!
//! Reference point V on the path, actual point P, tracking errors `E1 = x_V − x_P`,
//! `E2 = y_V − y_P` (µm), θ the tangent angle at V (direction of travel), κ = 1/R the
//! signed curvature at V (1/µm; κ > 0 when the path turns left, i.e. the centre of
//! curvature is on the left; κ = 0 for a line):
//!
//! ```text
//! C1 = sin θ − E1·κ/2,   C2 = cos θ + E2·κ/2
//! ε  = −C1·E1 + C2·E2                           [µm]
//! ```
//!
//! **Sign convention.** With the left normal `n = (−sin θ, cos θ)`, the first-order term
//! is `ε ≈ n·(V − P)`: **ε > 0 when P lies to the right of the direction of travel**
//! (outside a counter-clockwise circle, inside a clockwise one). The exact signed
//! distance with the same convention is `n·(V − P)` on a line and `σ·(|P − c| − |R|)` on
//! a circle of centre c, σ = sign κ. Expanding the exact distance to second order gives
//! `ε = n·E + (t·E)²·κ/2` (t the unit tangent); the model's curvature term is
//! `|E|²·κ/2`, larger by `(n·E)²·κ/2 = ε²·κ/2`: second order in the contour error
//! itself, so the model is exact for the dominant (tangential, lag) part of the tracking
//! error. The tests bound the difference by `ε²/(2R) + 2|E|³/R²`.
//!
//! Formats: `sin θ`, `cos θ`, C1, C2 in Q30 (`i64`; C1, C2 may exceed 1 by the
//! curvature term), κ in Q48 1/µm (`i64`; R = 10 µm … ∞), E and ε in µm Q16. Products
//! are formed in `i128` and saturated.

use crate::contour::{UnitQ30, Xy};
use fixed::types::I32F32;
use hydra_core::fixed_point::{mul64_shr_floor_sat, sat_i64};

/// Path geometry at the reference point: unit tangent and signed curvature.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PathFrame {
    /// sin θ, Q30.
    pub sin_q30: i32,
    /// cos θ, Q30.
    pub cos_q30: i32,
    /// Signed curvature κ = 1/R, 1/µm, Q48 (> 0 turning left; 0 on a line).
    pub curvature_per_um_q48: i64,
}

impl PathFrame {
    /// A frame from the seed-003 interpolator's unit tangent (Q2.30) and a curvature in
    /// 1/m (`I32F32`, from [`crate::contour::curvature_per_m`]); fixed point only:
    /// κ[1/µm, Q48] = κ[1/m, Q32]·2¹⁶/10⁶, the constant 2¹⁶/10⁶ in Q32 (281 474 977,
    /// relative error 10⁻⁹). The curvature is clamped to ±0.1 1/µm.
    #[inline]
    pub fn from_contour(tangent: Xy<UnitQ30>, curvature_per_m: I32F32) -> Self {
        let k = mul64_shr_floor_sat(curvature_per_m.to_bits(), 281_474_977, 32);
        let kmax: i64 = 28_147_497_671_066; // 0.1 1/µm in Q48
        Self {
            sin_q30: tangent.y.to_bits(),
            cos_q30: tangent.x.to_bits(),
            curvature_per_um_q48: k.clamp(kmax.wrapping_neg(), kmax),
        }
    }

    /// A frame from a tangent direction and a curvature in `f64` (host side and tests;
    /// not for a fixed-point hot path). The tangent need not be normalised; a zero
    /// tangent gives θ = 0.
    pub fn from_f64(tx: f64, ty: f64, curvature_per_um: f64) -> Self {
        let l2 = tx * tx + ty * ty;
        let (s, c) = if l2 > 0.0 && l2.is_finite() {
            let l = sqrt_f64(l2);
            (ty / l, tx / l)
        } else {
            (0.0, 1.0)
        };
        let q30 = 1_073_741_824.0;
        let k = if curvature_per_um.is_finite() {
            curvature_per_um.clamp(-0.1, 0.1)
        } else {
            0.0
        };
        Self {
            sin_q30: round_i64(s * q30) as i32,
            cos_q30: round_i64(c * q30) as i32,
            curvature_per_um_q48: round_i64(k * 281_474_976_710_656.0),
        }
    }
}

/// √x by Newton's iteration (`f64::sqrt` is not in `core`); x > 0 and finite.
fn sqrt_f64(x: f64) -> f64 {
    let mut g = if x > 1.0 { x } else { 1.0 };
    for _ in 0..2000 {
        let n = 0.5 * (g + x / g);
        if n >= g {
            break;
        }
        g = n;
    }
    g
}

/// Round half away from zero (`f64::round` is not in `core`).
fn round_i64(x: f64) -> i64 {
    if x < 0.0 {
        ((0.5 - x) as i64).wrapping_neg()
    } else {
        (x + 0.5) as i64
    }
}

/// The coupling gains and the model contour error at one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContourModel {
    /// C1 = sin θ − E1·κ/2, Q30.
    pub c1_q30: i64,
    /// C2 = cos θ + E2·κ/2, Q30.
    pub c2_q30: i64,
    /// ε = −C1·E1 + C2·E2, µm Q16.
    pub error_um_q16: i64,
}

/// C1, C2 and ε from the frame at V and the tracking errors `E1`, `E2` (µm Q16).
#[inline]
pub fn contour_model(f: &PathFrame, e1_um_q16: i64, e2_um_q16: i64) -> ContourModel {
    // E·κ/2: Q16·Q48 = Q64, >> 35 → Q30 with the /2.
    let k = f.curvature_per_um_q48;
    let c1 = i64::from(f.sin_q30).saturating_sub(mul64_shr_floor_sat(e1_um_q16, k, 35));
    let c2 = i64::from(f.cos_q30).saturating_add(mul64_shr_floor_sat(e2_um_q16, k, 35));
    let eps = (c2 as i128)
        .wrapping_mul(e2_um_q16 as i128)
        .saturating_sub((c1 as i128).wrapping_mul(e1_um_q16 as i128))
        .wrapping_shr(30);
    ContourModel {
        c1_q30: c1,
        c2_q30: c2,
        error_um_q16: sat_i64(eps),
    }
}

/// Exact signed distances (our convention) for the tests.
#[cfg(test)]
pub(crate) mod exact {
    /// Signed distance of P from the line through V with direction θ.
    pub fn line(v: [f64; 2], theta: f64, p: [f64; 2]) -> f64 {
        -theta.sin() * (v[0] - p[0]) + theta.cos() * (v[1] - p[1])
    }

    /// Signed distance of P from the circle of centre c and radius r, travelled
    /// counter-clockwise (`ccw`) or clockwise.
    pub fn circle(c: [f64; 2], r: f64, ccw: bool, p: [f64; 2]) -> f64 {
        let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt();
        if ccw {
            d - r
        } else {
            r - d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn q16(x: f64) -> i64 {
        (x * 65536.0).round() as i64
    }

    proptest! {
        #[test]
        fn line_model_is_the_exact_signed_distance(
            theta in -3.2f64..3.2, e1 in -5000.0f64..5000.0, e2 in -5000.0f64..5000.0,
        ) {
            let f = PathFrame::from_f64(theta.cos(), theta.sin(), 0.0);
            let m = contour_model(&f, q16(e1), q16(e2));
            let v = [1000.0, -2000.0];
            let p = [v[0] - e1, v[1] - e2];
            let want = exact::line(v, theta, p);
            let got = m.error_um_q16 as f64 / 65536.0;
            prop_assert!((got - want).abs() < 1e-3, "{got} vs {want}");
        }

        #[test]
        fn circle_model_matches_exact_to_second_order(
            r in 5_000.0f64..500_000.0, phi in -3.2f64..3.2, ccw in any::<bool>(),
            et in -0.03f64..0.03, en in -0.005f64..0.005,
        ) {
            // V on the circle; E = V − P from tangential and normal parts (fractions of R).
            let c = [300.0, -700.0];
            let v = [c[0] + r * phi.cos(), c[1] + r * phi.sin()];
            let (t, kappa) = if ccw {
                ([-phi.sin(), phi.cos()], 1.0 / r)
            } else {
                ([phi.sin(), -phi.cos()], -1.0 / r)
            };
            let n = [-t[1], t[0]];
            let e = [et * r * t[0] + en * r * n[0], et * r * t[1] + en * r * n[1]];
            let p = [v[0] - e[0], v[1] - e[1]];
            let f = PathFrame::from_f64(t[0], t[1], kappa);
            let m = contour_model(&f, q16(e[0]), q16(e[1]));
            let got = m.error_um_q16 as f64 / 65536.0;
            let want = exact::circle(c, r, ccw, p);
            let emag = (e[0] * e[0] + e[1] * e[1]).sqrt();
            let bound = want * want / (2.0 * r) + 2.0 * emag.powi(3) / (r * r) + 1e-3;
            prop_assert!((got - want).abs() <= bound, "{got} vs {want} (bound {bound})");
            if want.abs() > 2.0 * bound {
                prop_assert_eq!(got.signum(), want.signum());
            }
        }
    }

    #[test]
    fn from_contour_matches_from_f64() {
        let t = Xy::new(UnitQ30::from_num(0.6), UnitQ30::from_num(0.8));
        let a = PathFrame::from_contour(t, I32F32::from_num(20.0)); // R = 50 mm
        let b = PathFrame::from_f64(0.6, 0.8, 2e-5);
        assert!((a.sin_q30 - b.sin_q30).abs() <= 1);
        assert!((a.cos_q30 - b.cos_q30).abs() <= 1);
        let rel = (a.curvature_per_um_q48 - b.curvature_per_um_q48).abs() as f64
            / b.curvature_per_um_q48 as f64;
        assert!(rel < 1e-8, "{rel}");
    }

    #[test]
    fn sign_convention_right_is_positive() {
        // Travelling +x along y = 0: a point below (to the right) has ε > 0.
        let f = PathFrame::from_f64(1.0, 0.0, 0.0);
        let m = contour_model(&f, 0, q16(10.0)); // V − P = (0, 10): P is 10 µm below.
        assert!(m.error_um_q16 > 0);
        // CCW circle, P outside: ε > 0.
        let r = 50_000.0;
        let f = PathFrame::from_f64(0.0, 1.0, 1.0 / r); // at (R, 0), moving +y
        let m = contour_model(&f, q16(-20.0), 0); // P = V + (20, 0): outside
        assert!((m.error_um_q16 as f64 / 65536.0 - 20.0).abs() < 0.01);
    }
}
