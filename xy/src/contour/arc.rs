//! Circular arc, parameterised by arc length.
//!
//! ```text
//! φ(u) = φ0 + σ·u/R          (σ = +1 counter-clockwise, −1 clockwise)
//! r(u) = c + R·(cos φ, sin φ),  r′ = σ·(−sin φ, cos φ),  r″ = −(cos φ, sin φ)/R
//! u ∈ [0, R·|sweep|] µm
//! ```
//!
//! φ is carried in turns (Q0.32, wrapping): φ = φ0 + σ·u·k with k = 2^64/(2πR) (Q0.64
//! turns per µm), so a full turn wraps exactly. sin/cos come from [`super::trig`]
//! (error < 10⁻¹⁵). The angle's resolution (2^-32 turn) only moves a point *along* the
//! circle (by 2πR·2^-32 = 1.5·10⁻⁵ µm at R = 10 mm); the radial error of a point is
//! the sin/cos error times R plus the Q12 rounding: < 0.2 nm for any R ≤ 4.19 m.

use super::path::{fine_bits, in_range, ParametricPath, PathError, PathPoint};
use super::trig::{sin_cos_q62, turns_from_deg};
use super::{Deriv, Param, PosFine, Xy};
use hydra_core::fixed_point::{mul64_shr_round_sat, sat_i64, shr_round_i64};

/// Specification of a circular arc, engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcSpec {
    /// Centre (x, y), µm.
    pub center_um: [f64; 2],
    /// Radius, µm (10 µm … 4.19 m).
    pub radius_um: f64,
    /// Angle of the start point seen from the centre, degrees (0 = +x, counter-clockwise).
    pub start_deg: f64,
    /// Swept angle, degrees: > 0 counter-clockwise, < 0 clockwise, 0 < |sweep| ≤ 3600.
    pub sweep_deg: f64,
}

/// A validated circular arc (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Arc {
    /// Centre, Q52.12 µm raw.
    center: Xy<i64>,
    /// Radius, Q52.12 µm raw.
    radius: i64,
    /// 1/R, Q0.64 raw (per µm).
    inv_r_q64: i64,
    /// 1/(2πR), Q0.64 turns per µm.
    turns_per_um_q64: i64,
    /// Start angle, Q0.32 turns.
    phi0: u32,
    /// Counter-clockwise?
    ccw: bool,
    /// Arc length, Q32.32 µm raw.
    len: i64,
}

impl ArcSpec {
    /// Validates the arc: finite, 10 µm ≤ R ≤ 4.19 m, 0 < |sweep| ≤ 3600°, the whole
    /// circle within ±8.388 m.
    pub fn build(&self) -> Result<Arc, PathError> {
        let [cx, cy] = self.center_um;
        let (r, a0, sw) = (self.radius_um, self.start_deg, self.sweep_deg);
        if ![cx, cy, r, a0, sw].iter().all(|v| v.is_finite()) {
            return Err(PathError::NotFinite);
        }
        if !(10.0..=4_194_304.0).contains(&r) {
            return Err(PathError::Radius);
        }
        if sw == 0.0 || !(-3600.0..=3600.0).contains(&sw) || !(-1e6..=1e6).contains(&a0) {
            return Err(PathError::Sweep);
        }
        if ![cx - r, cx + r, cy - r, cy + r]
            .iter()
            .all(|&v| in_range(v))
        {
            return Err(PathError::OutOfRange);
        }
        let two64 = 18_446_744_073_709_551_616.0_f64;
        let sweep_abs = if sw < 0.0 { -sw } else { sw };
        let len = r * sweep_abs * core::f64::consts::PI / 180.0;
        Ok(Arc {
            center: Xy::new(fine_bits(cx), fine_bits(cy)),
            radius: fine_bits(r),
            inv_r_q64: (two64 / r) as i64,
            turns_per_um_q64: (two64 / (core::f64::consts::TAU * r)) as i64,
            phi0: turns_from_deg(a0),
            ccw: sw > 0.0,
            len: Param::saturating_from_num(len).to_bits(),
        })
    }
}

impl Arc {
    /// Arc length, µm.
    pub fn length(&self) -> Param {
        Param::from_bits(self.len)
    }
}

impl Arc {
    /// φ(u) in turns: u (Q32) · k (Q64) → Q96 → Q32, wrapping to one turn.
    fn angle(&self, u: Param) -> u32 {
        let t = ((u.to_bits() as i128).wrapping_mul(self.turns_per_um_q64 as i128) >> 64) as u32;
        if self.ccw {
            self.phi0.wrapping_add(t)
        } else {
            self.phi0.wrapping_sub(t)
        }
    }

    /// c + R·(cos, sin): R (Q12) · cos (Q62) → Q12.
    fn on_circle(&self, s: i64, c: i64) -> Xy<PosFine> {
        Xy::new(
            PosFine::from_bits(self.center.x.saturating_add(mul64_shr_round_sat(
                self.radius,
                c,
                62,
            ))),
            PosFine::from_bits(self.center.y.saturating_add(mul64_shr_round_sat(
                self.radius,
                s,
                62,
            ))),
        )
    }
}

impl ParametricPath for Arc {
    fn position(&self, u: Param) -> Xy<PosFine> {
        let (s, c) = sin_cos_q62(self.angle(u));
        self.on_circle(s, c)
    }

    fn u_start(&self) -> Param {
        Param::ZERO
    }

    fn u_end(&self) -> Param {
        Param::from_bits(self.len)
    }

    fn eval(&self, u: Param) -> PathPoint {
        let (s, c) = sin_cos_q62(self.angle(u));
        let pos = self.on_circle(s, c);
        // r′ = σ(−sin, cos): Q62 → Q32.
        let (tx, ty) = (shr_round_i64(s, 30).wrapping_neg(), shr_round_i64(c, 30));
        let (tx, ty) = if self.ccw {
            (tx, ty)
        } else {
            (tx.wrapping_neg(), ty.wrapping_neg())
        };
        // r″ = −(cos, sin)/R: Q62 · Q64 → Q126 → Q32.
        let nx = sat_i64(hydra_core::fixed_point::shr_round_i128(
            (c as i128).wrapping_mul(self.inv_r_q64 as i128),
            94,
        ));
        let ny = sat_i64(hydra_core::fixed_point::shr_round_i128(
            (s as i128).wrapping_mul(self.inv_r_q64 as i128),
            94,
        ));
        PathPoint {
            pos,
            d1: Xy::new(Deriv::from_bits(tx), Deriv::from_bits(ty)),
            d2: Xy::new(
                Deriv::from_bits(nx.wrapping_neg()),
                Deriv::from_bits(ny.wrapping_neg()),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::path::curvature_per_m;
    use super::*;

    #[test]
    fn arc_eval_matches_f64() {
        for (r, sw) in [(10_000.0, 360.0), (25.0, -270.0), (4_000_000.0, 30.0)] {
            let spec = ArcSpec {
                center_um: [1000.0, -2000.0],
                radius_um: r,
                start_deg: -90.0,
                sweep_deg: sw,
            };
            let a = spec.build().unwrap();
            let len = a.length().to_num::<f64>();
            assert!((len - r * sw.abs().to_radians()).abs() < 1e-6);
            let sigma = if sw > 0.0 { 1.0 } else { -1.0 };
            for i in 0..=200 {
                let s = len * f64::from(i) / 200.0;
                let p = a.eval(Param::from_num(s));
                let phi = (-90f64).to_radians() + sigma * s / r;
                let (ex, ey) = (1000.0 + r * phi.cos(), -2000.0 + r * phi.sin());
                let (px, py) = (p.pos.x.to_num::<f64>(), p.pos.y.to_num::<f64>());
                // Radial error (what matters) below 0.2 nm; along-track within the
                // angle resolution.
                let rad = ((px - 1000.0).hypot(py + 2000.0) - r).abs();
                assert!(rad < 2e-4, "r={r} i={i} radial {rad}");
                assert!((px - ex).hypot(py - ey) < 2e-4 + r * 3e-9, "r={r} i={i}");
                let k = curvature_per_m(&p).unwrap().to_num::<f64>();
                assert!((k - sigma * 1e6 / r).abs() < 1e-3 + 1e-6 * 1e6 / r, "κ {k}");
            }
        }
    }

    #[test]
    fn arc_rejects_bad_specs() {
        let base = ArcSpec {
            center_um: [0.0, 0.0],
            radius_um: 1000.0,
            start_deg: 0.0,
            sweep_deg: 90.0,
        };
        assert!(base.build().is_ok());
        let e = |f: &dyn Fn(&mut ArcSpec)| {
            let mut s = base;
            f(&mut s);
            s.build().unwrap_err()
        };
        assert_eq!(e(&|s| s.radius_um = 5.0), PathError::Radius);
        assert_eq!(e(&|s| s.sweep_deg = 0.0), PathError::Sweep);
        assert_eq!(e(&|s| s.sweep_deg = 4000.0), PathError::Sweep);
        assert_eq!(
            e(&|s| s.center_um = [8_388_000.0, 0.0]),
            PathError::OutOfRange
        );
        assert_eq!(e(&|s| s.start_deg = f64::INFINITY), PathError::NotFinite);
    }
}
