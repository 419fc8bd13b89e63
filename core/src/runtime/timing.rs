//! Tick execution-time statistics (cycles of the CPU's cycle counter).
//!
//! ```text
//! max   = max over every recorded tick since the last reset
//! mean  = Σ cycles / n over the last completed window of W ticks (W = 1024)
//! ```
//!
//! The window mean is published only when a window completes, so a reader always sees
//! the mean of exactly W ticks; `last` is the most recent tick.

/// Ticks per mean window.
pub const WINDOW_TICKS: u32 = 1024;

/// Execution-time statistics of the tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickTiming {
    /// Cycles of the most recent tick.
    pub last_cycles: u32,
    /// Largest tick since the last reset, cycles.
    pub max_cycles: u32,
    /// Mean of the last completed window, cycles (0 until one completes).
    pub mean_cycles: u32,
    /// Overruns (late or skipped periods) since the last reset.
    pub overruns: u32,
    window_sum: u64,
    window_n: u32,
}

impl TickTiming {
    /// Records one tick's execution time.
    #[inline]
    pub fn record(&mut self, cycles: u32) {
        self.last_cycles = cycles;
        self.max_cycles = self.max_cycles.max(cycles);
        self.window_sum = self.window_sum.saturating_add(u64::from(cycles));
        self.window_n = self.window_n.saturating_add(1);
        if self.window_n >= WINDOW_TICKS {
            // sum ≤ W · 2^32 / W: the quotient fits u32.
            let mean = self
                .window_sum
                .checked_div(u64::from(self.window_n))
                .unwrap_or(0);
            self.mean_cycles = u32::try_from(mean).unwrap_or(u32::MAX);
            self.window_sum = 0;
            self.window_n = 0;
        }
    }

    /// Counts one overrun.
    #[inline]
    pub fn record_overrun(&mut self) {
        self.overruns = self.overruns.saturating_add(1);
    }

    /// Clears the maximum, the mean and the overrun count.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_and_window_mean() {
        let mut t = TickTiming::default();
        for i in 0..WINDOW_TICKS - 1 {
            t.record(1000 + (i % 2) * 200);
        }
        assert_eq!(t.mean_cycles, 0, "no window completed yet");
        t.record(1200);
        assert_eq!(t.mean_cycles, 1100);
        assert_eq!(t.max_cycles, 1200);
        t.record(u32::MAX);
        assert_eq!(t.max_cycles, u32::MAX);
        assert_eq!(t.last_cycles, u32::MAX);
        t.record_overrun();
        assert_eq!(t.overruns, 1);
        t.reset();
        assert_eq!(t, TickTiming::default());
    }
}
