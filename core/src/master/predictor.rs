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

use crate::units::Master;

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
}

impl Predictor {
    /// An empty predictor of the given kind.
    pub const fn new(kind: PredictorKind) -> Self {
        Self {
            kind,
            hist: [0; 3],
            filled: 0,
        }
    }
}

impl Predictor {
    /// Pushes θ(k) and returns θ̂(k+1). Until three samples exist it falls back to the
    /// lower-order forms (hold, then linear extrapolation).
    #[inline]
    pub fn update(&mut self, theta: Master) -> Master {
        let [h0, h1, _] = self.hist;
        self.hist = [theta.to_bits(), h0, h1];
        if self.filled < 3 {
            self.filled = self.filled.saturating_add(1);
        }
        self.predict()
    }

    /// θ̂(k+1) from the stored history, modulo 2^64 raw like the master filter
    /// ([`crate::master::MasterFilter::update`]): the differences of a counter that
    /// wraps are its true increments.
    #[inline]
    pub fn predict(&self) -> Master {
        let [t0, t1, t2] = self.hist;
        let d1 = t0.wrapping_sub(t1);
        let d2 = t1.wrapping_sub(t2);
        let next = match self.filled {
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
        };
        Master::from_bits(next)
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
        fn never_panics(xs in proptest::collection::vec(any::<i64>(), 1..10)) {
            let mut p = Predictor::default();
            for x in xs { let _ = p.update(Master::from_bits(x)); }
        }
    }
}
