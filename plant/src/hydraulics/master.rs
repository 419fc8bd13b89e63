//! The master: the rotary table's angle as a closed-form function of time.
//!
//! The table speed is a nominal speed `w` (°/s) shaped by an envelope `env(τ)` and a
//! relative ripple `a` at frequency `f` (a hydraulically driven table is never perfectly
//! steady), `τ = t − t_start`:
//!
//! ```text
//! ω(τ) = σ·w·env(τ)·(1 + a·sin(Ω·τ + φ)),   Ω = 2π·f,   σ = sgn(θ_end − θ_0)
//! env = (1 − cos(π·τ/T_r))/2          0 ≤ τ < T_r           (cosine speed ramp up)
//!     = 1                             T_r ≤ τ < τ_s         (cruise)
//!     = (1 + cos(π·(τ − τ_s)/T_r))/2  τ_s ≤ τ < τ_s + T_r   (cosine ramp down)
//!     = 0                             after (hold at θ_end)
//! θ(τ) = θ_0 + ∫₀^τ ω
//! ```
//!
//! Every piece integrates in closed form (products of cosines and sines expand into sines
//! of sum and difference frequencies), so `θ(t)` is exact at any instant, not the
//! accumulation of an integrator. The start of the ramp down `τ_s` is solved once (by
//! bisection to machine precision; the travel is strictly increasing in `τ_s`) so the
//! table arrives at rest at exactly `θ_end`; from then on `θ` is `θ_end` exactly.

use std::f64::consts::{FRAC_PI_2, PI};

/// Parameters of the master motion (engineering units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterMotion {
    /// Start angle θ_0, degrees.
    pub start_deg: f64,
    /// End angle θ_end, degrees (≠ start).
    pub end_deg: f64,
    /// Nominal speed w, °/s (> 0).
    pub speed_deg_per_s: f64,
    /// Duration T_r of each cosine speed ramp, s (> 0).
    pub ramp_s: f64,
    /// Relative speed ripple a (0 ≤ a < 1; PLANT.md: 0.03).
    pub ripple: f64,
    /// Ripple frequency f, Hz.
    pub ripple_hz: f64,
    /// Ripple phase φ at the start of the motion, rad.
    pub ripple_phase_rad: f64,
    /// Time at rest before the motion starts, s.
    pub start_s: f64,
    /// Time at rest at θ_end after the motion, s.
    pub hold_s: f64,
}

/// The master travel is shorter than its two speed ramps cover.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "master travel of {travel_deg}° is shorter than the {min_deg:.4}° its two speed ramps need"
)]
pub struct MasterTooShort {
    /// Requested travel |θ_end − θ_0|, degrees.
    pub travel_deg: f64,
    /// Shortest travel the ramps allow, degrees.
    pub min_deg: f64,
}

/// A master motion with its solved ramp-down instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterProfile {
    m: MasterMotion,
    sign: f64,
    beta: f64,
    omega: f64,
    /// Start of the ramp down, τ_s (s after the start of the motion).
    tau_stop: f64,
    /// `∫₀^{T_r}` and `∫₀^{τ_s}` of `env·(1 + a·sin)` (cached pieces), s.
    j_ramp: f64,
    j_cruise: f64,
}

/// `sin(z)/z`, 1 at 0.
fn sinc(z: f64) -> f64 {
    if z.abs() < 1e-4 {
        1.0 - z * z / 6.0
    } else {
        z.sin() / z
    }
}

/// `∫_{t0}^{t1} sin(k·s + φ) ds = Δ·sinc(k·Δ/2)·sin(k·(t0 + t1)/2 + φ)`, Δ = t1 − t0.
fn int_sin(k: f64, phi: f64, t0: f64, t1: f64) -> f64 {
    let d = t1 - t0;
    d * sinc(0.5 * k * d) * (k * 0.5 * (t0 + t1) + phi).sin()
}

impl MasterProfile {
    /// Solves the ramp-down instant so the motion ends exactly at `end_deg`.
    /// The caller validates the other parameters (finite, positive speed and ramp,
    /// 0 ≤ ripple < 1).
    pub fn new(m: MasterMotion) -> Result<Self, MasterTooShort> {
        let travel = (m.end_deg - m.start_deg).abs();
        let mut p = Self {
            m,
            sign: if m.end_deg >= m.start_deg { 1.0 } else { -1.0 },
            beta: PI / m.ramp_s,
            omega: 2.0 * PI * m.ripple_hz,
            tau_stop: m.ramp_s,
            j_ramp: 0.0,
            j_cruise: 0.0,
        };
        let want = travel / m.speed_deg_per_s; // ∫ env·(1 + a·sin) over the whole motion, s
        let min = p.total(m.ramp_s);
        if want < min {
            return Err(MasterTooShort {
                travel_deg: travel,
                min_deg: min * m.speed_deg_per_s,
            });
        }
        // total(τ_s) − min ≥ (τ_s − T_r)·(1 − a) − a·T_r: widen until the bracket holds the root.
        let (mut lo, mut hi) = (m.ramp_s, m.ramp_s + (want - min) / (1.0 - m.ripple) + 1.0);
        for _ in 0..64 {
            if p.total(hi) >= want {
                break;
            }
            lo = hi;
            hi = m.ramp_s + 2.0 * (hi - m.ramp_s);
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if p.total(mid) < want {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        p.tau_stop = 0.5 * (lo + hi);
        p.j_ramp = p.piece(0.5, -0.5, 0.0, 0.0, m.ramp_s);
        p.j_cruise = p.j_ramp + p.piece(1.0, 0.0, 0.0, m.ramp_s, p.tau_stop);
        Ok(p)
    }

    /// The motion parameters.
    pub fn motion(&self) -> &MasterMotion {
        &self.m
    }

    /// `∫_{t0}^{t1} (c0 + c1·cos(β·s + ψ))·(1 + a·sin(Ω·s + φ)) ds`, s.
    fn piece(&self, c0: f64, c1: f64, psi: f64, t0: f64, t1: f64) -> f64 {
        if t1 <= t0 {
            return 0.0;
        }
        let (a, b, w, phi) = (
            self.m.ripple,
            self.beta,
            self.omega,
            self.m.ripple_phase_rad,
        );
        c0 * (t1 - t0)
            + c1 * int_sin(b, psi + FRAC_PI_2, t0, t1)
            + a * c0 * int_sin(w, phi, t0, t1)
            + 0.5 * a * c1 * (int_sin(w + b, phi + psi, t0, t1) + int_sin(w - b, phi - psi, t0, t1))
    }

    /// `∫₀^τ env·(1 + a·sin)` for a ramp-down start `tau_stop`, s.
    fn integral(&self, tau: f64, tau_stop: f64) -> f64 {
        let tr = self.m.ramp_s;
        self.piece(0.5, -0.5, 0.0, 0.0, tau.min(tr))
            + self.piece(1.0, 0.0, 0.0, tr, tau.min(tau_stop))
            + self.piece(
                0.5,
                0.5,
                -self.beta * tau_stop,
                tau_stop,
                tau.min(tau_stop + tr),
            )
    }

    fn total(&self, tau_stop: f64) -> f64 {
        self.integral(tau_stop + self.m.ramp_s, tau_stop)
    }

    /// Time at which the table arrives at rest at θ_end, s.
    pub fn stop_time_s(&self) -> f64 {
        self.m.start_s + self.tau_stop + self.m.ramp_s
    }

    /// Total scenario time: start delay, motion and hold, s.
    pub fn duration_s(&self) -> f64 {
        self.stop_time_s() + self.m.hold_s
    }

    /// Table angle θ(t), degrees.
    pub fn angle_deg(&self, t: f64) -> f64 {
        let tau = t - self.m.start_s;
        if tau <= 0.0 {
            self.m.start_deg
        } else if tau >= self.tau_stop + self.m.ramp_s {
            self.m.end_deg
        } else {
            // The completed pieces are cached: one piece per call.
            let tr = self.m.ramp_s;
            let j = if tau < tr {
                self.piece(0.5, -0.5, 0.0, 0.0, tau)
            } else if tau < self.tau_stop {
                self.j_ramp + self.piece(1.0, 0.0, 0.0, tr, tau)
            } else {
                self.j_cruise + self.piece(0.5, 0.5, -self.beta * self.tau_stop, self.tau_stop, tau)
            };
            self.m.start_deg + self.sign * self.m.speed_deg_per_s * j
        }
    }

    /// Table speed ω(t), °/s.
    pub fn speed_deg_per_s(&self, t: f64) -> f64 {
        let tau = t - self.m.start_s;
        let tr = self.m.ramp_s;
        let env = if tau <= 0.0 || tau >= self.tau_stop + tr {
            return 0.0;
        } else if tau < tr {
            0.5 * (1.0 - (self.beta * tau).cos())
        } else if tau < self.tau_stop {
            1.0
        } else {
            0.5 * (1.0 + (self.beta * (tau - self.tau_stop)).cos())
        };
        let ripple = 1.0 + self.m.ripple * (self.omega * tau + self.m.ripple_phase_rad).sin();
        self.sign * self.m.speed_deg_per_s * env * ripple
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> MasterMotion {
        MasterMotion {
            start_deg: 0.0,
            end_deg: 90.0,
            speed_deg_per_s: 3.0,
            ramp_s: 1.0,
            ripple: 0.03,
            ripple_hz: 0.4,
            ripple_phase_rad: 0.0,
            start_s: 0.0,
            hold_s: 1.0,
        }
    }

    /// Simpson integration of the speed against the closed-form angle.
    #[test]
    fn angle_is_integral_of_speed() {
        for (m, ph) in [(reference(), 0.0), (reference(), 1.0)] {
            let p = MasterProfile::new(MasterMotion {
                ripple_phase_rad: ph,
                ripple_hz: if ph > 0.0 { 0.5 } else { 0.4 }, // 0.5 Hz: Ω = β, a degenerate term
                ..m
            })
            .unwrap();
            let n = 200_000;
            let t_end = p.duration_s();
            let h = t_end / f64::from(n);
            let mut acc = 0.0;
            let mut worst: f64 = 0.0;
            for i in 0..n {
                let t0 = f64::from(i) * h;
                acc += h / 6.0
                    * (p.speed_deg_per_s(t0)
                        + 4.0 * p.speed_deg_per_s(t0 + 0.5 * h)
                        + p.speed_deg_per_s(t0 + h));
                worst = worst.max((acc - p.angle_deg(t0 + h)).abs());
            }
            assert!(worst < 1e-6, "worst {worst}°");
        }
    }

    #[test]
    fn stops_exactly_and_continuously() {
        let p = MasterProfile::new(reference()).unwrap();
        let ts = p.stop_time_s();
        assert_eq!(p.angle_deg(ts), 90.0);
        assert!((p.angle_deg(ts - 1e-9) - 90.0).abs() < 1e-9);
        assert_eq!(p.speed_deg_per_s(ts + 0.1), 0.0);
        // 90° at 3 °/s plus two half-covered 1 s ramps: about 31 s, ripple shifts it.
        assert!((ts - 31.0).abs() < 0.2, "stop at {ts}");
        assert!((p.duration_s() - ts - 1.0).abs() < 1e-12);
        // Speed within the ripple band during cruise.
        for i in 0..100 {
            let w = p.speed_deg_per_s(2.0 + 0.28 * f64::from(i));
            assert!((w - 3.0).abs() <= 0.09 + 1e-12, "{w}");
        }
    }

    #[test]
    fn reverse_and_too_short() {
        let p = MasterProfile::new(MasterMotion {
            start_deg: 90.0,
            end_deg: 0.0,
            ..reference()
        })
        .unwrap();
        assert_eq!(p.angle_deg(1e3), 0.0);
        assert!(p.speed_deg_per_s(5.0) < 0.0);
        assert!(p.angle_deg(5.0) < 90.0);
        let e = MasterProfile::new(MasterMotion {
            end_deg: 2.0,
            ..reference()
        })
        .unwrap_err();
        assert!((e.min_deg - 3.0).abs() < 0.1, "{e}");
    }
}
