//! The real-time adaptive contour-error estimator (SPEC §C, steps 2–6).
//!
//! Given the actual point P and a [`ContourWindow`]:
//!
//! 1. **Nearest ordinary point** S_m by |P − S_k|²: a walk downhill from the last call's
//!    nearest point (3 evaluations in steady state), with a full scan of the window (N
//!    evaluations) as the fallback ([`super::nearest`]).
//! 2. **Segment choice** between (S_{m−1}, S_m) and (S_m, S_{m+1}): the one on P's side
//!    of the path normal at S_m, i.e. outgoing when (P − S_m)·t_m ≥ 0 with t_m the unit
//!    tangent stored with S_m. The seed compares P's distances to the two segments;
//!    that rule is ambiguous on the convex side near S_m, where both distances clamp to
//!    |P − S_m| while the foot can lie up to e·ΔS/(2ρ) into either segment (e the offset,
//!    ρ the radius of curvature) — an error of up to e·ΔS²/(8ρ²), 0.016 µm at 500 mm/s
//!    on a 10 mm radius. The normal test has no such zone and costs one dot product
//!    instead of two segment distances. (The distance rule is kept for a window pushed
//!    without tangents.)
//! 3. **Bisection** over that segment's extra points E_0 = S_a, E_1 … E_h, E_{h+1} = S_b:
//!    with lo = 0, hi = h + 1, while hi − lo ≥ 2, mid = ⌊(lo + hi)/2⌋ and
//!    `(P − E_mid)·(E_hi − E_lo) ≥ 0 ? lo = mid : hi = mid` — the foot lies beyond E_mid
//!    when P projects forward of it on the local chord direction (for a circle the
//!    chord E_lo→E_hi is exactly parallel to the tangent at a midpoint). Each step halves
//!    hi − lo, so it stops after at most ⌈log₂(h + 1)⌉ ≤ ⌈log₂(H + 1)⌉ steps
//!    ([`max_bisection_steps`]) for *any* window contents.
//! 4. **Final chord** (E_lo, E_hi): the distance from P to it is |ε|, the perpendicular's
//!    foot (clamped to the chord) is the foot point F. At the window's newest end, and
//!    at its oldest while that is still the path's start (window not yet full), the
//!    chord is open: a P ahead of the newest point (axes leading a decelerating
//!    reference) or behind the start is measured to the chord's *line* — the path goes
//!    on there, the window just holds no more of it. (Clamped, |ε| would be the
//!    distance to the end point, i.e. the along-path lead, with a sign that flips with
//!    the tiny normal offset: ±20 µm of chatter in a cross-coupled loop.)
//! 5. **Sign**: ε = |ε|·sgn(N·(P − F)) with N the right-hand normal of the final chord
//!    (its direction of travel turned −90°): **ε > 0 when P lies to the right of the
//!    path**. This is SPEC §D's convention, ε ≈ −C1·E1 + C2·E2 with E = V − P, so the
//!    cross-coupled controller can use it as is.
//!
//! **Worst case per call** (`N` ordinary points, `H` extra points per segment): a walk
//! that ends at the window's end plus the full scan, at most 2N squared distances (2
//! subtractions, 2 `i32×i32→i64` products each), one dot product for the
//! segment choice, ⌈log₂(H + 1)⌉ bisection steps (6 subtractions and 2 products each),
//! one point-to-chord distance (one inverse square root by 3 Newton steps, at most one
//! more for a foot clamped to a chord end, about a dozen products) and one 32-bit
//! division for [`ContourEstimate::u_foot`]. No 64-bit division, no library call. No
//! allocation, no float, no panic; the window is only read (apart from the warm-start hint,
//! a `Cell` inside it).

use super::geom::{chord_dist, dot, rel, seg_dist, sub, Ends, SegDist};
use super::window::{clamp_pos, ContourWindow, OrdinaryPoint};
use super::{Param, PosFine, RelUm, UnitQ30, Xy};
use hydra_core::fixed_point::clamp_to_i32;
use hydra_core::units::PosUm;

/// The result of one estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContourEstimate {
    /// Signed contour error ε, µm (`I20F12`, 0.24 nm, ±524 mm): > 0 when the actual point
    /// is to the right of the path's direction of travel.
    pub eps_um: RelUm,
    /// Foot point F on the final chord, µm: within e·L/(2ρ) of the exact foot along the
    /// path (e = |ε|, L the final chord's length, ρ the radius of curvature: 0.025 µm
    /// for 50 µm, 10 µm, 10 mm) and within the chord's sagitta across it.
    pub foot: Xy<PosFine>,
    /// Unit tangent of the final chord (direction of travel), Q2.30: (cos θ, sin θ) of
    /// SPEC §D.
    pub tangent: Xy<UnitQ30>,
    /// Index (0 = oldest) of the ordinary point ending the chosen segment; 0 when the
    /// window holds a single point.
    pub segment: u16,
    /// Index of the final chord within that segment (0 … h).
    pub sub_chord: u16,
    /// Path parameter at the foot point, interpolated linearly over the segment's
    /// parameter range by the foot's arc-length place among its h + 1 sub-chords
    /// (resolution 2^-16 of the segment). For an arc-length parameter (line, circle) it
    /// is as close as the foot point itself; otherwise off by up to ΔS²·|d²u/ds²|/8
    /// more (below 1 µm of u on the default parabola at 500 mm/s). Evaluate the path there for the
    /// curvature (SPEC §D's R); for the tangent, [`Self::tangent`] is better.
    pub u_foot: Param,
    /// Bisection steps taken (≤ [`max_bisection_steps`]).
    pub bisection_steps: u8,
    /// P is more than 262 mm from the nearest ordinary point: distances saturated.
    pub saturated: bool,
}

impl ContourEstimate {
    /// ε in the controller's position format (`PosUm`, rounded to 3.9 nm).
    pub fn eps_pos_um(&self) -> PosUm {
        PosUm::from_bits(
            hydra_core::fixed_point::shr_round_i64(i64::from(self.eps_um.to_bits()), 4) as i32,
        )
    }
}

/// ⌈log₂(h + 1)⌉: the most bisection steps over h extra points.
pub const fn max_bisection_steps(h: usize) -> u32 {
    let n = h.saturating_add(1);
    if n <= 1 {
        0
    } else {
        usize::BITS.wrapping_sub(n.wrapping_sub(1).leading_zeros())
    }
}

/// Point k of a segment's bisection sequence: 0 = S_a, h + 1 = S_b (= `d`), else
/// extra point k (all relative to S_a).
#[inline]
fn seq_point(extras: &[Xy<i32>], d: Xy<i32>, k: usize) -> Xy<i32> {
    if k == 0 {
        Xy::new(0, 0)
    } else {
        match extras.get(k.wrapping_sub(1)) {
            Some(&e) => e,
            None => d,
        }
    }
}

/// Bisection over a segment's extra points (step 3 of the module docs).
///
/// `w` = P − S_a, `d` = S_b − S_a, `extras` relative to S_a. Returns (lo, hi, steps)
/// with hi = lo + 1 (or hi = lo = 0 for an empty sequence), `steps` ≤
/// ⌈log₂(extras.len() + 1)⌉.
#[inline(always)]
pub(crate) fn bisect(w: Xy<i32>, d: Xy<i32>, extras: &[Xy<i32>]) -> (usize, usize, u8) {
    let mut lo = 0usize;
    let mut hi = extras.len().saturating_add(1);
    let mut steps = 0u8;
    // E_lo and E_hi are carried along (the new end is the old E_mid): one point read
    // per step.
    let (mut pl, mut ph) = (Xy::new(0, 0), seq_point(extras, d, hi));
    // hi − lo halves (rounding up) every step: ⌈log₂(h + 1)⌉ steps; the bound is a
    // belt-and-braces guard, never reached.
    for _ in 0..usize::BITS {
        if hi.wrapping_sub(lo) < 2 {
            break;
        }
        let mid = lo.wrapping_add(hi.wrapping_sub(lo) / 2);
        let pm = seq_point(extras, d, mid);
        // (P − E_mid)·(E_hi − E_lo) in i64: every component difference ≤ 2^31, each
        // product ≤ 2^62, the sum saturates.
        let (qx, qy) = (
            i64::from(w.x).wrapping_sub(i64::from(pm.x)),
            i64::from(w.y).wrapping_sub(i64::from(pm.y)),
        );
        let (cx, cy) = (
            i64::from(ph.x).wrapping_sub(i64::from(pl.x)),
            i64::from(ph.y).wrapping_sub(i64::from(pl.y)),
        );
        if qx.wrapping_mul(cx).saturating_add(qy.wrapping_mul(cy)) >= 0 {
            (lo, pl) = (mid, pm);
        } else {
            (hi, ph) = (mid, pm);
        }
        steps = steps.wrapping_add(1);
    }
    (lo, hi, steps)
}

impl<const N: usize, const H: usize> ContourWindow<N, H> {
    /// Raw absolute position of ordinary point `i`.
    fn pos_raw(&self, i: usize) -> Option<Xy<i64>> {
        self.point(i).map(|p| p.pos.map(PosFine::to_bits))
    }

    pub(crate) fn u_raw(&self, i: usize) -> i64 {
        self.point(i).map_or(0, |p| p.u.to_bits())
    }

    fn tangent_raw(&self, i: usize) -> Xy<i32> {
        self.point(i)
            .map(|p| p.tangent.map(UnitQ30::to_bits))
            .unwrap_or(Xy::new(0, 0))
    }

    /// P's distance to the segment (S_a, S_{a+1}).
    pub(crate) fn segment_distance(&self, p: Xy<i64>, a: usize) -> Option<SegDist> {
        let sa = self.pos_raw(a)?;
        let sb = self.pos_raw(a.checked_add(1)?)?;
        let (w, _) = rel(p, sa);
        let (d, _) = rel(sb, sa);
        Some(seg_dist(w, d, self.tangent_raw(a)))
    }

    /// The adaptive estimate of the contour error of the actual point `p` (µm, the
    /// axes' position format). `None` only for an empty window. See the module docs for
    /// the method and its worst-case cost.
    pub fn estimate(&self, p: Xy<PosUm>) -> Option<ContourEstimate> {
        self.estimate_fine(Xy::new(
            PosFine::from_bits(i64::from(p.x.to_bits()).wrapping_shl(4)),
            PosFine::from_bits(i64::from(p.y.to_bits()).wrapping_shl(4)),
        ))
    }

    /// [`Self::estimate`] for a point given in the fine format.
    /// P is saturated to ±268 m like the window's points.
    pub fn estimate_fine(&self, p: Xy<PosFine>) -> Option<ContourEstimate> {
        let p = clamp_pos(p.map(PosFine::to_bits));
        let n = self.len();
        // Step 1: the nearest ordinary point S_m (warm-started walk or full scan).
        let m = self.nearest_point(p)?;
        let slot_m = self.slot(m)?;
        let sm = slot_m.pos_raw();
        let (wm, saturated) = rel(p, sm);
        if n == 1 {
            let seg = seg_dist(wm, Xy::new(0, 0), slot_m.tangent_raw());
            return Some(finish(sm, seg, 0, 0, slot_m.u_raw(), 0, saturated));
        }
        // Step 2: the segment (S_a, S_b) on P's side of the normal at S_m:
        // (P − S_m)·t_m ≥ 0 → the foot lies after S_m (outgoing), else before it.
        let t = slot_m.tangent_raw();
        let incoming = m.checked_sub(1);
        let outgoing = if m.wrapping_add(1) < n { Some(m) } else { None };
        let a = match (incoming, outgoing) {
            (Some(i), Some(o)) => {
                if t != Xy::new(0, 0) {
                    if dot(wm, t) >= 0 {
                        o
                    } else {
                        i
                    }
                } else {
                    // No tangent stored: the nearer segment by distance (seed's rule).
                    let di = self.segment_distance(p, i)?.dist;
                    let d_o = self.segment_distance(p, o)?.dist;
                    if d_o < di {
                        o
                    } else {
                        i
                    }
                }
            }
            (Some(i), None) => i,
            (None, Some(o)) => o,
            (None, None) => return None,
        };
        let b = a.wrapping_add(1);
        let (slot_a, slot_b) = (self.slot(a)?, self.slot(b)?);
        let sa = slot_a.pos_raw();
        let w = if a == m { wm } else { rel(p, sa).0 };
        let (d, _) = rel(slot_b.pos_raw(), sa);
        // b ≥ 1: its extra points are those of the segment (S_a, S_b).
        let extras = slot_b.extras();
        // Step 3: bisection; step 4: the final chord.
        let (lo, hi, steps) = bisect(w, d, extras);
        let el = seq_point(extras, d, lo);
        let eh = seq_point(extras, d, hi);
        // At the window's ends the path goes on beyond the last chord: P ahead of the
        // newest point (axes leading a decelerating reference) or behind the path's
        // start is measured to the chord's line, not to its end point (step 4). Behind
        // the oldest point of a full window (a lag longer than the window: too short a
        // window for the servo) stays clamped: the distance to that point, an
        // overestimate, not a line that may leave a curved path far behind.
        let at_start = a == 0 && lo == 0 && n < N;
        let at_end = b.wrapping_add(1) == n && hi == extras.len().wrapping_add(1);
        let ends = match (at_start, at_end) {
            (false, false) => Ends::Closed,
            (true, false) => Ends::OpenStart,
            (false, true) => Ends::OpenEnd,
            (true, true) => Ends::Open,
        };
        // From S_a itself (lo = 0, E_0 = S_a = 0) the differences are w and E_hi as they
        // are (both already within ±2^30): no subtraction.
        let (wl, dl) = if lo == 0 {
            (w, eh)
        } else {
            (sub(w, el), sub(eh, el))
        };
        let seg = chord_dist(wl, dl, slot_b.tangent_raw(), ends);
        // |S_a| ≤ 2^40 (window positions are saturated to ±POS_LIMIT), |E_lo| ≤ 2^30:
        // the sum cannot wrap.
        let base = Xy::new(
            sa.x.wrapping_add(i64::from(el.x)),
            sa.y.wrapping_add(i64::from(el.y)),
        );
        let u = u_at_foot(slot_a.u_raw(), slot_b.u_raw(), lo, extras.len(), &seg);
        Some(finish(base, seg, b, lo, u, steps, saturated))
    }

    /// The newest ordinary point (the reference) — for the tangent baseline.
    pub fn reference(&self) -> Option<&OrdinaryPoint> {
        self.newest()
    }
}

/// u at the foot: u_a + (u_b − u_a)·(lo + t)/(h + 1), t = along/len of the final
/// chord; the fraction in Q16 by one 32-bit division (`udiv` on a Cortex-M4).
#[inline(always)]
pub(crate) fn u_at_foot(u_a: i64, u_b: i64, lo: usize, h: usize, seg: &SegDist) -> i64 {
    let n = (h.min(usize::from(u16::MAX)) as u32).wrapping_add(1);
    let lo = lo.min(usize::from(u16::MAX)) as u32;
    // t_q30 clamped to [0, 2^30] (chord_dist already keeps it there).
    let t_q16 = u32::try_from(seg.t_q30.max(0))
        .unwrap_or(u32::MAX)
        .min(1 << 30)
        >> 14;
    let frac = lo
        .wrapping_shl(16)
        .saturating_add(t_q16)
        .checked_div(n)
        .unwrap_or(0)
        .min(1 << 16);
    let f = i64::from(frac);
    // (Δu·frac + 2^15) >> 16. A segment's Δu is far below 2^46 (ΔS ≤ 65.5 mm per
    // period, |r′| ≥ 1/16: Δu < 2^20 µm = 2^52 in Q32 at the very worst; 2^38 at 50 µm):
    // then Δu·frac < 2^62, one 64×32-bit product. Otherwise without an i128:
    // Δu = Δu_h·2^16 + Δu_l, exact (|Δu| ≤ 2^62 after the clamp: Δu_h·frac ≤ 2^62,
    // Δu_l·frac < 2^33). Both forms give the same value.
    let d = u_b.wrapping_sub(u_a);
    // |d| < 2^46, and the subtraction did not wrap (the sign of d is that of u_b − u_a).
    let d_fits = d.wrapping_add(1 << 46) as u64 >> 47 == 0;
    let du_f = if d_fits && (u_b >= u_a) == (d >= 0) {
        d.wrapping_mul(f).wrapping_add(1 << 15) >> 16
    } else {
        let du = u_b.saturating_sub(u_a).clamp(-(1 << 62), 1 << 62);
        let hi = (du >> 16).wrapping_mul(f);
        let lo = (du & 0xFFFF).wrapping_mul(f).wrapping_add(1 << 15) >> 16;
        hi.wrapping_add(lo)
    };
    u_a.saturating_add(du_f)
}

/// Packs a segment distance (foot relative to `base`) into an estimate.
#[inline(always)]
pub(crate) fn finish(
    base: Xy<i64>,
    seg: SegDist,
    b: usize,
    sub_chord: usize,
    u_foot: i64,
    steps: u8,
    saturated: bool,
) -> ContourEstimate {
    ContourEstimate {
        eps_um: RelUm::from_bits(clamp_to_i32(seg.eps, i32::MAX)),
        // |base| ≤ 2^40 + 2^30 (a window position plus an extra point), |foot| ≤ 2^30:
        // the sum cannot wrap.
        foot: Xy::new(
            PosFine::from_bits(base.x.wrapping_add(i64::from(seg.foot.x))),
            PosFine::from_bits(base.y.wrapping_add(i64::from(seg.foot.y))),
        ),
        tangent: seg.unit.map(UnitQ30::from_bits),
        segment: b.min(usize::from(u16::MAX)) as u16,
        sub_chord: sub_chord.min(usize::from(u16::MAX)) as u16,
        u_foot: Param::from_bits(u_foot),
        bisection_steps: steps,
        saturated,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn u_at_foot_split_product_is_exact() {
        let seg = |t: i64| SegDist {
            dist: 0,
            eps: 0,
            foot: Xy::new(0, 0),
            unit: Xy::new(0, 0),
            along: 0,
            len: 0,
            t_q30: t,
        };
        for (ua, ub) in [
            (0i64, 200 << 32),
            (-5 << 40, 7 << 40),
            (1 << 50, -(1 << 50)),
            (3, 3),
            ((1 << 46) - 1, 0),
            (0, (1 << 46) - 1),
            (0, 1 << 46),
            (i64::MIN + 5, i64::MAX),
        ] {
            for (lo, h, t) in [
                (0usize, 0usize, 0i64),
                (0, 0, 1 << 29),
                (3, 7, 12345),
                (63, 63, 1 << 30),
                (2, 4, -7),
                (1, 1, (1 << 30) + 9),
                (1, 1, 1 << 40),
            ] {
                let s = seg(t);
                let n = (h as i64) + 1;
                let frac = ((((lo as i64) << 16) + ((t.clamp(0, 1 << 30)) >> 14)) / n).min(1 << 16);
                let du = i128::from(ub)
                    .saturating_sub(i128::from(ua))
                    .clamp(-(1 << 62), 1 << 62)
                    .clamp(i128::from(i64::MIN), i128::from(i64::MAX));
                let exact = (i128::from(ua) + ((du * i128::from(frac) + (1 << 15)) >> 16))
                    .clamp(i128::from(i64::MIN), i128::from(i64::MAX))
                    as i64;
                assert_eq!(
                    u_at_foot(ua, ub, lo, h, &s),
                    exact,
                    "{ua} {ub} {lo} {h} {t}"
                );
            }
        }
    }

    #[test]
    fn bisection_bound_table() {
        let cases = [
            (0, 0),
            (1, 1),
            (2, 2),
            (3, 2),
            (4, 3),
            (7, 3),
            (8, 4),
            (63, 6),
            (64, 7),
        ];
        for (h, s) in cases {
            assert_eq!(max_bisection_steps(h), s, "h={h}");
        }
    }

    #[test]
    fn bisection_finds_the_bracketing_chord_on_a_line() {
        // 9 extra points every 10 µm along +x; P above x = 47 µm.
        let um = 4096;
        let extras: [Xy<i32>; 9] = core::array::from_fn(|k| Xy::new((k as i32 + 1) * 10 * um, 0));
        let d = Xy::new(100 * um, 0);
        let (lo, hi, steps) = bisect(Xy::new(47 * um, 3 * um), d, &extras);
        assert_eq!((lo, hi), (4, 5));
        assert!(u32::from(steps) <= max_bisection_steps(9));
        // Before the start and beyond the end.
        assert_eq!(bisect(Xy::new(-5 * um, 0), d, &extras).0, 0);
        assert_eq!(bisect(Xy::new(500 * um, 0), d, &extras).1, 10);
    }

    /// 16 points on a circle of radius 50 mm (CCW, every 50 µm from angle 0, with their
    /// tangents) in a window of capacity `N`.
    fn arc_window<const N: usize>(r: f64, step: f64) -> ContourWindow<N, 4> {
        let mut w = ContourWindow::new();
        for k in 0..16 {
            let a = f64::from(k) * step;
            w.push(
                OrdinaryPoint {
                    pos: Xy::new(
                        PosFine::from_num(r * a.cos()),
                        PosFine::from_num(r * a.sin()),
                    ),
                    tangent: Xy::new(UnitQ30::from_num(-a.sin()), UnitQ30::from_num(a.cos())),
                    u: crate::contour::Param::from_num(k),
                },
                &[],
            );
        }
        w
    }

    /// P ahead of the newest point, or behind the path's start in a window not yet full,
    /// is measured to the line of the end chord, within 0.03 µm of the exact distance to
    /// the circle (measured 0.014 µm 20 µm ahead: the line is the chord's, not the
    /// tangent's) — not to the end point (which would report the 20–30 µm lead as the
    /// error). Behind the oldest point of a full window it stays the distance to that
    /// point.
    #[test]
    fn points_beyond_the_window_ends_measure_to_the_path_not_the_end_point() {
        let r = 50_000.0f64;
        let step = 50.0 / r;
        let w = arc_window::<32>(r, step);
        // (angle past the end or before the start, radial offset µm; > 0 outward = right
        // of a CCW path, i.e. ε > 0).
        let a_end = 15.0 * step;
        for (a, off) in [
            (a_end + 20.0 / r, 3.0),
            (a_end + 20.0 / r, -2.0),
            (-20.0 / r, 3.0),
            (-30.0 / r, -1.5),
        ] {
            let p = Xy::new(
                PosFine::from_num((r + off) * a.cos()),
                PosFine::from_num((r + off) * a.sin()),
            );
            let e = w.estimate_fine(p).unwrap();
            let eps = e.eps_um.to_num::<f64>();
            assert!(
                (eps - off).abs() < 0.03,
                "angle {a}: ε {eps} vs exact {off}"
            );
        }
        // Full window (capacity 16): 20 µm behind the oldest point, 3 µm out: √(20² + 3²).
        let full = arc_window::<16>(r, step);
        let a = -20.0 / r;
        let p = Xy::new(
            PosFine::from_num((r + 3.0) * a.cos()),
            PosFine::from_num((r + 3.0) * a.sin()),
        );
        let eps = full.estimate_fine(p).unwrap().eps_um.to_num::<f64>();
        assert!((eps - 409.0f64.sqrt()).abs() < 0.03, "full window: ε {eps}");
        // Ahead of the newest point the full window is open as well.
        let a = a_end + 20.0 / r;
        let p = Xy::new(
            PosFine::from_num((r + 3.0) * a.cos()),
            PosFine::from_num((r + 3.0) * a.sin()),
        );
        let eps = full.estimate_fine(p).unwrap().eps_um.to_num::<f64>();
        assert!((eps - 3.0).abs() < 0.03, "full window ahead: ε {eps}");
    }
}
