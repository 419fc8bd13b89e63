//! Tracking-error statistics of a run (µm in, µm out): the simulator's and the
//! emulated board's figures are computed by the same code.

/// Accumulates max |e| and Σe² (the error statistics of a run; board-emu measures the
/// emulated board with the same).
#[derive(Clone, Copy, Debug, Default)]
pub struct ErrorStat {
    /// Largest |e|.
    pub max: f64,
    sum2: f64,
    /// Samples.
    pub n: u64,
}

impl ErrorStat {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, e: f64) {
        self.max = self.max.max(e.abs());
        self.sum2 += e * e;
        self.n += 1;
    }

    /// RMS of the samples (0 without any).
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum2 / self.n as f64).sqrt()
        }
    }
}
