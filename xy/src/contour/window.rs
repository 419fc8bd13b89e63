//! The fixed-capacity window of interpolation points the estimator searches.
//!
//! It keeps the last `N` ordinary points S (the motion commands, absolute, Q52.12 µm)
//! and, for each segment (S_{k−1}, S_k), up to `H` extra points E_1 … E_h between them,
//! stored relative to S_{k−1} in Q20.12 µm (`i32`). Extra points are only ever used for
//! estimation, never as motion commands. Pushing into a full window overwrites the
//! oldest ordinary point (a ring buffer: O(1), no allocation).
//!
//! Memory: `N · (40 + 8·H) + 16` bytes on the Cortex-M4 (+ 24 on a 64-bit host)
//! (`ContourWindow<16, 63>`: 8.5 KiB).
//!
//! Every relative vector the estimator forms (extra points, chords, P − S) is saturated
//! to ±2^30 LSB = ±262 mm, so a difference of two of them fits an `i32` and a sum of two
//! `i32·i32` products is bounded; chords are never that long (the interpolator caps one
//! tick's advance at 65.5 mm) and a point further than that from the path is flagged
//! [`super::ContourEstimate::saturated`].

use core::cell::Cell;

use super::{Param, PosFine, RelUm, UnitQ30, Xy};
use hydra_core::fixed_point::clamp_to_i32;

/// Largest |relative coordinate| used by the estimator, raw Q20.12 (262 mm).
pub(crate) const REL_LIMIT: i32 = 1 << 30;

/// Largest |absolute coordinate| the window stores and the estimator takes, raw Q52.12
/// (2^28 µm = 268 m, far beyond the ±8.388 m of a validated path): positions are
/// saturated to it, so the difference of two of them is an exact `i64` (no saturating
/// subtraction in the estimator's inner loops).
pub(crate) const POS_LIMIT: i64 = 1 << 40;

/// Saturates an absolute raw position to ±[`POS_LIMIT`]: one unsigned range test per
/// component on the common path (the saturating branch out of line, so that the
/// compiler does not turn the test into a branch-free 64-bit clamp).
#[inline(always)]
pub(crate) fn clamp_pos(p: Xy<i64>) -> Xy<i64> {
    p.map(|v| {
        if (v.wrapping_add(POS_LIMIT) as u64) <= (2 * POS_LIMIT) as u64 {
            v
        } else {
            clamp_pos_out_of_range(v)
        }
    })
}

/// The saturating branch of [`clamp_pos`].
#[cold]
#[inline(never)]
fn clamp_pos_out_of_range(v: i64) -> i64 {
    v.clamp(-POS_LIMIT, POS_LIMIT)
}

/// An ordinary interpolation point (a motion command) as stored in the window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OrdinaryPoint {
    /// Position, µm.
    pub pos: Xy<PosFine>,
    /// Unit tangent (direction of travel) at the point, Q2.30.
    pub tangent: Xy<UnitQ30>,
    /// Path parameter of the point.
    pub u: Param,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Slot<const H: usize> {
    point: OrdinaryPoint,
    /// Extra points of the segment ending here, relative to the previous ordinary point.
    n_extra: u16,
    extra: [Xy<i32>; H],
}

impl<const H: usize> Slot<H> {
    /// Raw position (Q52.12).
    #[inline(always)]
    pub(crate) fn pos_raw(&self) -> Xy<i64> {
        self.point.pos.map(PosFine::to_bits)
    }

    /// Raw unit tangent (Q2.30).
    #[inline(always)]
    pub(crate) fn tangent_raw(&self) -> Xy<i32> {
        self.point.tangent.map(UnitQ30::to_bits)
    }

    /// Raw path parameter.
    #[inline(always)]
    pub(crate) fn u_raw(&self) -> i64 {
        self.point.u.to_bits()
    }

    /// The extra points of the segment ending here (relative to the previous point).
    #[inline(always)]
    pub(crate) fn extras(&self) -> &[Xy<i32>] {
        self.extra.get(..usize::from(self.n_extra)).unwrap_or(&[])
    }

    const EMPTY: Self = Slot {
        point: OrdinaryPoint {
            pos: Xy {
                x: PosFine::ZERO,
                y: PosFine::ZERO,
            },
            tangent: Xy {
                x: UnitQ30::ZERO,
                y: UnitQ30::ZERO,
            },
            u: Param::ZERO,
        },
        n_extra: 0,
        extra: [Xy { x: 0, y: 0 }; H],
    };
}

/// The last `N` ordinary points and up to `H` extra points per segment between them.
///
/// `N ≥ 2` for any estimate beyond the distance to a single point; `H ≤ 65 535`.
#[derive(Clone, Debug)]
pub struct ContourWindow<const N: usize, const H: usize> {
    slots: [Slot<H>; N],
    /// Physical index of the oldest point.
    head: usize,
    len: usize,
    /// Warm start of the nearest-point search: the physical slot of the last nearest
    /// point, [`NO_HINT`] when there is none (cleared, or that point has left the window).
    /// Interior mutability so that [`ContourWindow::estimate`] can stay `&self`.
    pub(crate) hint: Cell<u16>,
}

/// The value of [`ContourWindow::hint`] meaning "no warm start: scan the window".
pub(crate) const NO_HINT: u16 = u16::MAX;

/// The window size the firmware uses: 16 ordinary points (15 segments, enough for a
/// servo lagging up to 13 periods), up to 63 extra points per segment (bisection ≤ 6
/// steps). 8.5 KiB.
pub type DefaultWindow = ContourWindow<16, 63>;

impl<const N: usize, const H: usize> Default for ContourWindow<N, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const H: usize> ContourWindow<N, H> {
    /// An empty window.
    pub const fn new() -> Self {
        Self {
            slots: [Slot::<H>::EMPTY; N],
            head: 0,
            len: 0,
            hint: Cell::new(NO_HINT),
        }
    }

    /// Capacity in ordinary points.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Capacity in extra points per segment.
    pub const fn extra_capacity(&self) -> usize {
        H
    }

    /// Number of ordinary points held.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// No point held?
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Forgets every point.
    pub fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
        self.hint.set(NO_HINT);
    }

    /// Physical slot index of logical index `i` (0 = oldest).
    pub(crate) fn phys(&self, i: usize) -> usize {
        let p = self.head.wrapping_add(i);
        if p >= N {
            p.wrapping_sub(N)
        } else {
            p
        }
    }

    /// Raw positions of the held points in storage order (the valid slots are always
    /// the first `len`: the head moves only once the ring is full), for the full scan.
    pub(crate) fn stored_pos_raw(&self) -> impl Iterator<Item = Xy<i64>> + '_ {
        self.slots
            .iter()
            .take(self.len)
            .map(|s| s.point.pos.map(PosFine::to_bits))
    }

    /// The slots in storage order (physical indices).
    #[inline(always)]
    pub(crate) fn slots_ref(&self) -> &[Slot<H>; N] {
        &self.slots
    }

    /// Physical index of the oldest point.
    pub(crate) fn head(&self) -> usize {
        self.head
    }

    /// The slot of logical index `i` (0 = oldest).
    pub(crate) fn slot(&self, i: usize) -> Option<&Slot<H>> {
        if i >= self.len {
            return None;
        }
        self.slots.get(self.phys(i))
    }

    /// Ordinary point `i` (0 = oldest, `len − 1` = newest).
    pub fn point(&self, i: usize) -> Option<&OrdinaryPoint> {
        self.slot(i).map(|s| &s.point)
    }

    /// The newest ordinary point (the current reference).
    pub fn newest(&self) -> Option<&OrdinaryPoint> {
        self.point(self.len.checked_sub(1)?)
    }

    /// Extra points of the segment (S_{i−1}, S_i), relative to S_{i−1}, Q20.12 raw. Empty
    /// for the oldest point (its predecessor has left the window).
    pub(crate) fn extras_raw(&self, i: usize) -> &[Xy<i32>] {
        if i == 0 {
            return &[];
        }
        match self.slot(i) {
            Some(s) => s.extra.get(..usize::from(s.n_extra)).unwrap_or(&[]),
            None => &[],
        }
    }

    /// Number of extra points of the segment ending at ordinary point `i`.
    pub fn extra_count(&self, i: usize) -> usize {
        self.extras_raw(i).len()
    }

    /// Extra point `j` (0-based) of the segment ending at ordinary point `i`, relative to
    /// ordinary point `i − 1`, µm.
    pub fn extra(&self, i: usize, j: usize) -> Option<Xy<RelUm>> {
        self.extras_raw(i)
            .get(j)
            .map(|e| Xy::new(RelUm::from_bits(e.x), RelUm::from_bits(e.y)))
    }

    /// Appends an ordinary point and the extra points of the segment from the previous
    /// newest point to it (relative to that previous point; at most `H` are kept, each
    /// saturated to ±262 mm; the point's position is saturated to ±268 m). Overwrites the oldest point when full. Returns the number
    /// of extra points stored.
    pub fn push(&mut self, point: OrdinaryPoint, extras: &[Xy<RelUm>]) -> usize {
        self.push_with(point, |buf| {
            let mut n = 0usize;
            for (dst, src) in buf.iter_mut().zip(extras.iter()) {
                *dst = Xy::new(
                    clamp_to_i32(i64::from(src.x.to_bits()), REL_LIMIT),
                    clamp_to_i32(i64::from(src.y.to_bits()), REL_LIMIT),
                );
                n = n.wrapping_add(1);
            }
            n
        })
    }

    /// Appends an ordinary point; `fill` writes the segment's extra points (Q20.12 raw,
    /// relative to the previous newest point, within ±2^30) into the buffer and returns
    /// how many it wrote (clamped to `H`). No copy of the extra points is made.
    pub(crate) fn push_with<F: FnOnce(&mut [Xy<i32>; H]) -> usize>(
        &mut self,
        point: OrdinaryPoint,
        fill: F,
    ) -> usize {
        if N == 0 {
            return 0;
        }
        let idx = if self.len < N {
            let i = self.phys(self.len);
            self.len = self.len.wrapping_add(1);
            i
        } else {
            let i = self.head;
            self.head = self.phys(1);
            // The oldest point is overwritten: a warm start from it would be stale.
            if usize::from(self.hint.get()) == i {
                self.hint.set(NO_HINT);
            }
            i
        };
        match self.slots.get_mut(idx) {
            Some(slot) => {
                let n = fill(&mut slot.extra).min(H).min(usize::from(u16::MAX));
                slot.n_extra = n as u16;
                slot.point = OrdinaryPoint {
                    pos: clamp_pos(point.pos.map(PosFine::to_bits)).map(PosFine::from_bits),
                    ..point
                };
                n
            }
            None => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(x: i64) -> OrdinaryPoint {
        OrdinaryPoint {
            pos: Xy::new(PosFine::from_bits(x), PosFine::ZERO),
            ..OrdinaryPoint::default()
        }
    }

    #[test]
    fn ring_keeps_the_newest() {
        let mut w: ContourWindow<3, 2> = ContourWindow::new();
        assert!(w.newest().is_none());
        let e = [Xy::new(RelUm::from_num(1), RelUm::ZERO); 5];
        for k in 0..5 {
            let n = w.push(pt(k), &e[..(k as usize).min(5)]);
            assert_eq!(n, (k as usize).min(2));
        }
        assert_eq!(w.len(), 3);
        let xs: [i64; 3] = core::array::from_fn(|i| w.point(i).unwrap().pos.x.to_bits());
        assert_eq!(xs, [2, 3, 4]);
        assert_eq!(w.extra_count(0), 0);
        assert_eq!(w.extra_count(1), 2);
        assert_eq!(w.extra(2, 1).unwrap().x, RelUm::from_num(1));
        assert!(w.extra(2, 2).is_none());
        assert!(w.point(3).is_none());
        w.clear();
        assert!(w.is_empty());
    }

    #[test]
    fn default_window_size_is_as_documented() {
        // N·(40 + 8·H) + 24 bytes on a 64-bit host (head, len, hint; + 16 on the M4).
        assert_eq!(
            core::mem::size_of::<DefaultWindow>(),
            16 * (40 + 8 * 63) + 24
        );
    }

    #[test]
    fn zero_capacity_is_harmless() {
        let mut w: ContourWindow<0, 0> = ContourWindow::new();
        assert_eq!(w.push(pt(1), &[]), 0);
        assert!(w.newest().is_none());
    }
}
