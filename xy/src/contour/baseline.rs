//! The two classic estimators the adaptive method improves on (seed 003 §0004–0005),
//! on the same window and with the same sign convention, so they can be compared.
//!
//! * **Tangent line** (1st-order Taylor expansion of the distance function at the
//!   reference point R, the newest ordinary point): ε = (P − R)·n_R, n_R the right-hand
//!   normal of the path at R. Exact on a straight line; on a curve of radius ρ its error
//!   grows like L²/(2ρ) with the lag L between R and P's foot point.
//! * **Chord**: the distance from P to the polyline of the ordinary points (the nearest of
//!   all window segments). Its error is the sagitta ΔS²/(8ρ) of one period's chord.
//!
//! Cost: tangent 4 products; chord N − 1 segment distances (a normalisation each).

use super::estimate::{finish, u_at_foot, ContourEstimate};
use super::geom::{rel, rel_sat};
use super::window::{ContourWindow, OrdinaryPoint};
use super::{PosFine, RelUm, UnitQ30, Xy};
use hydra_core::fixed_point::{clamp_to_i32, mul_shr_round_i64};
use hydra_core::units::PosUm;

fn fine(p: Xy<PosUm>) -> Xy<i64> {
    Xy::new(
        i64::from(p.x.to_bits()).wrapping_shl(4),
        i64::from(p.y.to_bits()).wrapping_shl(4),
    )
}

/// Tangent-line estimate at a reference point: ε = (P − R)·n_R, n_R = (t_y, −t_x).
pub fn tangent_error(reference: &OrdinaryPoint, p: Xy<PosUm>) -> RelUm {
    let w = rel_sat(fine(p), reference.pos.map(PosFine::to_bits));
    let t = reference.tangent.map(UnitQ30::to_bits);
    // perp = t × w (> 0: P left); ε = −perp.
    let perp = mul_shr_round_i64(t.x, w.y, 30).saturating_sub(mul_shr_round_i64(t.y, w.x, 30));
    RelUm::from_bits(clamp_to_i32(perp.wrapping_neg(), i32::MAX))
}

impl<const N: usize, const H: usize> ContourWindow<N, H> {
    /// Tangent-line baseline at the newest ordinary point (the current reference).
    /// `None` for an empty window.
    pub fn estimate_tangent(&self, p: Xy<PosUm>) -> Option<RelUm> {
        Some(tangent_error(self.newest()?, p))
    }

    /// Chord baseline: P's distance to the polyline of the window's ordinary points
    /// (extra points ignored). `None` for an empty window.
    pub fn estimate_chord(&self, p: Xy<PosUm>) -> Option<ContourEstimate> {
        let pf = fine(p);
        if self.len() == 1 {
            return self.estimate(p);
        }
        let mut best: Option<(usize, super::geom::SegDist)> = None;
        for a in 0..self.len().saturating_sub(1) {
            if let Some(s) = self.segment_distance(pf, a) {
                if best.as_ref().is_none_or(|b| s.dist < b.1.dist) {
                    best = Some((a, s));
                }
            }
        }
        let (a, seg) = best?;
        let base = self.point(a)?.pos.map(PosFine::to_bits);
        let (_, saturated) = rel(pf, base);
        let b = a.wrapping_add(1);
        let u = u_at_foot(self.u_raw(a), self.u_raw(b), 0, 0, &seg);
        Some(finish(base, seg, b, 0, u, 0, saturated))
    }
}
