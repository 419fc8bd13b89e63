//! Parabola, parameterised by the coordinate along its own x axis.
//!
//! In the parabola's frame (vertex at the origin, x along the axis direction θ):
//!
//! ```text
//! x_l = u,   y_l = u²/(2p)                     (radius of curvature p at the vertex)
//! r(u) = v + x_l·a + y_l·b,   a = (cos θ, sin θ),  b = (−sin θ, cos θ)
//! r′ = a + (u/p)·b,           r″ = b/p
//! u ∈ [x_start, x_end] µm,    |u| ≤ 16·|p|  (|r′| ≤ 16.03)
//! ```
//!
//! Fixed point: u is rounded to Q16 µm (1.5·10⁻⁵ µm) and both x_l and y_l are computed
//! from that same value, so the point lies on the parabola; 1/(2p) and 1/p are Q48
//! (relative error < 2·10⁻¹¹ for |p| ≤ 8.4 m); y_l = u²·(1/(2p)) exact (a 64×64-bit
//! unsigned product while |x_l| < 65.5 mm, `i128` beyond) and u/p from 32-bit products, rounded to
//! Q12; the rotation uses the Q62 sin/cos of θ (exactly (1, 0) for θ = 0). A point is
//! within 0.4 nm of the exact parabola (two Q12 roundings and the rotation).

use super::path::{fine_bits, in_range, ParametricPath, PathError, PathPoint};
use super::trig::{sin_cos_q62, turns_from_deg, ONE_Q62};
use super::{Deriv, Param, PosFine, Xy};
use hydra_core::fixed_point::{
    mul64_shr_round_sat, mul_shr32_round_i64_small, shr_round_i64, sq_mul_shr68_round,
};

/// Specification of a parabolic segment, engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParabolaSpec {
    /// Vertex (x, y), µm.
    pub vertex_um: [f64; 2],
    /// p in y_l = x_l²/(2p), µm: the radius of curvature at the vertex; < 0 opens
    /// toward −y_l. 1 µm ≤ |p| ≤ 8.388 m.
    pub p_um: f64,
    /// Direction of the parabola's x axis, degrees (0 = +x).
    pub axis_deg: f64,
    /// First x_l, µm.
    pub x_start_um: f64,
    /// Last x_l, µm (> `x_start_um`).
    pub x_end_um: f64,
}

/// A validated parabola (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Parabola {
    vertex: Xy<i64>,
    /// cos θ, sin θ in Q62.
    rot: Xy<i64>,
    /// θ a multiple of 90° (sin θ, cos θ ∈ {0, ±1} exactly): the rotation is a swap
    /// and sign change of the components, no product.
    quarter: Option<Quarter>,
    /// 1/(2p) in Q48 (per µm).
    inv_2p_q48: i64,
    /// 1/p in Q48 (per µm).
    inv_p_q48: i64,
    /// Parameter range, Q32.32 µm raw.
    u0: i64,
    u1: i64,
}

/// An axis direction along ±x or ±y.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum Quarter {
    /// θ = 0°: (x, y).
    PlusX,
    /// θ = 90°: (−y, x).
    PlusY,
    /// θ = 180°: (−x, −y).
    MinusX,
    /// θ = 270°: (y, −x).
    MinusY,
}

/// Largest |u| the evaluation accepts, Q32 raw (2^23 µm).
const U_LIMIT: i64 = 1 << 55;

impl ParabolaSpec {
    /// Validates the parabola: finite; 1 µm ≤ |p| ≤ 8.388 m; x_start < x_end;
    /// |x| ≤ 16·|p|; the whole segment within ±8.388 m.
    pub fn build(&self) -> Result<Parabola, PathError> {
        let [vx, vy] = self.vertex_um;
        let (p, th, x0, x1) = (self.p_um, self.axis_deg, self.x_start_um, self.x_end_um);
        if ![vx, vy, p, th, x0, x1].iter().all(|v| v.is_finite()) {
            return Err(PathError::NotFinite);
        }
        let pa = if p < 0.0 { -p } else { p };
        if !(1.0..=8_388_607.0).contains(&pa) {
            return Err(PathError::Focal);
        }
        if x0 >= x1 || x0 < -16.0 * pa || x1 > 16.0 * pa || !(-1e6..=1e6).contains(&th) {
            return Err(PathError::Span);
        }
        if x1 - x0 < 1.0 {
            return Err(PathError::TooShort);
        }
        let (s, c) = sin_cos_q62(turns_from_deg(th));
        let q62 = 4_611_686_018_427_387_904.0_f64;
        let (cf, sf) = (c as f64 / q62, s as f64 / q62);
        // The segment lies in the box [x0, x1] × [y_min, y_max] of its own frame.
        let xm = if x0 <= 0.0 && x1 >= 0.0 { 0.0 } else { x0 };
        let ys = [
            x0 * x0 / (2.0 * p),
            x1 * x1 / (2.0 * p),
            xm * xm / (2.0 * p),
        ];
        let (mut ylo, mut yhi) = (ys[0], ys[0]);
        for &y in &ys {
            ylo = ylo.min(y);
            yhi = yhi.max(y);
        }
        for (xl, yl) in [(x0, ylo), (x0, yhi), (x1, ylo), (x1, yhi)] {
            if !in_range(vx + cf * xl - sf * yl) || !in_range(vy + sf * xl + cf * yl) {
                return Err(PathError::OutOfRange);
            }
        }
        let q48 = 281_474_976_710_656.0_f64;
        Ok(Parabola {
            vertex: Xy::new(fine_bits(vx), fine_bits(vy)),
            rot: Xy::new(c, s),
            quarter: match (c, s) {
                (ONE_Q62, 0) => Some(Quarter::PlusX),
                (0, ONE_Q62) => Some(Quarter::PlusY),
                (c, 0) if c == ONE_Q62.wrapping_neg() => Some(Quarter::MinusX),
                (0, s) if s == ONE_Q62.wrapping_neg() => Some(Quarter::MinusY),
                _ => None,
            },
            inv_2p_q48: (q48 / (2.0 * p)) as i64,
            inv_p_q48: (q48 / p) as i64,
            u0: Param::saturating_from_num(x0).to_bits(),
            u1: Param::saturating_from_num(x1).to_bits(),
        })
    }
}

impl Parabola {
    /// Rotates a local vector (Q-format kept) by θ: (c·x − s·y, s·x + c·y). For an axis
    /// along ±x or ±y the same result without products (exactly: c, s ∈ {0, ±2^62}).
    #[inline(always)]
    fn rotate(&self, x: i64, y: i64) -> (i64, i64) {
        match self.quarter {
            Some(Quarter::PlusX) => return (x, y),
            Some(Quarter::PlusY) => return (y.saturating_neg(), x),
            Some(Quarter::MinusX) => return (x.saturating_neg(), y.saturating_neg()),
            Some(Quarter::MinusY) => return (y, x.saturating_neg()),
            None => {}
        }
        let (c, s) = (self.rot.x, self.rot.y);
        (
            mul64_shr_round_sat(c, x, 62).saturating_sub(mul64_shr_round_sat(s, y, 62)),
            mul64_shr_round_sat(s, x, 62).saturating_add(mul64_shr_round_sat(c, y, 62)),
        )
    }
}

impl Parabola {
    /// The position at u and u rounded to Q16 µm (|uq| ≤ 2^39).
    #[inline(always)]
    fn local(&self, u: Param) -> (Xy<PosFine>, i64) {
        let u = u.to_bits().clamp(-U_LIMIT, U_LIMIT);
        let uq = shr_round_i64(u, 16);
        let xl = shr_round_i64(uq, 4);
        // u² (Q32, ≤ 2^78) · 1/(2p) (Q48, ≤ 2^47) → Q80 → Q12 (64-bit products while
        // |x_l| < 65.5 mm, the exact i128 form beyond).
        let yl = sq_mul_shr68_round(uq, self.inv_2p_q48);
        let (px, py) = self.rotate(xl, yl);
        // |x_l| ≤ 2^35 (u clamped to 2^23 µm), |y_l| ≤ 2^57 (u² ≤ 2^78 in Q32, 1/(2p) ≤
        // 2^47 in Q48), so |(px, py)| < 2^58 after any rotation; the vertex is within
        // ±8.4 m (2^35): the sum cannot wrap.
        (
            Xy::new(
                PosFine::from_bits(self.vertex.x.wrapping_add(px)),
                PosFine::from_bits(self.vertex.y.wrapping_add(py)),
            ),
            uq,
        )
    }
}

impl ParametricPath for Parabola {
    fn u_start(&self) -> Param {
        Param::from_bits(self.u0)
    }

    fn u_end(&self) -> Param {
        Param::from_bits(self.u1)
    }

    #[inline(always)]
    fn position(&self, u: Param) -> Xy<PosFine> {
        self.local(u).0
    }

    #[inline(always)]
    fn eval(&self, u: Param) -> PathPoint {
        let (pos, uq) = self.local(u);
        // u/p: Q16·Q48 → Q64 → Q32 (|uq| ≤ 2^39, |1/p| ≤ 2^48: 32-bit products).
        let slope = mul_shr32_round_i64_small(uq, self.inv_p_q48);
        let curv = shr_round_i64(self.inv_p_q48, 16);
        let (d1x, d1y) = self.rotate(1 << 32, slope);
        let (d2x, d2y) = self.rotate(0, curv);
        PathPoint {
            pos,
            d1: Xy::new(Deriv::from_bits(d1x), Deriv::from_bits(d1y)),
            d2: Xy::new(Deriv::from_bits(d2x), Deriv::from_bits(d2y)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::path::curvature_per_m;
    use super::*;

    #[test]
    fn parabola_eval_matches_f64() {
        for (p, th) in [(10_000.0, 0.0), (-2_500.0, 33.0), (1_000_000.0, -120.0)] {
            let spec = ParabolaSpec {
                vertex_um: [500.0, -700.0],
                p_um: p,
                axis_deg: th,
                x_start_um: -2.0 * f64::abs(p).min(20_000.0),
                x_end_um: 1.5 * f64::abs(p).min(20_000.0),
            };
            let par = spec.build().unwrap();
            let (c, s) = (f64::to_radians(th).cos(), f64::to_radians(th).sin());
            for i in 0..=200 {
                let x = spec.x_start_um + (spec.x_end_um - spec.x_start_um) * f64::from(i) / 200.0;
                let pt = par.eval(Param::from_num(x));
                let y = x * x / (2.0 * p);
                let (ex, ey) = (500.0 + c * x - s * y, -700.0 + s * x + c * y);
                let (px, py) = (pt.pos.x.to_num::<f64>(), pt.pos.y.to_num::<f64>());
                assert!((px - ex).hypot(py - ey) < 4e-4, "p={p} θ={th} x={x}");
                let k_exact = 1.0 / p / (1.0 + (x / p).powi(2)).powf(1.5) * 1e6;
                let k = curvature_per_m(&pt).unwrap().to_num::<f64>();
                assert!(
                    (k - k_exact).abs() < 2e-3 + 1e-6 * k_exact.abs(),
                    "κ {k} vs {k_exact}"
                );
            }
        }
    }

    #[test]
    fn quarter_turn_rotation_equals_the_products() {
        for (th, q) in [
            (0.0, Some(Quarter::PlusX)),
            (90.0, Some(Quarter::PlusY)),
            (180.0, Some(Quarter::MinusX)),
            (-90.0, Some(Quarter::MinusY)),
            (450.0, Some(Quarter::PlusY)),
            (30.0, None),
        ] {
            let mut par = ParabolaSpec {
                vertex_um: [500.0, -700.0],
                p_um: 10_000.0,
                axis_deg: th,
                x_start_um: -20_000.0,
                x_end_um: 20_000.0,
            }
            .build()
            .unwrap();
            assert_eq!(par.quarter, q, "θ = {th}");
            let fast: [PathPoint; 51] =
                core::array::from_fn(|i| par.eval(Param::from_num(-20_000 + 800 * i as i32)));
            par.quarter = None;
            for (i, f) in fast.iter().enumerate() {
                assert_eq!(
                    *f,
                    par.eval(Param::from_num(-20_000 + 800 * i as i32)),
                    "θ = {th}"
                );
            }
        }
    }

    #[test]
    fn parabola_rejects_bad_specs() {
        let base = ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 10_000.0,
            axis_deg: 0.0,
            x_start_um: -20_000.0,
            x_end_um: 20_000.0,
        };
        assert!(base.build().is_ok());
        let e = |f: &dyn Fn(&mut ParabolaSpec)| {
            let mut s = base;
            f(&mut s);
            s.build().unwrap_err()
        };
        assert_eq!(e(&|s| s.p_um = 0.5), PathError::Focal);
        assert_eq!(e(&|s| s.x_end_um = -30_000.0), PathError::Span);
        assert_eq!(e(&|s| s.x_end_um = 200_000.0), PathError::Span);
        assert_eq!(
            e(&|s| s.vertex_um = [0.0, 8_380_000.0]),
            PathError::OutOfRange
        );
        assert_eq!(e(&|s| s.p_um = f64::NAN), PathError::NotFinite);
    }
}
