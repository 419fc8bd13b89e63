//! The time-optimal rest-to-rest 7-phase plan (SPEC §B), in `f64`, outside the hot path.
//!
//! Limits V, A, J > 0, distance D ≥ 0 (all in the position format's LSB and seconds).
//! Jerk per phase: `+J, 0, −J, 0, −J, 0, +J`; durations `tj, ta, tj, tv, tj, ta, tj`
//! (the deceleration mirrors the acceleration, so the profile is point-symmetric about
//! the middle of the move). With `ap = J·tj` the peak acceleration and `vp` the peak
//! velocity:
//!
//! ```text
//! vp = ap·(tj + ta)                     (area of the acceleration trapezoid)
//! D  = vp·(2·tj + ta + tv)              (the acceleration half averages vp/2)
//! T  = 4·tj + 2·ta + tv                 (move time)
//! ```
//!
//! The four regimes (Biagiotti & Melchiorri, *Trajectory Planning for Automatic
//! Machines and Robots*, 2008, §3.4, with equal limits for both halves):
//!
//! | regime | condition | tj | ta | tv |
//! |---|---|---|---|---|
//! | [`Regime::BothLimits`] | V·J ≥ A², D ≥ V·(V/A + A/J) | A/J | V/A − A/J | (D − V·(V/A + A/J))/V |
//! | [`Regime::AccNotReached`] | V·J < A², D ≥ 2·V·√(V/J) | √(V/J) | 0 | (D − 2·V·√(V/J))/V |
//! | [`Regime::VelNotReached`] | D below both of the above, D ≥ 2·A³/J² | A/J | vp/A − A/J | 0 |
//! | [`Regime::NeitherReached`] | D < 2·A³/J², D below the V threshold | ∛(D/(2J)) | 0 | 0 |
//!
//! with, when V is not reached but A is, `vp = 2D / (√((A/J)² + 4D/A) + A/J)` (the
//! positive root of `vp²/A + vp·A/J = D`, in the form without cancellation). Each
//! profile is the fastest one that respects the limits: the acceleration half reaches
//! the highest velocity the distance allows as fast as the jerk and acceleration limits
//! let it, and cruises at the velocity limit otherwise.

use super::ScurveError;

/// Largest accepted limit, in LSB per second^n (far above any machine: for `PosUm`
/// 1e18 LSB/s is 3.9e9 m/s).
pub const MAX_LIMIT: f64 = 1e18;

/// Limits of a move in the position format's LSB per second, second², second³.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    /// Velocity limit V, LSB/s (> 0).
    pub vel_lsb_per_s: f64,
    /// Acceleration limit A, LSB/s² (> 0).
    pub acc_lsb_per_s2: f64,
    /// Jerk limit J, LSB/s³ (> 0).
    pub jerk_lsb_per_s3: f64,
}

/// Which limits the time-optimal profile reaches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Regime {
    /// Zero distance: the empty move (no phase, the target is the start).
    Empty,
    /// A and V both reached: all seven phases (phases 2, 6 may be empty when V·J = A²).
    BothLimits,
    /// V reached, A not (V·J < A²): no constant-acceleration phases.
    AccNotReached,
    /// A reached, V not (short move): no cruise.
    VelNotReached,
    /// Neither reached (shortest moves): only the four jerk phases.
    NeitherReached,
}

/// The time-optimal plan of one move, in `f64` (the reference; the control loop samples
/// the fixed-point [`super::Profile`] built from it).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Plan {
    /// Which limits are reached.
    pub regime: Regime,
    /// Distance D, LSB.
    pub distance_lsb: u64,
    /// Jerk J used in phases 1, 3, 5, 7, LSB/s³.
    pub jerk: f64,
    /// Peak acceleration ap = J·tj ≤ A, LSB/s².
    pub peak_acc: f64,
    /// Peak velocity vp ≤ V, LSB/s.
    pub peak_vel: f64,
    /// Duration of each jerk phase (1, 3, 5, 7), s.
    pub t_jerk_s: f64,
    /// Duration of each constant-acceleration phase (2, 6), s.
    pub t_acc_s: f64,
    /// Duration of the cruise (phase 4), s.
    pub t_cruise_s: f64,
}

fn limit_ok(x: f64) -> bool {
    x.is_finite() && x > 0.0 && x <= MAX_LIMIT
}

impl Plan {
    /// The time-optimal plan for `distance_lsb` under `limits`.
    ///
    /// Errors: a limit not finite, not positive or above [`MAX_LIMIT`]
    /// ([`ScurveError::Velocity`], [`ScurveError::Acceleration`], [`ScurveError::Jerk`]);
    /// a distance above [`super::MAX_DISTANCE_LSB`] ([`ScurveError::DistanceTooLong`]).
    /// A zero distance is the valid empty move.
    pub fn new(distance_lsb: u64, limits: &Limits) -> Result<Plan, ScurveError> {
        let (v, a, j) = (
            limits.vel_lsb_per_s,
            limits.acc_lsb_per_s2,
            limits.jerk_lsb_per_s3,
        );
        if !limit_ok(v) {
            return Err(ScurveError::Velocity);
        }
        if !limit_ok(a) {
            return Err(ScurveError::Acceleration);
        }
        if !limit_ok(j) {
            return Err(ScurveError::Jerk);
        }
        if distance_lsb > super::MAX_DISTANCE_LSB {
            return Err(ScurveError::DistanceTooLong);
        }
        if distance_lsb == 0 {
            return Ok(Plan {
                regime: Regime::Empty,
                distance_lsb: 0,
                jerk: j,
                peak_acc: 0.0,
                peak_vel: 0.0,
                t_jerk_s: 0.0,
                t_acc_s: 0.0,
                t_cruise_s: 0.0,
            });
        }
        let d = distance_lsb as f64;
        // Acceleration half that ends exactly at V.
        let a_reached = v * j >= a * a;
        let (tj_v, ta_v) = if a_reached {
            (a / j, (v / a - a / j).max(0.0))
        } else {
            (libm::sqrt(v / j), 0.0)
        };
        let d_v = v * (2.0 * tj_v + ta_v); // distance of both halves, no cruise
        let (regime, tj, ta, tv, vp, ap) = if d >= d_v {
            let regime = if a_reached {
                Regime::BothLimits
            } else {
                Regime::AccNotReached
            };
            let ap = if a_reached { a } else { j * tj_v };
            (regime, tj_v, ta_v, (d - d_v) / v, v, ap)
        } else if d >= 2.0 * a * a * a / (j * j) {
            let tj = a / j;
            let vp = 2.0 * d / (libm::sqrt(tj * tj + 4.0 * d / a) + tj);
            let ta = (vp / a - tj).max(0.0);
            (Regime::VelNotReached, tj, ta, 0.0, vp, a)
        } else {
            let tj = libm::cbrt(d / (2.0 * j));
            (Regime::NeitherReached, tj, 0.0, 0.0, j * tj * tj, j * tj)
        };
        if !(tj.is_finite() && ta.is_finite() && tv.is_finite()) {
            return Err(ScurveError::DurationTooLong);
        }
        Ok(Plan {
            regime,
            distance_lsb,
            jerk: j,
            peak_acc: ap,
            peak_vel: vp,
            t_jerk_s: tj,
            t_acc_s: ta,
            t_cruise_s: tv,
        })
    }

    /// Move time T = 4·tj + 2·ta + tv, s.
    pub fn duration_s(&self) -> f64 {
        4.0 * self.t_jerk_s + 2.0 * self.t_acc_s + self.t_cruise_s
    }

    /// Durations of the seven phases, s: `[tj, ta, tj, tv, tj, ta, tj]`.
    pub fn phase_durations_s(&self) -> [f64; 7] {
        let (tj, ta, tv) = (self.t_jerk_s, self.t_acc_s, self.t_cruise_s);
        [tj, ta, tj, tv, tj, ta, tj]
    }

    /// Velocity at the end of phase 1, `v1 = ap·tj/2`, LSB/s.
    pub(crate) fn v1(&self) -> f64 {
        0.5 * self.peak_acc * self.t_jerk_s
    }

    /// Velocity at the end of phase 2, `v2 = v1 + ap·ta`, LSB/s.
    pub(crate) fn v2(&self) -> f64 {
        self.v1() + self.peak_acc * self.t_acc_s
    }

    /// Position, velocity, acceleration of the acceleration half at `σ ∈ [0, 2tj + ta]`.
    fn half_state(&self, sigma: f64) -> (f64, f64, f64) {
        let (j, ap, tj, ta) = (self.jerk, self.peak_acc, self.t_jerk_s, self.t_acc_s);
        if sigma < tj {
            (
                j * (sigma * sigma * sigma) / 6.0,
                0.5 * j * sigma * sigma,
                j * sigma,
            )
        } else if sigma < tj + ta {
            let tau = sigma - tj;
            let (s1, v1) = (j * (tj * tj * tj) / 6.0, self.v1());
            (s1 + v1 * tau + 0.5 * ap * tau * tau, v1 + ap * tau, ap)
        } else {
            let tau = (sigma - tj - ta).min(tj);
            let (s1, v1, v2) = (j * (tj * tj * tj) / 6.0, self.v1(), self.v2());
            let s2 = s1 + v1 * ta + 0.5 * ap * ta * ta;
            (
                s2 + v2 * tau + 0.5 * ap * tau * tau - j * (tau * tau * tau) / 6.0,
                v2 + ap * tau - 0.5 * j * tau * tau,
                ap - j * tau,
            )
        }
    }

    /// The exact profile at time `t_s` (s): (position LSB, velocity LSB/s, acceleration
    /// LSB/s²). Reference for tests and reports, not for the control loop. The
    /// deceleration half is evaluated as `D − s(T − t)` (the profile's symmetry).
    pub fn state_at(&self, t_s: f64) -> (f64, f64, f64) {
        let d = self.distance_lsb as f64;
        let t_half = 2.0 * self.t_jerk_s + self.t_acc_s;
        let t_end = self.duration_s();
        if d == 0.0 || t_s >= t_end {
            (d, 0.0, 0.0)
        } else if t_s <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if t_s <= t_half {
            self.half_state(t_s)
        } else if t_s < t_half + self.t_cruise_s {
            let (sa, _, _) = self.half_state(t_half);
            (sa + self.peak_vel * (t_s - t_half), self.peak_vel, 0.0)
        } else {
            let (s, v, a) = self.half_state(t_end - t_s);
            (d - s, v, -a)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER: Limits = Limits {
        vel_lsb_per_s: 1.5,
        acc_lsb_per_s2: 1.0,
        jerk_lsb_per_s3: 1.0,
    };

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    /// Paper case, D = 10: A and V reached; T = D/V + V/A + A/J = 9.1667 s.
    #[test]
    fn regime_both_limits() {
        let p = Plan::new(10, &PAPER).unwrap();
        assert_eq!(p.regime, Regime::BothLimits);
        assert!(close(p.t_jerk_s, 1.0));
        assert!(close(p.t_acc_s, 0.5));
        assert!(close(p.t_cruise_s, 10.0 / 1.5 - 2.5));
        assert!(close(p.duration_s(), 10.0 / 1.5 + 2.5));
        assert!(close(p.peak_vel, 1.5) && close(p.peak_acc, 1.0));
    }

    /// V·J < A²: V = 0.5, A = 1, J = 1 reaches V after tj = √(V/J) with ap = √(V·J) < A.
    #[test]
    fn regime_acceleration_not_reached() {
        let lim = Limits {
            vel_lsb_per_s: 0.5,
            ..PAPER
        };
        let p = Plan::new(10, &lim).unwrap();
        assert_eq!(p.regime, Regime::AccNotReached);
        let tj = 0.5f64.sqrt();
        assert!(close(p.t_jerk_s, tj));
        assert_eq!(p.t_acc_s, 0.0);
        assert!(close(p.peak_acc, tj));
        assert!(close(p.t_cruise_s, (10.0 - 2.0 * 0.5 * tj) / 0.5));
        assert!(close(p.duration_s(), 4.0 * tj + (10.0 - tj) / 0.5));
    }

    /// Paper case, D = 3: A reached (D ≥ 2A³/J² = 2) but V not (D < 3.75).
    #[test]
    fn regime_velocity_not_reached() {
        let p = Plan::new(3, &PAPER).unwrap();
        assert_eq!(p.regime, Regime::VelNotReached);
        // vp² + vp − 3 = 0.
        let vp = (-1.0 + 13f64.sqrt()) / 2.0;
        assert!(close(p.peak_vel, vp));
        assert!(close(p.t_jerk_s, 1.0));
        assert!(close(p.t_acc_s, vp - 1.0));
        assert_eq!(p.t_cruise_s, 0.0);
        assert!(p.peak_vel < 1.5);
    }

    /// Paper case, D = 1: neither limit; tj = ∛(D/2J), T = 4·tj.
    #[test]
    fn regime_neither_limit() {
        let p = Plan::new(1, &PAPER).unwrap();
        assert_eq!(p.regime, Regime::NeitherReached);
        let tj = 0.5f64.powf(1.0 / 3.0);
        assert!(close(p.t_jerk_s, tj));
        assert_eq!((p.t_acc_s, p.t_cruise_s), (0.0, 0.0));
        assert!(close(p.duration_s(), 4.0 * tj));
        assert!(p.peak_acc < 1.0 && p.peak_vel < 1.5);
    }

    #[test]
    fn reference_state_ends_at_distance() {
        for (d, lim) in [(1u64, PAPER), (3, PAPER), (10, PAPER)] {
            let p = Plan::new(d, &lim).unwrap();
            let (s, v, a) = p.state_at(p.duration_s() * (1.0 - 1e-12));
            assert!((s - d as f64).abs() < 1e-9 && v.abs() < 1e-9 && a.abs() < 1e-6);
            // Symmetry: the middle is at D/2 with peak velocity.
            let (s, v, _) = p.state_at(p.duration_s() / 2.0);
            assert!(close(s, d as f64 / 2.0) && close(v, p.peak_vel));
        }
    }

    #[test]
    fn bad_limits_are_named() {
        let bad = |v: f64, a: f64, j: f64| {
            Plan::new(
                10,
                &Limits {
                    vel_lsb_per_s: v,
                    acc_lsb_per_s2: a,
                    jerk_lsb_per_s3: j,
                },
            )
        };
        assert_eq!(bad(0.0, 1.0, 1.0), Err(ScurveError::Velocity));
        assert_eq!(bad(-1.0, 1.0, 1.0), Err(ScurveError::Velocity));
        assert_eq!(bad(f64::NAN, 1.0, 1.0), Err(ScurveError::Velocity));
        assert_eq!(bad(1.0, 0.0, 1.0), Err(ScurveError::Acceleration));
        assert_eq!(bad(1.0, f64::INFINITY, 1.0), Err(ScurveError::Acceleration));
        assert_eq!(bad(1.0, 1.0, -3.0), Err(ScurveError::Jerk));
        assert_eq!(bad(1.0, 1.0, 1e19), Err(ScurveError::Jerk));
        assert_eq!(
            Plan::new(super::super::MAX_DISTANCE_LSB + 1, &PAPER),
            Err(ScurveError::DistanceTooLong)
        );
        let empty = Plan::new(0, &PAPER).unwrap();
        assert_eq!(empty.regime, Regime::Empty);
        assert_eq!(empty.duration_s(), 0.0);
    }
}
