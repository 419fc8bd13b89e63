//! Step 1 of the estimator: the ordinary point S_m of the window nearest to the actual
//! point P, by |P − S_k|² (each component of P − S_k saturated to ±2^30 LSB = ±262 mm).
//!
//! # Warm start
//!
//! A full scan costs N squared distances every period (64 for the X–Y tick's window).
//! But from one period to the next the
//! measured point moves by about one segment along the path, and the window by one
//! point, so the nearest point of the last call is a neighbour of this one's. The
//! window remembers the **physical slot** of the last nearest point (slots do not move
//! when the ring advances) and the search walks downhill from it:
//!
//! ```text
//! i = hint;  while d(i+1) < d(i): i += 1;   (if it did not move:) while d(i−1) < d(i): i −= 1
//! ```
//!
//! which ends at a local minimum of k ↦ |P − S_k|² after |m − hint| + 2 distances
//! (3 in steady state). It is the global minimum — the full scan's answer — whenever
//! the distance is unimodal along the window, which holds for the paths and errors a
//! contouring servo sees: on a circle of radius ρ the distance from any point to the
//! path point at angle φ from it grows monotonically with |φ| up to 180°, so a window
//! turning by less than 180° is unimodal; for a general curve the same holds for points
//! closer to the path than its radius of curvature (asserted on random circles, lines
//! and parabolas in the tests below and in `tests/tests/contour_proptest.rs`).
//!
//! **Fallback to the full scan** when there is no hint (a new or cleared window, or the
//! hinted point was overwritten as the oldest) and when the walk ends at either end of
//! the window (P ahead of the newest point, behind the oldest, or a point that jumped
//! out of the window's span: there the scan also catches a path that comes back). Where
//! a window does hold two separate local minima (a path folding back on itself within
//! the window, e.g. a hairpin tighter than the window's span), the walk keeps the one
//! the servo has been following — the branch continuity a contouring controller wants —
//! while the full scan may jump to the other branch.

use super::window::{ContourWindow, NO_HINT};
use super::Xy;
use hydra_core::fixed_point::clamp_rel;

/// |p − s|², each component saturated to ±`REL_LIMIT` (2^30) (Q24 µm², < 2^61).
#[inline(always)]
fn dist2(p: Xy<i64>, s: Xy<i64>) -> u64 {
    // Both within ±POS_LIMIT (2^40): the i64 difference is exact.
    let dx = clamp_rel(p.x.wrapping_sub(s.x));
    let dy = clamp_rel(p.y.wrapping_sub(s.y));
    // |d| ≤ 2^30 per component: i32 squares (`smull`), sum < 2^61.
    (i64::from(dx).wrapping_mul(i64::from(dx)) as u64)
        .wrapping_add(i64::from(dy).wrapping_mul(i64::from(dy)) as u64)
}

impl<const N: usize, const H: usize> ContourWindow<N, H> {
    /// |p − S_i|² for logical index `i` (`u64::MAX` if there is no such point) — the
    /// tests' reference.
    #[cfg(test)]
    fn dist2_at(&self, p: Xy<i64>, i: usize) -> u64 {
        self.slot(i).map_or(u64::MAX, |s| dist2(p, s.pos_raw()))
    }

    /// Index (0 = oldest) of the ordinary point nearest to `p` (Q52.12 raw): the warm
    /// start from the last nearest point, or the full scan (module docs). Remembers the
    /// answer for the next call. `None` if the window is empty.
    pub(crate) fn nearest_point(&self, p: Xy<i64>) -> Option<usize> {
        if self.is_empty() {
            return None;
        }
        let m = match self.hint_index() {
            Some(start) => self.nearest_walk(p, start),
            None => None,
        };
        let m = match m {
            Some(m) => m,
            None => self.nearest_scan(p)?,
        };
        self.hint
            .set(u16::try_from(self.phys(m)).unwrap_or(NO_HINT));
        Some(m)
    }

    /// The logical index of the remembered slot, if it holds a point.
    fn hint_index(&self) -> Option<usize> {
        let h = usize::from(self.hint.get());
        if h >= N {
            return None;
        }
        // Logical = (physical − head) mod N; valid below len.
        let head = self.head();
        let i = if h >= head {
            h.wrapping_sub(head)
        } else {
            h.wrapping_add(N).wrapping_sub(head)
        };
        (i < self.len()).then_some(i)
    }

    /// |p − S|² of the slot at physical index `pi` (`u64::MAX` if out of range).
    #[inline(always)]
    fn dist2_phys(&self, p: Xy<i64>, pi: usize) -> u64 {
        self.slots_ref()
            .get(pi)
            .map_or(u64::MAX, |s| dist2(p, s.pos_raw()))
    }

    /// The walk downhill from logical index `start`: the local minimum it reaches, or
    /// `None` when that is the first or the last point of the window (then scan). It
    /// steps through the ring by physical index (one wrap test per step, no logical →
    /// physical conversion); the logical index only bounds the walk.
    pub(crate) fn nearest_walk(&self, p: Xy<i64>, start: usize) -> Option<usize> {
        let last = self.len().checked_sub(1)?;
        let mut i = start.min(last);
        let mut pi = self.phys(i);
        let mut d = self.dist2_phys(p, pi);
        let mut moved = false;
        while i < last {
            let pn = if pi.wrapping_add(1) >= N {
                0
            } else {
                pi.wrapping_add(1)
            };
            let dn = self.dist2_phys(p, pn);
            if dn >= d {
                break;
            }
            (i, pi, d, moved) = (i.wrapping_add(1), pn, dn, true);
        }
        if !moved {
            while i > 0 {
                let pp = if pi == 0 {
                    N.wrapping_sub(1)
                } else {
                    pi.wrapping_sub(1)
                };
                let dp = self.dist2_phys(p, pp);
                if dp >= d {
                    break;
                }
                (i, pi, d) = (i.wrapping_sub(1), pp, dp);
            }
        }
        (i != 0 && i != last).then_some(i)
    }

    /// The full scan: one pass over the slots in storage order, the first strict
    /// minimum. `None` if empty.
    pub(crate) fn nearest_scan(&self, p: Xy<i64>) -> Option<usize> {
        let mut best = (u64::MAX, None);
        for (k, s) in self.stored_pos_raw().enumerate() {
            let d2 = dist2(p, s);
            if d2 < best.0 {
                best = (d2, Some(k));
            }
        }
        // Logical index = (physical − head) mod N.
        let head = self.head();
        best.1.map(|k| {
            if k >= head {
                k.wrapping_sub(head)
            } else {
                k.wrapping_add(N).wrapping_sub(head)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::window::OrdinaryPoint;
    use super::super::{PosFine, UnitQ30};
    use super::*;
    use proptest::prelude::*;

    const Q12: f64 = 4096.0;

    fn fine(x: f64, y: f64) -> Xy<i64> {
        Xy::new((x * Q12).round() as i64, (y * Q12).round() as i64)
    }

    fn point(x: f64, y: f64) -> OrdinaryPoint {
        let f = fine(x, y);
        OrdinaryPoint {
            pos: Xy::new(PosFine::from_bits(f.x), PosFine::from_bits(f.y)),
            tangent: Xy::new(UnitQ30::ZERO, UnitQ30::ZERO),
            ..OrdinaryPoint::default()
        }
    }

    /// A 16-point window of `pushed` points every `step_um` along a circle of radius
    /// `r_um` (`dir` = ±1: turning left or right), starting at angle `a0`.
    fn circle_window(
        r_um: f64,
        step_um: f64,
        a0: f64,
        dir: f64,
        pushed: usize,
    ) -> ContourWindow<16, 4> {
        let mut w = ContourWindow::new();
        for k in 0..pushed {
            let a = a0 + dir * k as f64 * step_um / r_um;
            w.push(point(r_um * a.cos(), r_um * a.sin()), &[]);
        }
        w
    }

    fn d2_of(w: &ContourWindow<16, 4>, p: Xy<i64>, i: usize) -> u64 {
        w.dist2_at(p, i)
    }

    #[test]
    fn steady_state_walk_takes_one_step() {
        // Points every 50 µm on a line, P follows 3 points behind the newest.
        let mut w: ContourWindow<16, 4> = ContourWindow::new();
        for k in 0..40 {
            w.push(point(50.0 * f64::from(k), 0.0), &[]);
            if k >= 3 {
                let p = fine(50.0 * f64::from(k - 3) + 1.0, 2.0);
                let m = w.nearest_point(p).unwrap();
                assert_eq!(m, w.len() - 4);
                assert_eq!(Some(m), w.nearest_scan(p));
            }
        }
        // The hint survives the ring's advance: it names a slot, not a logical index.
        assert_ne!(w.hint.get(), NO_HINT);
        w.clear();
        assert_eq!(w.hint.get(), NO_HINT);
        assert_eq!(w.nearest_point(fine(0.0, 0.0)), None);
    }

    #[test]
    fn walk_ending_at_an_edge_falls_back_to_the_scan() {
        // A hairpin: out along y = 0, back along y = 100 µm. P next to the returning
        // branch's newest point; the walk from the outgoing branch stops at the window's
        // first point, so the scan decides.
        let mut w: ContourWindow<16, 4> = ContourWindow::new();
        for k in 0..8 {
            w.push(point(50.0 * f64::from(k), 0.0), &[]);
        }
        for k in (0..8).rev() {
            w.push(point(50.0 * f64::from(k), 100.0), &[]);
        }
        let p = fine(2.0, 99.0);
        assert_eq!(w.nearest_walk(p, 3), None);
        w.hint.set(3);
        assert_eq!(w.nearest_point(p), Some(15));
        // From the returning branch the walk finds its local minimum, the followed branch.
        let q = fine(151.0, 60.0);
        assert_eq!(w.nearest_walk(q, 11), Some(12));
        assert_eq!(w.nearest_scan(q), Some(12));
    }

    #[test]
    fn overwritten_hint_is_dropped() {
        let mut w: ContourWindow<4, 0> = ContourWindow::new();
        for k in 0..4 {
            w.push(point(10.0 * f64::from(k), 0.0), &[]);
        }
        assert_eq!(w.nearest_point(fine(0.0, 1.0)), Some(0));
        assert_eq!(w.hint.get(), 0);
        w.push(point(40.0, 0.0), &[]);
        assert_eq!(w.hint.get(), NO_HINT);
        assert_eq!(w.nearest_point(fine(29.0, 1.0)), Some(2));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// The warm start finds the full scan's nearest distance on circles (and
        /// nearly straight paths at large radii) turning by less than 180° over the
        /// window, for points up to half the radius off the path, anywhere along the
        /// window and beyond its ends, from any hint.
        #[test]
        fn warm_start_equals_full_scan(
            r_um in 2_000.0f64..5_000_000.0,
            step_um in 5.0f64..1_500.0,
            a0 in 0.0f64..std::f64::consts::TAU,
            left in any::<bool>(),
            pushed in 1usize..40,
            at in -0.2f64..1.2,
            off in -1.0f64..1.0,
            hint_at in 0.0f64..1.0,
            hint_off in -1.0f64..1.0,
        ) {
            // The window (16 points, 15 steps) turns by less than 170°.
            prop_assume!(15.0 * step_um / r_um < 2.96);
            let dir = if left { 1.0 } else { -1.0 };
            let w = circle_window(r_um, step_um, a0, dir, pushed);
            let first = pushed.saturating_sub(16) as f64;
            let span = (w.len() - 1) as f64;
            let on = |t: f64, e: f64| {
                let a = a0 + dir * (first + t * span) * step_um / r_um;
                let rr = r_um + e * (r_um / 2.0).min(500.0);
                fine(rr * a.cos(), rr * a.sin())
            };
            // Set a hint from another point, then compare.
            let _ = w.nearest_point(on(hint_at, hint_off));
            let p = on(at, off);
            let warm = w.nearest_point(p).unwrap();
            let scan = w.nearest_scan(p).unwrap();
            prop_assert_eq!(d2_of(&w, p, warm), d2_of(&w, p, scan));
        }

        /// On arbitrary windows and points (no shape assumed) the answer is a point of
        /// the window and at least a local minimum of the distance; no panic.
        #[test]
        fn walk_is_a_local_minimum_on_any_window(
            pts in proptest::collection::vec((-1e6f64..1e6, -1e6f64..1e6), 1..30),
            p in (-2e6f64..2e6, -2e6f64..2e6),
            hint in 0u16..20,
        ) {
            let mut w: ContourWindow<16, 4> = ContourWindow::new();
            for &(x, y) in &pts {
                w.push(point(x, y), &[]);
            }
            w.hint.set(hint);
            let p = fine(p.0, p.1);
            let m = w.nearest_point(p).unwrap();
            prop_assert!(m < w.len());
            let d = d2_of(&w, p, m);
            if m > 0 { prop_assert!(d <= d2_of(&w, p, m - 1)); }
            if m + 1 < w.len() { prop_assert!(d <= d2_of(&w, p, m + 1)); }
        }
    }
}
