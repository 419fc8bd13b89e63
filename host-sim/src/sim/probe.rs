//! A sinusoidal probe at one follower's valve: the position loop's frequency response,
//! measured on the running machine with the loop broken at the sampled command.
//!
//! ```text
//! u_app(k) = clamp(u_ctrl(k) + d(k), ±1),   d(k) = A·sin(2π·f·(t_k − t_0))   (t_k ≥ t_0)
//! U(ω)     = Σ_k w(k)·u(k)·e^(−jω·t_k)      w: Hann over the analysis window
//! L(e^jωT) = −U_ctrl(ω) / U_app(ω)
//! ```
//!
//! `u_ctrl` is what the controller computed at the sample (valve units, 1 = full
//! opening), `u_app` what the valve receives. Whatever closes the loop — the position law,
//! the active damping's pressure feedback, the sample-and-hold and the period of delay —
//! is inside L, and the plant is the nonlinear model (valve, oil, friction), so the
//! figure is the loop at this amplitude around the table's motion. The probe starts at
//! `t_0` from zero phase; the analysis window begins `settle_s` later so the start's
//! transient has decayed, and the Hann window keeps the table's slow feed-forward out of
//! the bin.

use nalgebra::Complex;

/// The probe: where, how large, which frequency, when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// The follower axis (index among the followers).
    pub follower: usize,
    /// A, valve units (1 = full opening).
    pub amplitude: f64,
    /// f, Hz.
    pub freq_hz: f64,
    /// t_0: the probe starts, s.
    pub start_s: f64,
    /// From t_0 to the analysis window, s.
    pub settle_s: f64,
    /// The analysis window's length, s.
    pub window_s: f64,
}

impl Probe {
    /// The run must last this long, s.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.settle_s + self.window_s
    }

    /// d at time `t`, valve units.
    pub fn disturbance(&self, t: f64) -> f64 {
        if t < self.start_s {
            0.0
        } else {
            self.amplitude * (std::f64::consts::TAU * self.freq_hz * (t - self.start_s)).sin()
        }
    }
}

/// The two windowed DFT bins as the run accumulates them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeBins {
    ctrl: Complex<f64>,
    app: Complex<f64>,
    n: u64,
}

impl ProbeBins {
    /// Adds the sample at `t` (s): the controller's and the applied command.
    pub fn add(&mut self, p: &Probe, t: f64, u_ctrl: f64, u_app: f64) {
        let t0 = p.start_s + p.settle_s;
        let x = (t - t0) / p.window_s;
        if !(0.0..1.0).contains(&x) {
            return;
        }
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * x).cos();
        let e = Complex::from_polar(w, -std::f64::consts::TAU * p.freq_hz * t);
        self.ctrl += e * u_ctrl;
        self.app += e * u_app;
        self.n += 1;
    }

    /// L = −U_ctrl / U_app at the probe's frequency; `None` before any sample or with no
    /// applied content at the frequency.
    pub fn loop_response(&self) -> Option<Complex<f64>> {
        (self.n > 0 && self.app.norm() > 0.0).then(|| -self.ctrl / self.app)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A known discrete loop: the controller returns −g·u_app(k−1) (a gain and one
    /// period of delay): L = g·e^(−jωT), recovered in magnitude and phase.
    #[test]
    fn recovers_a_gain_and_a_delay() {
        let t_s = 1e-3;
        let p = Probe {
            follower: 0,
            amplitude: 0.02,
            freq_hz: 37.0,
            start_s: 0.1,
            settle_s: 0.2,
            window_s: 1.0,
        };
        let g = 0.6;
        let mut bins = ProbeBins::default();
        let mut prev_app = 0.0;
        let mut k = 0u64;
        while (k as f64) * t_s < p.end_s() {
            let t = k as f64 * t_s;
            let u_ctrl = -g * prev_app + 0.3 * (t * 0.7).sin(); // + slow "feed-forward"
            let u_app = u_ctrl + p.disturbance(t);
            bins.add(&p, t, u_ctrl, u_app);
            prev_app = u_app;
            k += 1;
        }
        let l = bins.loop_response().unwrap();
        let want = Complex::from_polar(g, -std::f64::consts::TAU * p.freq_hz * t_s);
        assert!((l - want).norm() < 0.01 * g, "{l} vs {want}");
        assert_eq!(ProbeBins::default().loop_response(), None);
    }
}
