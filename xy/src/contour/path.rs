//! Parametric paths: the trait the interpolator runs on, curvature from derivatives,
//! and the straight line.
//!
//! A path is r(u) = (x(u), y(u)), u ∈ [u_start, u_end]. [`ParametricPath::eval`] gives
//! the position r, the first derivative r′ = dr/du and the second derivative
//! r″ = d²r/du² at u. The curvature follows from the derivatives:
//!
//! ```text
//! κ = (r′ × r″) / |r′|³      (1/µm; > 0 when the path turns left)
//! ```
//!
//! Formats (see the table in [`super`]): u is [`Param`] (`I32F32`, in the path's own
//! length-like unit, µm for every built-in path); r is [`PosFine`] (`I52F12` µm);
//! r′ and r″ are [`Deriv`] (`I32F32`, µm per unit of u and µm per unit of u²).
//!
//! Contract for an implementation: `u_start < u_end`; r′ ≠ 0 over the domain and
//! 1/16 ≤ |r′| ≤ 16 (u length-like, so the fixed formats keep their precision: the
//! interpolator saturates outside this range); positions within ±8.388 m; `eval` total
//! (any u, no panic) and exact to a small fraction of a nanometre, since the estimator's
//! accuracy can be no better than the points it is given.

use super::{Deriv, Param, PosFine, Xy};
use fixed::types::I32F32;
use hydra_core::fixed_point::{
    mul_shr30_round_i32_i64, mul_shr_round_i64_by_u32, normalize_no_len, shr_round_i128,
};

/// Largest |coordinate| of any point of a built-in path, µm (the range of `PosUm`).
pub const MAX_COORD_UM: f64 = 8_388_607.0;

/// One evaluation of a path at u.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PathPoint {
    /// Position r(u), µm.
    pub pos: Xy<PosFine>,
    /// First derivative r′(u), µm per unit of u.
    pub d1: Xy<Deriv>,
    /// Second derivative r″(u), µm per unit of u².
    pub d2: Xy<Deriv>,
}

/// A plane path r(u) with its first two derivatives (see the module docs for the
/// contract).
pub trait ParametricPath {
    /// First parameter value.
    fn u_start(&self) -> Param;
    /// Last parameter value (> `u_start`).
    fn u_end(&self) -> Param;
    /// Position, first and second derivative at `u`.
    fn eval(&self, u: Param) -> PathPoint;

    /// Position only (the interpolator's extra points); override when it is cheaper
    /// than [`ParametricPath::eval`]. Must equal `eval(u).pos`.
    fn position(&self, u: Param) -> Xy<PosFine> {
        self.eval(u).pos
    }
}

/// Why a path specification was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PathError {
    /// A parameter is NaN or infinite.
    NotFinite,
    /// A point of the path lies outside ±8.388 m.
    OutOfRange,
    /// The path is shorter than 1 µm.
    TooShort,
    /// Arc radius outside 10 µm … 4.19 m.
    Radius,
    /// Arc sweep zero or above 3600°.
    Sweep,
    /// Parabola |p| outside 1 µm … 8.388 m.
    Focal,
    /// Parabola span empty (`x_start ≥ x_end`) or |x| > 16·|p| (slope above 16).
    Span,
}

/// Signed curvature κ = (r′ × r″)/|r′|³ in 1/m (`I32F32`; > 0 turning left).
///
/// Its resolution is set by the r″ format: about 2.3·10⁻⁴ 1/m for a µm-parameterised
/// path (a relative error of 2.3·10⁻⁶ at a 10 mm radius). `None` where r′ = 0.
pub fn curvature_per_m(p: &PathPoint) -> Option<I32F32> {
    let f = deriv_frame(p)?;
    let k = curvature_q32_per_um(p, &f);
    // κ[1/m] = κ[1/µm]·10⁶.
    Some(I32F32::from_bits(k.saturating_mul(1_000_000)))
}

/// The derivatives at one point in the form the interpolator uses: the unit tangent
/// û = r′/|r′| (Q2.30) and 1/|r′| (Q2.30 raw in a wider `i64`: 2^30 = 1 unit of u per
/// µm). (|r′| itself is not needed: the Taylor step and κ use 1/|r′|.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DerivFrame {
    pub ux: i32,
    pub uy: i32,
    pub inv_q30: i64,
}

/// û and 1/|r′| (one normalisation without the length: no division). `None` where r′ = 0.
#[inline(always)]
pub(crate) fn deriv_frame(p: &PathPoint) -> Option<DerivFrame> {
    let f = normalize_no_len(p.d1.x.to_bits(), p.d1.y.to_bits())?;
    // 1/|r′| for r′ in Q32: (2^32/len_raw) in Q30 = recip with 62 fractional bits.
    Some(DerivFrame {
        ux: f.ux,
        uy: f.uy,
        inv_q30: f.recip(62),
    })
}

/// Signed curvature in 1/µm, Q32.32 raw bits:
/// κ = (û × r″)·(1/|r′|)² (Q30·Q32 → Q32, then twice ·Q30 → Q32).
#[inline(always)]
pub(crate) fn curvature_q32_per_um(p: &PathPoint, f: &DerivFrame) -> i64 {
    let (d2x, d2y) = (p.d2.x.to_bits(), p.d2.y.to_bits());
    // û × r″ = κ·|r′|², Q32.
    let cross =
        mul_shr30_round_i32_i64(f.ux, d2y).saturating_sub(mul_shr30_round_i32_i64(f.uy, d2x));
    let c1 = mul_shr_round_i64_by_u32(cross, f.inv_q30, 30);
    mul_shr_round_i64_by_u32(c1, f.inv_q30, 30)
}

/// A straight line from `start` to `end` (µm), parameterised by arc length u ∈ [0, L] µm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSpec {
    /// Start point (x, y), µm.
    pub start_um: [f64; 2],
    /// End point (x, y), µm.
    pub end_um: [f64; 2],
}

/// A validated straight line: r(u) = o + u·a, |a| = 1, u ∈ [0, L] µm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Line {
    /// Start point, Q52.12 µm raw.
    origin: Xy<i64>,
    /// Unit direction, Q2.62 raw.
    dir_q62: Xy<i64>,
    /// Length L, Q32.32 µm raw.
    len: i64,
}

/// √x by Newton's iteration (builders only: `f64::sqrt` is not in `core`). x ≥ 0.
pub(crate) fn sqrt_f64(x: f64) -> f64 {
    if x <= 0.0 || !x.is_finite() {
        return 0.0;
    }
    let mut g = if x > 1.0 { x } else { 1.0 };
    for _ in 0..200 {
        let n = 0.5 * (g + x / g);
        if n >= g {
            break;
        }
        g = n;
    }
    g
}

pub(crate) fn in_range(v: f64) -> bool {
    v.is_finite() && (-MAX_COORD_UM..=MAX_COORD_UM).contains(&v)
}

/// Q52.12 raw bits of a µm value (validated range).
pub(crate) fn fine_bits(v_um: f64) -> i64 {
    PosFine::saturating_from_num(v_um).to_bits()
}

impl LineSpec {
    /// Validates the line: finite, both ends within ±8.388 m, length ≥ 1 µm.
    pub fn build(&self) -> Result<Line, PathError> {
        let [x0, y0] = self.start_um;
        let [x1, y1] = self.end_um;
        if ![x0, y0, x1, y1].iter().all(|v| v.is_finite()) {
            return Err(PathError::NotFinite);
        }
        if ![x0, y0, x1, y1].iter().all(|&v| in_range(v)) {
            return Err(PathError::OutOfRange);
        }
        let (dx, dy) = (x1 - x0, y1 - y0);
        let l = sqrt_f64(dx * dx + dy * dy);
        if l < 1.0 {
            return Err(PathError::TooShort);
        }
        let q62 = 4_611_686_018_427_387_904.0_f64;
        Ok(Line {
            origin: Xy::new(fine_bits(x0), fine_bits(y0)),
            dir_q62: Xy::new((dx / l * q62) as i64, (dy / l * q62) as i64),
            len: Param::saturating_from_num(l).to_bits(),
        })
    }
}

impl Line {
    /// Length, µm.
    pub fn length(&self) -> Param {
        Param::from_bits(self.len)
    }
}

impl ParametricPath for Line {
    fn u_start(&self) -> Param {
        Param::ZERO
    }

    fn u_end(&self) -> Param {
        Param::from_bits(self.len)
    }

    /// r = o + u·a (u Q32 · a Q62 → Q94 → Q12), r′ = a, r″ = 0.
    fn eval(&self, u: Param) -> PathPoint {
        let u = u.to_bits();
        let along = |a: i64| {
            hydra_core::fixed_point::sat_i64(shr_round_i128(
                (u as i128).wrapping_mul(a as i128),
                82,
            ))
        };
        PathPoint {
            pos: Xy::new(
                PosFine::from_bits(self.origin.x.saturating_add(along(self.dir_q62.x))),
                PosFine::from_bits(self.origin.y.saturating_add(along(self.dir_q62.y))),
            ),
            d1: Xy::new(
                Deriv::from_bits(hydra_core::fixed_point::shr_round_i64(self.dir_q62.x, 30)),
                Deriv::from_bits(hydra_core::fixed_point::shr_round_i64(self.dir_q62.y, 30)),
            ),
            d2: Xy::new(Deriv::ZERO, Deriv::ZERO),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_eval_matches_f64() {
        let l = LineSpec {
            start_um: [-20_000.0, -10_000.0],
            end_um: [20_000.0, 10_000.0],
        }
        .build()
        .unwrap();
        let len = 40_000f64.hypot(20_000.0);
        assert!((l.length().to_num::<f64>() - len).abs() < 1e-6);
        for i in 0..=100 {
            let s = len * f64::from(i) / 100.0;
            let p = l.eval(Param::from_num(s));
            let ex = -20_000.0 + 40_000.0 * s / len;
            let ey = -10_000.0 + 20_000.0 * s / len;
            assert!((p.pos.x.to_num::<f64>() - ex).abs() < 5e-4, "{i}");
            assert!((p.pos.y.to_num::<f64>() - ey).abs() < 5e-4, "{i}");
            assert_eq!(curvature_per_m(&p), Some(I32F32::ZERO));
        }
    }

    #[test]
    fn line_rejects_bad_specs() {
        let bad = |s: [f64; 2], e: [f64; 2]| {
            LineSpec {
                start_um: s,
                end_um: e,
            }
            .build()
        };
        assert_eq!(bad([0.0, 0.0], [0.5, 0.0]), Err(PathError::TooShort));
        assert_eq!(bad([f64::NAN, 0.0], [1.0, 0.0]), Err(PathError::NotFinite));
        assert_eq!(bad([0.0, 0.0], [9e6, 0.0]), Err(PathError::OutOfRange));
    }

    #[test]
    fn sqrt_newton() {
        for x in [0.0, 1e-6, 0.25, 2.0, 1e14] {
            assert!((sqrt_f64(x) - x.sqrt()).abs() <= 1e-15 * x.sqrt().max(1.0));
        }
    }
}
