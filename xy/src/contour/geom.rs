//! Plane geometry on relative vectors in Q20.12 µm (`i32`): the distance from a point
//! to a segment, its foot point and its sign.
//!
//! Inputs are saturated to ±2^30 LSB (±262 mm, [`super::window`]), so every product of
//! two components fits an `i64` exactly and sums of two products saturate harmlessly.

use super::Xy;
use hydra_core::fixed_point::{
    clamp_rel, clamp_to_i32, mul_shr_round_i64, normalize, shr_round_i64, sqrt_round_u64,
};

/// `a − b`, saturated to ±`REL_LIMIT` (2^30 LSB).
#[inline(always)]
pub(crate) fn sub(a: Xy<i32>, b: Xy<i32>) -> Xy<i32> {
    Xy::new(
        clamp_rel(i64::from(a.x).wrapping_sub(i64::from(b.x))),
        clamp_rel(i64::from(a.y).wrapping_sub(i64::from(b.y))),
    )
}

/// `a − b` of two absolute Q52.12 positions as a relative vector, saturated; the flag
/// says whether it saturated. For positions of the window or an estimated point (both
/// saturated to ±`POS_LIMIT` = 2^40 LSB, so the `i64` difference is exact).
#[inline(always)]
pub(crate) fn rel(a: Xy<i64>, b: Xy<i64>) -> (Xy<i32>, bool) {
    let dx = a.x.wrapping_sub(b.x);
    let dy = a.y.wrapping_sub(b.y);
    let (cx, cy) = (clamp_rel(dx), clamp_rel(dy));
    // Saturated ⇔ a component fell outside ±REL_LIMIT (the clamp changed it).
    let sat = i64::from(cx) != dx || i64::from(cy) != dy;
    (Xy::new(cx, cy), sat)
}

/// [`rel`] for any positions (a path's own points): the difference saturates first.
#[inline]
pub(crate) fn rel_sat(a: Xy<i64>, b: Xy<i64>) -> Xy<i32> {
    Xy::new(
        clamp_rel(a.x.saturating_sub(b.x)),
        clamp_rel(a.y.saturating_sub(b.y)),
    )
}

/// a · b (Q24 for Q12 inputs).
#[inline(always)]
pub(crate) fn dot(a: Xy<i32>, b: Xy<i32>) -> i64 {
    (i64::from(a.x).wrapping_mul(i64::from(b.x)))
        .saturating_add(i64::from(a.y).wrapping_mul(i64::from(b.y)))
}

/// |a|², exact (< 2^61 for saturated inputs).
#[inline]
pub(crate) fn norm2(a: Xy<i32>) -> u64 {
    (i64::from(a.x).wrapping_mul(i64::from(a.x)) as u64)
        .wrapping_add(i64::from(a.y).wrapping_mul(i64::from(a.y)) as u64)
}

/// Distance of a point from a segment A→B, with its foot point and sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SegDist {
    /// |P − F|, Q12 µm (≥ 0).
    pub dist: i64,
    /// Signed error ε: +dist when P lies to the right of A→B, −dist to the left.
    pub eps: i64,
    /// Foot point F relative to A, Q12 µm.
    pub foot: Xy<i32>,
    /// Unit direction of A→B, Q2.30 (the fallback tangent for a zero-length segment).
    pub unit: Xy<i32>,
    /// Distance of F from A along the segment, Q12 µm, in [0, len] (beyond an open
    /// end of [`chord_dist`]: below 0 or above len).
    pub along: i64,
    /// |B − A|, Q12 µm (0 for a zero-length segment).
    pub len: i64,
    /// along/len, Q2.30 in [0, 2^30] (0 for a zero-length segment).
    pub t_q30: i64,
}

/// Distance from P to the segment A→B, given w = P − A and d = B − A (Q12, saturated):
///
/// ```text
/// û = d/|d|,  along = û·w,  perp = û × w            (perp > 0: P left of A→B)
/// along ≤ 0      → F = A, dist = |w|
/// along ≥ |d|    → F = B, dist = |w − d|
/// otherwise      → F = A + û·along, dist = |perp|
/// ε = −sgn(perp)·dist                                  (ties: +)
/// ```
///
/// A zero-length segment is a point: dist = |w|, the sign from `fallback` (a unit
/// tangent, Q2.30). Cost: one normalisation (an inverse square root: 6 `umull`), at
/// most one square root (another inverse square root), about a dozen `i32×i32` products;
/// no division.
pub(crate) fn seg_dist(w: Xy<i32>, d: Xy<i32>, fallback: Xy<i32>) -> SegDist {
    chord_dist(w, d, fallback, Ends::Closed)
}

/// Which ends of a chord are open: the chord continues as a straight line beyond them
/// (the two ends of an estimation window, where the path goes on but the window holds
/// no more points).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ends {
    /// A segment: the foot is clamped to A and B.
    Closed,
    /// The line continues before A.
    OpenStart,
    /// The line continues beyond B.
    OpenEnd,
    /// Both ends open (a window of one chord).
    Open,
}

/// [`seg_dist`] with open ends: for P beyond an open end the foot is the perpendicular
/// foot on the chord's line, dist = |perp| (first order in the path's curvature: a foot
/// `a` beyond the end of a chord of length L lies off the path by about
/// ((a + L/2)² − L²/4)·κ/2 — 0.014 µm for 20 µm beyond a 50 µm chord on a 50 mm radius,
/// measured by the estimator's test). `along` may then be below 0 or above `len`;
/// `t_q30` stays clamped to [0, 1].
#[inline(always)]
pub(crate) fn chord_dist(w: Xy<i32>, d: Xy<i32>, fallback: Xy<i32>, ends: Ends) -> SegDist {
    let open_start = matches!(ends, Ends::OpenStart | Ends::Open);
    let open_end = matches!(ends, Ends::OpenEnd | Ends::Open);
    let n = normalize(i64::from(d.x), i64::from(d.y));
    let (unit, len) = match n {
        Some(u) => (Xy::new(u.ux, u.uy), u.len),
        None => (fallback, 0),
    };
    let along =
        mul_shr_round_i64(unit.x, w.x, 30).saturating_add(mul_shr_round_i64(unit.y, w.y, 30));
    let perp =
        mul_shr_round_i64(unit.x, w.y, 30).saturating_sub(mul_shr_round_i64(unit.y, w.x, 30));
    let beyond = len != 0 && ((open_start && along < 0) || (open_end && along > len));
    // |along| ≤ |w|·(1 + 10⁻⁸) < 2^31 and 0 ≤ len ≤ |d| < 2^31 (components within
    // ±2^30): both fit an i32, so the clamp to [0, len] is a 32-bit one.
    let (along32, len32) = (clamp_to_i32(along, i32::MAX), clamp_to_i32(len, i32::MAX));
    let along_t = i64::from(along32.clamp(0, len32.max(0)));
    let (dist, foot) = if beyond || (len != 0 && along > 0 && along < len) {
        // Interior (or beyond an open end): the perpendicular foot, û·along.
        (
            perp.saturating_abs(),
            Xy::new(
                clamp_rel(mul_shr_round_i64(unit.x, along32, 30)),
                clamp_rel(mul_shr_round_i64(unit.y, along32, 30)),
            ),
        )
    } else if len == 0 || along <= 0 {
        (sqrt_round_u64(norm2(w)) as i64, Xy::new(0, 0))
    } else {
        (sqrt_round_u64(norm2(sub(w, d))) as i64, d)
    };
    let along = if beyond { along } else { along_t };
    // t = along·(1/len) = along·rsq·2^(s−60) (s the normalisation shift); in Q30:
    // (along·2^s·rsq + 2^29) >> 30. For s ≥ 0 (|d| < 2^30: every chord shorter than
    // 262 mm) along·2^s ≤ len·2^s ≤ |n| + 2^(s−1) < 2^32 and the product < 2^63: one
    // `umull`, a fixed shift. Otherwise the general rounded shift (same value).
    let t_q30 = match n {
        Some(u) => {
            let s = u.exp.wrapping_add(60);
            if (0..=29).contains(&s) {
                let a = u64::from((along_t as u32).wrapping_shl(s as u32));
                let t = a.wrapping_mul(u64::from(u.rsq)).wrapping_add(1 << 29) >> 30;
                t.min(1 << 30) as i64
            } else {
                let sh = u.exp.saturating_add(30);
                let prod = along_t.wrapping_mul(i64::from(u.rsq));
                let t = if sh >= 0 {
                    prod
                } else {
                    shr_round_i64(prod, sh.unsigned_abs().min(63))
                };
                t.clamp(0, 1 << 30)
            }
        }
        None => 0,
    };
    SegDist {
        dist,
        eps: if perp > 0 { dist.wrapping_neg() } else { dist },
        foot,
        unit,
        along,
        len,
        t_q30,
    }
}

#[cfg(test)]
mod tests {
    use super::super::window::REL_LIMIT;
    use super::*;

    const UM: i32 = 4096;

    /// The previous implementation, the reference of `chord_dist_is_the_reference`.
    fn chord_dist_ref(w: Xy<i32>, d: Xy<i32>, fallback: Xy<i32>, ends: Ends) -> SegDist {
        let open_start = matches!(ends, Ends::OpenStart | Ends::Open);
        let open_end = matches!(ends, Ends::OpenEnd | Ends::Open);
        let n = normalize(i64::from(d.x), i64::from(d.y));
        let (unit, len) = match n {
            Some(u) => (Xy::new(u.ux, u.uy), u.len),
            None => (fallback, 0),
        };
        let along =
            mul_shr_round_i64(unit.x, w.x, 30).saturating_add(mul_shr_round_i64(unit.y, w.y, 30));
        let perp =
            mul_shr_round_i64(unit.x, w.y, 30).saturating_sub(mul_shr_round_i64(unit.y, w.x, 30));
        let beyond = len != 0 && ((open_start && along < 0) || (open_end && along > len));
        let (dist, foot) = if beyond {
            // |along| ≤ |w| < 2^31·√2: saturate to i32 for the foot (≥ ±262 mm: a window
            // that far behind is reported `saturated` anyway).
            let along32 = clamp_to_i32(along, i32::MAX);
            (
                perp.saturating_abs(),
                Xy::new(
                    clamp_rel(mul_shr_round_i64(unit.x, along32, 30)),
                    clamp_rel(mul_shr_round_i64(unit.y, along32, 30)),
                ),
            )
        } else if len == 0 || along <= 0 {
            (sqrt_round_u64(norm2(w)) as i64, Xy::new(0, 0))
        } else if along >= len {
            (sqrt_round_u64(norm2(sub(w, d))) as i64, d)
        } else {
            // 0 < along < |d| ≤ 2^31: û·along fits.
            let along32 = clamp_to_i32(along, i32::MAX);
            (
                perp.saturating_abs(),
                Xy::new(
                    clamp_rel(mul_shr_round_i64(unit.x, along32, 30)),
                    clamp_rel(mul_shr_round_i64(unit.y, along32, 30)),
                ),
            )
        };
        let along = if beyond {
            along
        } else {
            along.clamp(0, len.max(0))
        };
        let along_t = along.clamp(0, len.max(0));
        // t = along·(1/len) = along·rsq·2^exp; in Q30: shift by exp + 30 (≤ 0 here since
        // len < 2^32 in Q12); along, rsq < 2^32 so the product fits.
        let t_q30 = match n {
            Some(u) => {
                let sh = u.exp.saturating_add(30);
                let prod = along_t.wrapping_mul(i64::from(u.rsq));
                let t = if sh >= 0 {
                    prod
                } else {
                    shr_round_i64(prod, sh.unsigned_abs().min(63))
                };
                t.clamp(0, 1 << 30)
            }
            None => 0,
        };
        SegDist {
            dist,
            eps: if perp > 0 { dist.wrapping_neg() } else { dist },
            foot,
            unit,
            along,
            len,
            t_q30,
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(5000))]
        #[test]
        fn chord_dist_equals_the_reference(
            wx in -REL_LIMIT..=REL_LIMIT, wy in -REL_LIMIT..=REL_LIMIT,
            dx in proptest::prop_oneof![-REL_LIMIT..=REL_LIMIT, -5000i32..5000, -3i32..3],
            dy in proptest::prop_oneof![-REL_LIMIT..=REL_LIMIT, -5000i32..5000, -3i32..3],
            small in proptest::bool::ANY,
            ends in 0u8..4,
        ) {
            let (wx, wy) = if small { (wx >> 14, wy >> 14) } else { (wx, wy) };
            let ends = [Ends::Closed, Ends::OpenStart, Ends::OpenEnd, Ends::Open][usize::from(ends)];
            let (w, d, fb) = (Xy::new(wx, wy), Xy::new(dx, dy), Xy::new(1 << 30, 0));
            proptest::prop_assert_eq!(chord_dist(w, d, fb, ends), chord_dist_ref(w, d, fb, ends));
        }
    }

    #[test]
    fn interior_and_ends() {
        let d = Xy::new(100 * UM, 0);
        let fb = Xy::new(1 << 30, 0);
        // Left of a segment along +x: negative.
        let s = seg_dist(Xy::new(30 * UM, 5 * UM), d, fb);
        assert_eq!((s.dist, s.eps), (i64::from(5 * UM), -i64::from(5 * UM)));
        assert_eq!(s.foot, Xy::new(30 * UM, 0));
        // Right: positive.
        let s = seg_dist(Xy::new(30 * UM, -5 * UM), d, fb);
        assert_eq!(s.eps, i64::from(5 * UM));
        // Before A: distance to A.
        let s = seg_dist(Xy::new(-3 * UM, -4 * UM), d, fb);
        assert_eq!(
            (s.dist, s.eps, s.foot),
            (i64::from(5 * UM), i64::from(5 * UM), Xy::new(0, 0))
        );
        // Beyond B.
        let s = seg_dist(Xy::new(103 * UM, 4 * UM), d, fb);
        assert_eq!(
            (s.dist, s.eps, s.foot),
            (i64::from(5 * UM), -i64::from(5 * UM), d)
        );
        // Zero-length: a point, sign from the fallback tangent.
        let s = seg_dist(Xy::new(0, -7 * UM), Xy::new(0, 0), fb);
        assert_eq!((s.dist, s.eps), (i64::from(7 * UM), i64::from(7 * UM)));
    }

    #[test]
    fn open_ends_measure_to_the_line() {
        let d = Xy::new(100 * UM, 0);
        let fb = Xy::new(1 << 30, 0);
        // 20 µm beyond B, 3 µm right of the line: closed gives |(20, −3)|, open 3 µm.
        let w = Xy::new(120 * UM, -3 * UM);
        let closed = seg_dist(w, d, fb);
        assert!(closed.dist > i64::from(20 * UM));
        for ends in [Ends::OpenEnd, Ends::Open] {
            let s = chord_dist(w, d, fb, ends);
            assert_eq!((s.dist, s.eps), (i64::from(3 * UM), i64::from(3 * UM)));
            assert_eq!(s.foot, Xy::new(120 * UM, 0));
            assert_eq!((s.along, s.t_q30), (i64::from(120 * UM), 1 << 30));
        }
        assert_eq!(chord_dist(w, d, fb, Ends::OpenStart), closed);
        // 10 µm before A, 4 µm left.
        let w = Xy::new(-10 * UM, 4 * UM);
        for ends in [Ends::OpenStart, Ends::Open] {
            let s = chord_dist(w, d, fb, ends);
            assert_eq!((s.dist, s.eps), (i64::from(4 * UM), -i64::from(4 * UM)));
            assert_eq!(s.foot, Xy::new(-10 * UM, 0));
            assert_eq!(s.t_q30, 0);
        }
        assert_eq!(chord_dist(w, d, fb, Ends::OpenEnd), seg_dist(w, d, fb));
        // Inside, open ends change nothing.
        let w = Xy::new(40 * UM, 2 * UM);
        assert_eq!(chord_dist(w, d, fb, Ends::Open), seg_dist(w, d, fb));
    }

    #[test]
    fn saturated_inputs_do_not_overflow() {
        let big = Xy::new(REL_LIMIT, -REL_LIMIT);
        let s = seg_dist(big, Xy::new(-REL_LIMIT, REL_LIMIT), Xy::new(0, 0));
        assert!(s.dist > 0);
        let s = seg_dist(Xy::new(-REL_LIMIT, -REL_LIMIT), big, Xy::new(0, 0));
        assert!(s.dist > 0);
    }
}
