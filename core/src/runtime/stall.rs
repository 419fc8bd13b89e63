//! Master-stall detection while following.
//!
//! The monitor is armed by the master's first movement after control starts (so waiting
//! for a master that has not started yet is allowed for as long as it takes), then
//! counts the ticks since the master last moved:
//!
//! ```text
//! moved(k)  ⇔ |θ(k) − θ_anchor| ≥ m          (then θ_anchor ← θ(k), still ← 0, armed)
//! stalled   ⇔ armed ∧ still ≥ N_timeout
//! ```
//!
//! so an armed master slower than m / t_timeout (default 10 counts/s = 0.01 °/s) is a
//! stall: a frozen master encoder while the machine still turns is the case this catches.

use crate::units::Master;

/// The stall monitor's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StallMonitor {
    anchor: Master,
    still_ticks: u32,
    armed: bool,
}

impl StallMonitor {
    /// Restarts monitoring from `master` (disarmed).
    pub fn reset(&mut self, master: Master) {
        *self = Self {
            anchor: master,
            still_ticks: 0,
            armed: false,
        };
    }

    /// One tick; returns `true` if the master counts as stalled.
    /// `min_move_counts` ≥ 1 and `timeout_ticks` ≥ 1 (validated by the config).
    #[inline]
    pub fn update(&mut self, master: Master, min_move_counts: u32, timeout_ticks: u32) -> bool {
        let moved = master.saturating_sub(self.anchor).unsigned_abs() >= min_move_counts;
        if moved {
            self.anchor = master;
            self.still_ticks = 0;
            self.armed = true;
            false
        } else if self.armed {
            self.still_ticks = self.still_ticks.saturating_add(1);
            self.still_ticks >= timeout_ticks
        } else {
            false
        }
    }

    /// Whether the master has moved since the last reset.
    pub const fn armed(&self) -> bool {
        self.armed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(x: i32) -> Master {
        Master::from_num(x)
    }

    #[test]
    fn waits_for_first_motion_then_times_out() {
        let mut s = StallMonitor::default();
        s.reset(m(100));
        for _ in 0..10_000 {
            assert!(!s.update(m(100), 10, 50));
        }
        assert!(!s.armed());
        assert!(!s.update(m(110), 10, 50));
        assert!(s.armed());
        for i in 1..50 {
            assert!(!s.update(m(115), 10, 50), "tick {i}");
        }
        assert!(s.update(m(115), 10, 50));
    }

    #[test]
    fn steady_motion_never_stalls_and_slow_motion_does() {
        let mut s = StallMonitor::default();
        s.reset(m(0));
        // 1 count per tick, threshold 10 in 50 ticks: moving.
        for k in 1..5000 {
            assert!(!s.update(m(k), 10, 50));
        }
        // Backwards too.
        for k in (0..5000).rev() {
            assert!(!s.update(m(k), 10, 50));
        }
        // 1 count per 10 ticks: 5 counts in 50 ticks < 10 → stall within 100 ticks.
        let mut stalled = false;
        for k in 0..100 {
            stalled |= s.update(Master::from_num(f64::from(k) / 10.0), 10, 50);
        }
        assert!(stalled);
    }
}
