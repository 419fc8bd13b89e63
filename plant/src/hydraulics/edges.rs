//! The master encoder's timestamped edges, from the true angle: what the board's edge
//! timer captures (`hydra_core::master::EdgeEstimator`, `firmware/src/encoders.rs`).
//!
//! The encoder counts ×4 with the count the rounded position (`n = round(θ/r)`, cell
//! `[n − ½, n + ½)`); channel A is high on counts ≡ 1, 2 (mod 4), so its rising edges are
//! the boundary `4j + ½` passed upwards (the count after it `4j + 1`) and `4j + 2½`
//! passed downwards (the count after it `4j + 2`). The board captures the count and the
//! edge timer's time at every rising A edge; a tick reads the newest.
//!
//! The edge's instant is found by bisection of `θ(t)/r = boundary` inside the interval
//! (the angle is monotone between two samples of a table's master); the edge timer
//! counts `⌊t · f⌋` (wrapping at 2^32), as a timer that captures its counter.

use hydra_core::master::{EdgeCapture, EdgeReading};
use hydra_core::units::Counts;

/// The newest rising edge of channel A between two instants, for a position `pos(t)` in
/// counts (real-valued): `(t_edge, count after it)`, or `None` if the count did not
/// pass one between `t0` and `t1` (or went back and forth within the interval).
pub fn newest_rising_a(pos: impl Fn(f64) -> f64, t0: f64, t1: f64) -> Option<(f64, i64)> {
    let (c0, c1) = (pos(t0).round() as i64, pos(t1).round() as i64);
    let (latched, boundary) = if c1 > c0 {
        // The largest L ≤ c1 with L ≡ 1 (mod 4), boundary L − ½ above c0's cell.
        let l = c1 - (c1 - 1).rem_euclid(4);
        (l > c0).then_some((l, l as f64 - 0.5))?
    } else if c1 < c0 {
        // The smallest L ≥ c1 with L ≡ 2 (mod 4), boundary L + ½ below c0's cell.
        let l = c1 + (2 - c1).rem_euclid(4);
        (l < c0).then_some((l, l as f64 + 0.5))?
    } else {
        return None;
    };
    // pos(t) − boundary changes sign once in [t0, t1].
    let f = |t: f64| pos(t) - boundary;
    let (mut lo, mut hi) = (t0, t1);
    let rising = f(t1) > f(t0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if (f(mid) >= 0.0) == rising {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some((hi, latched))
}

/// The edge timer of a board: its frequency and the reading a tick takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTimer {
    /// Counting frequency, Hz (the board's: 1 MHz).
    pub hz: f64,
}

impl EdgeTimer {
    /// The timer's count at time `t` (s), wrapping.
    pub fn ticks(&self, t: f64) -> u32 {
        ((t * self.hz).floor() as u64) as u32
    }

    /// The reading at `t1` of a tick that read it last at `t0`: the time now and the
    /// newest rising A edge since, for a position `pos(t)` in counts.
    pub fn reading(&self, pos: impl Fn(f64) -> f64, t0: f64, t1: f64) -> EdgeReading {
        EdgeReading {
            now_ticks: self.ticks(t1),
            edge: newest_rising_a(pos, t0, t1).map(|(t, c)| EdgeCapture {
                at_ticks: self.ticks(t),
                count: Counts(c.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rising_a_edges_up_and_down() {
        // Up from 0.2 to 9.7 counts in 1 s: A rises at 4.5 and 8.5; the newest, 8.5.
        let (t, c) = newest_rising_a(|t| 0.2 + 9.5 * t, 0.0, 1.0).unwrap();
        assert_eq!(c, 9);
        assert!((0.2 + 9.5 * t - 8.5).abs() < 1e-9);
        // Up from 1.6 to 4.4: the boundaries 2.5 … 3.5 — no rising A (4.5 not reached).
        assert_eq!(newest_rising_a(|t| 1.6 + 2.8 * t, 0.0, 1.0), None);
        // Down from 11.2 to 2.6: A rises at 10.5 and 6.5 (2.5 not reached); the newest, 6.5.
        let (t, c) = newest_rising_a(|t| 11.2 - 8.6 * t, 0.0, 1.0).unwrap();
        assert_eq!(c, 6);
        assert!((11.2 - 8.6 * t - 6.5).abs() < 1e-9);
        // Negative counts: up from −7.8 to −2.9: A rises at −6.5 and −3.5 (−7 and −3 are
        // ≡ 1 mod 4); the newest, −3.5.
        let (_, c) = newest_rising_a(|t| -7.8 + 4.9 * t, 0.0, 1.0).unwrap();
        assert_eq!(c, -3);
        // Standing still: none.
        assert_eq!(newest_rising_a(|_| 5.0, 0.0, 1.0), None);
    }

    #[test]
    fn the_timer_counts_the_edge_instant() {
        let tm = EdgeTimer { hz: 1e6 };
        // 3000 counts/s from 0: A rises at 0.5 (t = 166.67 µs) and 4.5 (1.5 ms).
        let r = tm.reading(|t| 3000.0 * t, 0.0, 0.0016);
        assert_eq!(r.now_ticks, 1600);
        let e = r.edge.unwrap();
        assert_eq!(e.count, Counts(5));
        assert!((1499..=1500).contains(&e.at_ticks), "{}", e.at_ticks);
        assert_eq!(tm.ticks(4295.0), (4_295_000_000u64 % (1 << 32)) as u32);
    }
}
