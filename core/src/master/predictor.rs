//! The paper's master predictor (SPEC §A eq. 4), in difference form.
//!
//! ```text
//! θ̂(k+1) = θ(k) + [θ(k) − θ(k−1)] + ½·([θ(k) − θ(k−1)] − [θ(k−1) − θ(k−2)])
//! ```
//!
//! The backward difference θ(k) − θ(k−1) estimates the speed half a period late, so on
//! quadratic motion eq. 4 is short by exactly ½·θ̈·T² (the seed's O(Δt²·θ̈) term).
//! [`PredictorKind::Quadratic`] removes it, θ̂(k+1) = θ(k) + d1 + (d1 − d2) =
//! 3θ(k) − 3θ(k−1) + θ(k−2), exact on quadratic motion but with a larger noise gain
//! (√19 ≈ 4.4 against √(6.25+4+0.25) ≈ 3.2 counts per count of measurement noise).
//! Computed on differences so a large absolute θ never overflows; all quantities are
//! [`Master`] (`I48F16`, master counts). The ½ is an arithmetic shift (rounds toward −∞,
//! an error ≤ 2^-17 count).

use super::MasterEstimate;
use crate::fixed_point::mul64_shr_floor_sat;
use crate::units::{Master, MasterRate};

/// Which 3-point extrapolation the predictor uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PredictorKind {
    /// SPEC §A eq. 4 as printed: θ(k) + d1 + ½(d1 − d2).
    #[default]
    Eq4,
    /// Exact quadratic extrapolation: θ(k) + d1 + (d1 − d2).
    Quadratic,
}

/// Three-sample history and the eq. 4 prediction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Predictor {
    /// The extrapolation used once three samples exist.
    pub kind: PredictorKind,
    /// θ(k), θ(k−1), θ(k−2) as raw `I48F16` bits.
    hist: [i64; 3],
    /// Samples seen, saturating at 3.
    filled: u8,
    /// θ̂(k+1) from `hist`, raw `I48F16` (formed once per push).
    next: i64,
}

impl Predictor {
    /// An empty predictor of the given kind.
    pub const fn new(kind: PredictorKind) -> Self {
        Self {
            kind,
            hist: [0; 3],
            filled: 0,
            next: 0,
        }
    }
}

impl Predictor {
    /// Pushes θ(k) and returns θ̂(k+1). Until three samples exist it falls back to the
    /// lower-order forms (hold, then linear extrapolation).
    #[inline]
    pub fn update(&mut self, theta: Master) -> Master {
        self.push(theta.to_bits());
        self.predict()
    }

    /// Shifts θ(k) (raw) into the history and forms θ̂(k+1).
    #[inline(always)]
    fn push(&mut self, m: i64) {
        let [h0, h1, _] = self.hist;
        self.hist = [m, h0, h1];
        if self.filled < 3 {
            self.filled = self.filled.saturating_add(1);
        }
        self.next = self.extrapolate();
    }

    /// Pushes θ(k) when the predictor is the follower's only master estimate (every axis
    /// in `Paper` mode): returns whether θ(k) is 2^15 counts or more from the
    /// prediction θ̂(k) made a tick earlier (a master jump, as the tracking filter
    /// reports one), and the direction of motion, the sign of θ(k) − θ(k−1) (0 until two
    /// samples exist).
    #[inline]
    pub fn observe(&mut self, theta: Master) -> (bool, i8) {
        let m = theta.to_bits();
        // θ(k) − θ̂(k) modulo 2^64; a jump when it does not fit an i32 (2^15 counts), as
        // in the tracking filter.
        let residual = m.wrapping_sub(self.next);
        let jump = self.filled > 0 && (residual >> 32) as i32 != (residual as i32) >> 31;
        let dir = if self.filled == 0 {
            0
        } else {
            match m.wrapping_sub(self.hist[0]) {
                d if d > 0 => 1,
                d if d < 0 => -1,
                _ => 0,
            }
        };
        self.push(m);
        (jump, dir)
    }

    /// The master now and its speed and acceleration from the stored differences:
    /// θ(k), [θ(k) − θ(k−1)]/T and [θ(k) − 2θ(k−1) + θ(k−2)]/T² (0 until the samples
    /// exist), for telemetry. `tps_q16` is ticks per second, Q16.
    pub fn estimate(&self, tps_q16: i32) -> MasterEstimate {
        let [t0, t1, t2] = self.hist;
        let d1 = if self.filled >= 2 {
            t0.wrapping_sub(t1)
        } else {
            0
        };
        let dd = if self.filled >= 3 {
            d1.wrapping_sub(t1.wrapping_sub(t2))
        } else {
            0
        };
        let tps = i64::from(tps_q16);
        MasterEstimate {
            pos: Master::from_bits(t0),
            // counts/tick (Q16) · ticks/s (Q16) >> 16 = counts/s (Q16); twice for /T².
            rate_per_s: MasterRate::from_bits(mul64_shr_floor_sat(d1, tps, 16)),
            acc_per_s2: MasterRate::from_bits(mul64_shr_floor_sat(
                mul64_shr_floor_sat(dd, tps, 16),
                tps,
                16,
            )),
        }
    }

    /// θ̂(k+1), the prediction formed at the last push (θ(k) itself before any push).
    #[inline]
    pub fn predict(&self) -> Master {
        Master::from_bits(self.next)
    }

    /// θ̂(k+1) from the stored history (with `kind`), modulo 2^64 raw like the master
    /// filter ([`crate::master::MasterFilter::update`]): the differences of a counter
    /// that wraps are its true increments.
    #[inline(always)]
    fn extrapolate(&self) -> i64 {
        let [t0, t1, t2] = self.hist;
        let d1 = t0.wrapping_sub(t1);
        let d2 = t1.wrapping_sub(t2);
        match self.filled {
            0 | 1 => t0,
            2 => t0.wrapping_add(d1),
            _ => {
                let dd = d1.wrapping_sub(d2);
                let curv = match self.kind {
                    PredictorKind::Eq4 => dd >> 1,
                    PredictorKind::Quadratic => dd,
                };
                t0.wrapping_add(d1).wrapping_add(curv)
            }
        }
    }

    /// Clears the history (after a master fault or a new table).
    pub fn reset(&mut self) {
        *self = Self::new(self.kind);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn warms_up_then_second_order() {
        let mut p = Predictor::default();
        assert_eq!(p.update(Master::from_num(10)), Master::from_num(10));
        assert_eq!(p.update(Master::from_num(12)), Master::from_num(14));
        // 10, 12, 16: d1 = 4, d2 = 2 → 16 + 4 + 1 = 21
        assert_eq!(p.update(Master::from_num(16)), Master::from_num(21));
    }

    /// `observe` pushes like `update`, reports a measurement more than 2^14 counts from
    /// the prediction as a jump, and gives the sign of the last difference.
    #[test]
    fn observe_reports_jumps_and_direction() {
        let mut p = Predictor::default();
        assert_eq!(p.observe(Master::from_num(10)), (false, 0));
        assert_eq!(p.observe(Master::from_num(12)), (false, 1));
        assert_eq!(p.predict(), Master::from_num(14));
        assert_eq!(p.observe(Master::from_num(16)), (false, 1));
        assert_eq!(p.predict(), Master::from_num(21));
        // 21 predicted: 2^15 counts less 2^-16 above it is the largest accepted, 2^15 a jump.
        let mut q = p;
        let edge = Master::from_num(21 + 32_768) - Master::DELTA;
        assert_eq!(q.observe(edge), (false, 1));
        assert_eq!(p.observe(Master::from_num(21 + 32_768)), (true, 1));
        assert_eq!(p.observe(Master::from_num(0)), (true, -1));
    }

    /// The telemetry estimate: position, speed and acceleration from the differences.
    #[test]
    fn estimate_from_the_differences() {
        let mut p = Predictor::default();
        let tps = 1000 << 16; // 1 kHz
        for k in 0..3i64 {
            p.observe(Master::from_num(100 + 3 * k + k * k));
        }
        // 100, 104, 110: d1 = 6 counts/tick, dd = 2 counts/tick².
        let e = p.estimate(tps);
        assert_eq!(e.pos, Master::from_num(110));
        assert_eq!(e.rate_per_s, MasterRate::from_num(6000));
        assert_eq!(e.acc_per_s2, MasterRate::from_num(2_000_000));
    }

    proptest! {
        /// θ(k) = a + b·k + c·k² (c a multiple of 2^-15, so ½·Δ² is exact): the
        /// quadratic form predicts θ(k+1) exactly; eq. 4 is short by exactly ½·Δ²θ = c.
        #[test]
        fn exact_on_quadratic_motion(a in -1_000_000_000i64..1_000_000_000, b in -100_000i64..100_000,
                                     c in -20_000i64..20_000, k0 in 0i64..1000) {
            let theta = |k: i64| Master::from_bits((a << 16) + (b << 16) * k + (c * 2) * k * k);
            let mut q = Predictor::new(PredictorKind::Quadratic);
            let mut p = Predictor::new(PredictorKind::Eq4);
            for k in k0..k0 + 2 {
                q.update(theta(k));
                p.update(theta(k));
            }
            prop_assert_eq!(q.update(theta(k0 + 2)), theta(k0 + 3));
            let short = theta(k0 + 3).to_bits() - p.update(theta(k0 + 2)).to_bits();
            prop_assert_eq!(short, c * 2);
        }

        #[test]
        fn never_panics(xs in proptest::collection::vec(any::<i64>(), 1..10), tps in any::<i32>()) {
            let mut p = Predictor::default();
            let mut o = Predictor::default();
            for x in xs {
                let _ = p.update(Master::from_bits(x));
                let _ = o.observe(Master::from_bits(x));
                prop_assert_eq!(o.predict(), p.predict());
                let _ = o.estimate(tps);
            }
        }
    }
}
