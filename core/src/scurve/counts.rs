//! Per-axis output in whole encoder counts, the remainder carried from period to period.
//!
//! The paper's PLC output whole pulses per period, each period's increment rounded on
//! its own, so the rounding errors added up over the move (its < 0.5 % position error).
//! Here the count emitted in period k is
//!
//! ```text
//! n(k)   = round((x(k) − x0) / r)          (x in µm, r = µm per count)
//! out(k) = n(k) − n(k − 1)                 (counts to emit this period)
//! ```
//!
//! which is the same as rounding each increment after adding the remainder carried from
//! the previous period: the remainder `(x(k) − x0)/r − n(k)` stays in [−½, ½] count at
//! every period, so Σ out = n(k) never drifts, and at the end of a move it is the
//! target's count exactly.
//!
//! Format: counts per `PosUm` LSB (1/256 µm) as `u64` Q16.48 (resolution 3.6e-15 count
//! per LSB: over ±8.39 m the product is exact to 2^-15 count). The product is formed
//! with [`crate::fixed_point::mulhi`] in Q.14 counts and rounded once.

use crate::fixed_point::mulhi;
use crate::units::{Counts, PosUm};

/// Smallest and largest encoder resolution accepted, µm per count.
pub const UM_PER_COUNT_RANGE: (f64, f64) = (1e-3, 1e4);

/// An encoder resolution out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CountsError {
    /// µm per count not finite or outside [`UM_PER_COUNT_RANGE`].
    Resolution,
}

impl core::fmt::Display for CountsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("encoder resolution must be finite, in 0.001 … 10000 µm per count")
    }
}

impl core::error::Error for CountsError {}

/// An encoder's scale: counts per `PosUm` LSB, Q16.48.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CountsScale {
    counts_per_lsb_q48: u64,
}

impl CountsScale {
    /// The scale of an encoder of `um_per_count` µm per count (e.g. 1.0, 0.977, 5.0).
    pub fn new(um_per_count: f64) -> Result<Self, CountsError> {
        let (lo, hi) = UM_PER_COUNT_RANGE;
        if !(um_per_count.is_finite() && um_per_count >= lo && um_per_count <= hi) {
            return Err(CountsError::Resolution);
        }
        // counts per LSB = 1 / (256·r) ≤ 3.9: < 2^50 in Q16.48.
        let m = 281_474_976_710_656.0 / (256.0 * um_per_count);
        Ok(CountsScale {
            counts_per_lsb_q48: (m + 0.5) as u64,
        })
    }
}

/// The count output of one axis: origin, scale and the count emitted so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CountsOut {
    scale: CountsScale,
    origin_lsb: i64,
    total: i64,
}

impl CountsOut {
    /// An output that counts from `origin` (count 0 there).
    pub fn new(scale: CountsScale, origin: PosUm) -> Self {
        CountsOut {
            scale,
            origin_lsb: i64::from(origin.to_bits()),
            total: 0,
        }
    }

    /// round((pos − origin) / r): the count of `pos`.
    #[inline]
    pub fn count_of(&self, pos: PosUm) -> i64 {
        // |d| < 2^33, so d·2^30 < 2^63; ⌊d·2^30·m / 2^64⌋ = d·m / 2^34 in Q.14 counts.
        let d = i64::from(pos.to_bits()).wrapping_sub(self.origin_lsb);
        let q14 = mulhi(d.wrapping_shl(30), self.scale.counts_per_lsb_q48);
        q14.wrapping_add(1 << 13).wrapping_shr(14)
    }

    /// The counts to emit this period for the new position `pos` (whole counts; the
    /// remainder is carried in the running total).
    #[inline]
    pub fn update(&mut self, pos: PosUm) -> Counts {
        let n = self.count_of(pos);
        let out = n.wrapping_sub(self.total);
        self.total = n;
        Counts(crate::fixed_point::sat_i32(out))
    }

    /// Counts emitted since the origin.
    pub fn total(&self) -> i64 {
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Cursor, LineMove, PathLimits};
    use super::*;

    #[test]
    fn bad_resolution_is_named() {
        for r in [0.0, -1.0, f64::NAN, 1e-4, 2e4] {
            assert_eq!(CountsScale::new(r), Err(CountsError::Resolution));
        }
    }

    #[test]
    fn count_of_rounds_exactly() {
        let out = CountsOut::new(CountsScale::new(1.0).unwrap(), PosUm::from_num(10));
        assert_eq!(out.count_of(PosUm::from_num(10)), 0);
        assert_eq!(out.count_of(PosUm::from_num(11.49)), 1);
        assert_eq!(out.count_of(PosUm::from_num(11.5)), 2);
        assert_eq!(out.count_of(PosUm::from_num(-3.6)), -14);
        assert_eq!(out.count_of(PosUm::MAX), 8_388_598);
    }

    /// Paper-style per-period rounding drifts; the carried remainder never does.
    #[test]
    fn remainder_carry_never_accumulates() {
        let r = 0.977; // µm per count (the patent's X–Y table encoder)
        let scale = CountsScale::new(r).unwrap();
        let from = [PosUm::from_num(0)];
        let to = [PosUm::from_num(50_000)];
        let lim = PathLimits {
            vel_um_per_s: 1500.0,
            acc_um_per_s2: 1000.0,
            jerk_um_per_s3: 1000.0,
        };
        let mv = LineMove::plan(from, to, &lim, 0.05).unwrap();
        let mut out = CountsOut::new(scale, from[0]);
        let mut c = Cursor::new();
        let (mut sum, mut naive, mut prev) = (0i64, 0i64, 0.0f64);
        let mut naive_worst = 0.0f64;
        while !c.done(mv.profile()) {
            let x = mv.next(&mut c)[0];
            sum += i64::from(out.update(x).0);
            let exact = x.to_num::<f64>() / r;
            assert!((sum as f64 - exact).abs() <= 0.5 + 1e-6);
            naive += ((exact - prev) + 0.5).floor() as i64;
            prev = exact;
            naive_worst = naive_worst.max((naive as f64 - exact).abs());
        }
        assert_eq!(sum, (50_000.0 / r + 0.5).floor() as i64);
        assert_eq!(out.total(), sum);
        // Measured: 146 counts (0.29 % of the move) for the paper-style rounding.
        assert!(
            naive_worst > 100.0,
            "per-period rounding drifts: {naive_worst}"
        );
    }
}
