//! Quadrature-encoder counts: extending a 16-bit timer counter to 32 bits, and the
//! per-tick plausibility check.
//!
//! A 16-bit counter read once per tick is extended by accumulating the wrapping
//! difference of two reads:
//!
//! ```text
//! Δ(k) = (raw(k) − raw(k−1)) mod 2^16, taken as a signed i16 ∈ [−32768, 32767]
//! count(k) = count(k−1) + Δ(k)          (wrapping in i32)
//! ```
//!
//! This is exact as long as the true count changes by less than 2^15 = 32 768 between
//! two reads (at 1 kHz and 1 µm per count: 32 m/s, far beyond any cylinder). The runtime
//! flags a step above the channel's plausible maximum (validated below 2^14 per tick) as
//! an encoder fault, so a step large enough to alias is never silently accepted unless it
//! exceeds 2^16 − 2^14 counts in one tick. A 32-bit timer's counter is already the count
//! ([`counts_from_u32`]), its two's-complement reading wraps the same way.

use crate::units::Counts;

/// Extends a 16-bit hardware counter to a 32-bit count (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Extender16 {
    last_raw: u16,
    count: i32,
}

impl Extender16 {
    /// An extender whose count starts at `count` for the raw reading `raw`.
    pub const fn new(raw: u16, count: i32) -> Self {
        Self {
            last_raw: raw,
            count,
        }
    }

    /// Takes a new raw reading and returns the extended count.
    #[inline]
    pub fn update(&mut self, raw: u16) -> Counts {
        // Reinterpreting the wrapped u16 difference as i16 is the signed step.
        let step = raw.wrapping_sub(self.last_raw) as i16;
        self.last_raw = raw;
        self.count = self.count.wrapping_add(i32::from(step));
        Counts(self.count)
    }

    /// The current extended count (without a new reading).
    pub const fn count(&self) -> Counts {
        Counts(self.count)
    }

    /// The extended count of an earlier raw value `raw` (e.g. a hardware capture of
    /// the counter at a reference edge), from the last reading: exact while the counter
    /// moved less than 32 768 counts between that value and the last reading.
    pub const fn extend_past(&self, raw: u16) -> Counts {
        let back = self.last_raw.wrapping_sub(raw) as i16;
        Counts(self.count.wrapping_sub(back as i32))
    }
}

/// A 32-bit timer's counter as a count (two's complement, wraps like the extender).
#[inline]
pub const fn counts_from_u32(raw: u32) -> Counts {
    Counts(raw as i32)
}

/// The signed step between two counts, robust to wrap-around of the 32-bit count.
#[inline]
pub const fn step(prev: Counts, now: Counts) -> i32 {
    now.0.wrapping_sub(prev.0)
}

/// Whether one tick's step is plausible: |step| ≤ `limit_counts`.
#[inline]
pub const fn plausible(step: i32, limit_counts: u32) -> bool {
    step.unsigned_abs() <= limit_counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn wraps_forward_and_backward() {
        let mut e = Extender16::new(65530, 0);
        assert_eq!(e.update(4), Counts(10)); // 65530 → 65535 → 0 → 4
        assert_eq!(e.update(65534), Counts(10 - 6)); // 4 → 65534 is −6
        assert_eq!(e.update(65534), Counts(4));
        assert_eq!(e.update(65534u16.wrapping_add(32767)), Counts(4 + 32767)); // largest forward step
        assert_eq!(e.count(), Counts(32771));
    }

    #[test]
    fn step_and_plausibility() {
        assert_eq!(step(Counts(i32::MAX), Counts(i32::MIN)), 1);
        assert_eq!(step(Counts(5), Counts(-5)), -10);
        assert!(plausible(-10, 10));
        assert!(!plausible(11, 10));
        assert!(plausible(i32::MIN, u32::MAX));
        assert!(!plausible(i32::MIN, 1 << 30));
        assert_eq!(counts_from_u32(u32::MAX), Counts(-1));
    }

    proptest! {
        /// Any motion whose per-read step stays below 2^15 is reproduced exactly
        /// (modulo 2^32) from the 16-bit readings.
        #[test]
        fn reproduces_true_count(start in any::<i32>(),
                                 steps in proptest::collection::vec(-32767i32..=32767, 1..400)) {
            let mut truth = start;
            let mut e = Extender16::new(truth as u16, truth);
            for s in steps {
                truth = truth.wrapping_add(s);
                prop_assert_eq!(e.update(truth as u16), Counts(truth));
            }
        }

        /// A 32-bit counter read through `counts_from_u32` gives the same steps as
        /// the true count.
        #[test]
        fn u32_counter_steps(start in any::<u32>(), s in -1_000_000i32..1_000_000) {
            let a = counts_from_u32(start);
            let b = counts_from_u32(start.wrapping_add(s as u32));
            prop_assert_eq!(step(a, b), s);
        }
    }

    #[test]
    fn extends_a_capture_from_the_past() {
        let mut e = Extender16::new(65_530, 1000);
        // Through the wrap: 65 530 → 20 is +26.
        assert_eq!(e.update(20), Counts(1026));
        // A capture at 65 535 (before the wrap) and one at 10 (after it).
        assert_eq!(e.extend_past(65_535), Counts(1005));
        assert_eq!(e.extend_past(10), Counts(1016));
        // A capture "after" the reading cannot happen; it extends forward all the same.
        assert_eq!(e.extend_past(25), Counts(1031));
    }
}
