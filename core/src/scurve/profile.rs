//! The planned move in fixed point, and its per-period sampling (the hot path).
//!
//! A [`Profile`] is built once from a [`Plan`] and the control period T. Sampling tick
//! `k` ([`Profile::position_at`]) evaluates the closed form of the phase that contains
//! `t = k·T`, from that phase's start: no state, nothing accumulates from tick to tick.
//!
//! ## Formats
//!
//! | quantity | format | unit |
//! |---|---|---|
//! | time | `u64`, `64 − f` integer and `f` fraction bits, f = `time_frac_bits` ≥ 31 chosen per move so the whole move fits (`f = 63 − bitlen(⌊T_move/T⌋ + 2)`) | control period (tick) |
//! | phase-local time τ_n | `u64` Q0.64 | fraction of the phase's normaliser 2^e ticks, 2^e the smallest power of two above the phase duration |
//! | polynomial coefficients, position inside the evaluator | `i64` Q.14 ([`POS_FRAC_BITS`]) | LSB·(2^e ticks)^−n |
//! | output position | `i64` | LSB of the caller's format (e.g. `PosUm` raw = 1/256 µm) |
//! | [`Sample::vel_q`], [`Sample::acc_q`] | `i64` Q.14 | LSB/tick, LSB/tick² |
//!
//! Every phase polynomial is `c0 + c1·τn + c2·τn² + c3·τn³` with τn ∈ [0, 1); because
//! the normaliser is within a factor of 4 of the phase duration, every coefficient is
//! bounded by 64·D (D ≤ [`super::MAX_DISTANCE_LSB`] = 2^40 LSB) and a Q.14 value stays
//! below 2^60: the Horner steps ([`crate::fixed_point::mulhi`]) cannot overflow.
//!
//! ## Structure and exactness
//!
//! The acceleration half `S(σ)`, σ ∈ [0, 2tj + ta], is phases 1–3; phase 2 starts
//! from the value phase 1's evaluator gives at its end and phase 3 from phase 2's, so
//! the half is continuous in fixed point. The deceleration half is `D − S(T_move − t)`
//! (the profile is point-symmetric), so the motion ends at D by construction; the
//! cruise joins `S(end)` to `D − S(end)` linearly with a slope rounded down, so it
//! never overshoots. From the last tick `⌈T_move/T⌉` on, the sample is D exactly.
//!
//! ## Error bound
//!
//! Against the exact profile of the [`Plan`] at t = k·T, a position sample differs by at
//! most ½ LSB (the final rounding) plus: coefficient rounding and three floors per
//! Horner evaluation (5·2^-14 LSB per phase, chained over three phases), the rounding of
//! the phase boundaries to 2^-f ticks (≤ 4·2^-f ticks times the peak velocity in
//! LSB/tick: below 2^-17 LSB for any move since f is chosen from its length) and the
//! `f64` plan (relative 2^-50). Stated bound: **|error| ≤ 0.5 + 2^-8 LSB**; the
//! property tests measure it (docs/scurve.md gives the measured maximum).
//!
//! ## Cost
//!
//! [`Profile::position_at`]: three comparisons, one shift, three `mulhi` (4 `umull`
//! each) and adds. No division, no float, no loop, no table.

use super::plan::Plan;
use super::ScurveError;
use crate::fixed_point::{bitlen, mulhi, shl_signed_sat};

/// Fraction bits of a position inside the evaluator (Q.14 LSB: 6.1e-5 LSB).
pub const POS_FRAC_BITS: u32 = 14;

/// Longest accepted control period, s.
pub const MAX_PERIOD_S: f64 = 3600.0;

/// `2^k` as `f64` for |k| ≤ 1022.
fn pow2(k: i32) -> f64 {
    let k = k.clamp(-1022, 1023);
    f64::from_bits(u64::from(k.wrapping_add(1023).unsigned_abs()).wrapping_shl(52))
}

/// Round a non-negative finite `x < 2^63` to the nearest integer.
fn round_u64(x: f64) -> u64 {
    // `as` saturates; x + 0.5 then truncation is round-half-up for x ≥ 0.
    (x + 0.5) as u64
}

/// A coefficient `x·2^(n·e + F)` rounded to the nearest `i64`, checked below 2^62.
fn coef(x: f64, scale_log2: i32) -> Result<i64, ScurveError> {
    let y = x * pow2(scale_log2.wrapping_add(POS_FRAC_BITS as i32));
    let lim = pow2(62);
    if !y.is_finite() || y.abs() >= lim {
        return Err(ScurveError::DistanceTooLong);
    }
    let r = if y >= 0.0 {
        (y + 0.5) as i64
    } else {
        ((-y + 0.5) as i64).wrapping_neg()
    };
    Ok(r)
}

/// A non-negative `x·2^14` rounded down (a limit in Q.14: never above the exact one),
/// saturated to the `i64` range (`as` saturates).
fn coef_floor(x: f64) -> i64 {
    (x * pow2(POS_FRAC_BITS as i32)).max(0.0) as i64
}

/// One phase: `c0 + c1·τn + c2·τn² + c3·τn³`, τn = τ·2^shift as Q0.64.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Poly {
    /// τn = τ << shift (τ in time units, τ < 2^(64 − shift) by construction).
    shift: u32,
    /// e = log2 of the normaliser in ticks (may be negative for sub-tick phases).
    log2_norm: i32,
    /// Coefficients, Q.14 LSB per normaliser^n.
    c: [i64; 4],
}

impl Poly {
    /// The normaliser of a phase of `d` time units: (shift, e).
    fn norm(d: u64, time_frac_bits: u32) -> (u32, i32) {
        if d == 0 {
            (63, 0)
        } else {
            let b = bitlen(d);
            (
                64u32.wrapping_sub(b),
                (b as i32).wrapping_sub(time_frac_bits as i32),
            )
        }
    }

    /// A phase of `d` time units starting at `c0` (Q.14 LSB) with velocity `v`
    /// (LSB/tick), acceleration `a` (LSB/tick²) and jerk `j` (LSB/tick³).
    fn new(
        d: u64,
        time_frac_bits: u32,
        c0: i64,
        v: f64,
        a: f64,
        j: f64,
    ) -> Result<Poly, ScurveError> {
        let (shift, e) = Self::norm(d, time_frac_bits);
        if d == 0 {
            return Ok(Poly {
                shift,
                log2_norm: 0,
                c: [c0, 0, 0, 0],
            });
        }
        Ok(Poly {
            shift,
            log2_norm: e,
            c: [
                c0,
                coef(v, e)?,
                coef(0.5 * a, e.wrapping_mul(2))?,
                coef(j / 6.0, e.wrapping_mul(3))?,
            ],
        })
    }

    /// Position, Q.14 LSB, at τ time units into the phase.
    #[inline(always)]
    fn pos(&self, tau: u64) -> i64 {
        let tn = tau.wrapping_shl(self.shift);
        let [c0, c1, c2, c3] = self.c;
        let acc = mulhi(c3, tn).wrapping_add(c2);
        let acc = mulhi(acc, tn).wrapping_add(c1);
        mulhi(acc, tn).wrapping_add(c0)
    }

    /// Velocity, Q.14 LSB/tick: `(c1 + 2·c2·τn + 3·c3·τn²)·2^−e`.
    fn vel(&self, tau: u64) -> i64 {
        let tn = tau.wrapping_shl(self.shift);
        let [_, c1, c2, c3] = self.c;
        let acc = mulhi(c3.saturating_mul(3), tn).wrapping_add(c2.saturating_mul(2));
        let acc = mulhi(acc, tn).wrapping_add(c1);
        shl_signed_sat(acc, self.log2_norm.wrapping_neg())
    }

    /// Acceleration, Q.14 LSB/tick²: `(2·c2 + 6·c3·τn)·2^−2e`.
    fn acc(&self, tau: u64) -> i64 {
        let tn = tau.wrapping_shl(self.shift);
        let [_, _, c2, c3] = self.c;
        let acc = mulhi(c3.saturating_mul(6), tn).saturating_add(c2.saturating_mul(2));
        shl_signed_sat(acc, self.log2_norm.wrapping_mul(-2))
    }
}

/// One sample of the path: position, velocity and acceleration at tick `k`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Position along the move, LSB, in [0, D].
    pub pos_lsb: i64,
    /// Velocity, Q.14 LSB per tick (`i64`, in [0, vp]).
    pub vel_q: i64,
    /// Acceleration, Q.14 LSB per tick² (in [−ap, ap]).
    pub acc_q: i64,
}

/// A planned move in fixed point: sample it with [`Profile::position_at`] (or the
/// monotone stream [`super::Cursor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Profile {
    plan: Plan,
    period_s: f64,
    /// Fraction bits of the time format (time unit 2^−f tick).
    time_frac_bits: u32,
    /// tj, tj + ta, 2·tj + ta, end of cruise, end of move (time units).
    t_jerk: u64,
    t_jerk_acc: u64,
    t_half: u64,
    t_cruise_end: u64,
    t_end: u64,
    /// First tick at which the sample is the target: ⌈T_move / T⌉.
    end_tick: u32,
    /// D in LSB and in Q.14 LSB.
    dist_lsb: i64,
    dist_q: i64,
    p1: Poly,
    p2: Poly,
    p3: Poly,
    cruise: Poly,
    /// Peak velocity, Q.14 LSB/tick (the cruise's velocity sample), rounded down.
    cruise_vel_q: i64,
    /// Peak acceleration, Q.14 LSB/tick², rounded down.
    peak_acc_q: i64,
}

/// Rounds a Q.14 position to the nearest LSB (ties up).
#[inline(always)]
fn round_q(x: i64) -> i64 {
    x.wrapping_add(1 << (POS_FRAC_BITS - 1))
        .wrapping_shr(POS_FRAC_BITS)
}

impl Profile {
    /// Converts `plan` to fixed point for a control period of `period_s` seconds.
    ///
    /// Errors: [`ScurveError::Period`] (not finite, ≤ 0 or above [`MAX_PERIOD_S`]),
    /// [`ScurveError::DurationTooLong`] (the move lasts 2^32 − 2 periods or more),
    /// [`ScurveError::DistanceTooLong`] (a coefficient does not fit its format).
    pub fn new(plan: &Plan, period_s: f64) -> Result<Profile, ScurveError> {
        if !(period_s.is_finite() && period_s > 0.0 && period_s <= MAX_PERIOD_S) {
            return Err(ScurveError::Period);
        }
        let mut p = Profile {
            plan: *plan,
            period_s,
            time_frac_bits: 32,
            t_jerk: 0,
            t_jerk_acc: 0,
            t_half: 0,
            t_cruise_end: 0,
            t_end: 0,
            end_tick: 0,
            dist_lsb: 0,
            dist_q: 0,
            p1: Poly::default(),
            p2: Poly::default(),
            p3: Poly::default(),
            cruise: Poly::default(),
            cruise_vel_q: 0,
            peak_acc_q: 0,
        };
        if plan.distance_lsb == 0 {
            return Ok(p);
        }
        let move_ticks = plan.duration_s() / period_s;
        if !(move_ticks.is_finite() && move_ticks < 4_294_967_294.0) {
            return Err(ScurveError::DurationTooLong);
        }
        // Integer bits: the move's tick count + 2, plus one bit of headroom.
        let int_bits = bitlen((move_ticks as u64).wrapping_add(2)).wrapping_add(1);
        let f = 64u32.wrapping_sub(int_bits);
        let unit = pow2(f as i32) / period_s; // time units per second
        let tj = round_u64(plan.t_jerk_s * unit);
        let ta = round_u64(plan.t_acc_s * unit);
        let mut tv = round_u64(plan.t_cruise_s * unit);
        let t_half = tj.wrapping_mul(2).wrapping_add(ta);
        if t_half == 0 && tv == 0 {
            // A move shorter than one time unit: a one-unit step.
            tv = 1;
        }
        // move_ticks < 2^(int_bits − 1): every sum below is < 2^63 (no overflow).
        let t_end = t_half.wrapping_mul(2).wrapping_add(tv);
        let one = 1u64.wrapping_shl(f);
        let end_tick = t_end.wrapping_add(one.wrapping_sub(1)).wrapping_shr(f);
        let end_tick = u32::try_from(end_tick).map_err(|_| ScurveError::DurationTooLong)?;

        let (t, d) = (period_s, plan.distance_lsb);
        let jt = plan.jerk * t * t * t;
        let at = plan.peak_acc * t * t;
        let v1t = plan.v1() * t;
        let v2t = plan.v2() * t;
        let p1 = Poly::new(tj, f, 0, 0.0, 0.0, jt)?;
        let p2 = Poly::new(ta, f, p1.pos(tj), v1t, at, 0.0)?;
        let p3 = Poly::new(tj, f, p2.pos(ta), v2t, at, -jt)?;
        let s_half = p3.pos(tj);
        // d ≤ 2^40: D in Q.14 < 2^54.
        let dist_q = (d as i64).wrapping_shl(POS_FRAC_BITS);
        let bridge = dist_q.wrapping_sub(s_half.wrapping_mul(2)).max(0);
        let (shift, e) = Poly::norm(tv, f);
        // Slope rounded down: c1 = ⌊bridge·2^bitlen(tv) / tv⌋ ≤ 2·bridge.
        let c1 = if tv == 0 {
            0
        } else {
            let num = (bridge as u128).wrapping_shl(bitlen(tv));
            i64::try_from(num.checked_div(u128::from(tv)).unwrap_or(0))
                .map_err(|_| ScurveError::DistanceTooLong)?
        };
        let cruise = Poly {
            shift,
            log2_norm: e,
            c: [s_half, c1, 0, 0],
        };
        p.time_frac_bits = f;
        p.t_jerk = tj;
        p.t_jerk_acc = tj.wrapping_add(ta);
        p.t_half = t_half;
        p.t_cruise_end = t_half.wrapping_add(tv);
        p.t_end = t_end;
        p.end_tick = end_tick;
        p.dist_lsb = d as i64;
        p.dist_q = dist_q;
        (p.p1, p.p2, p.p3, p.cruise) = (p1, p2, p3, cruise);
        p.cruise_vel_q = coef_floor(plan.peak_vel * t);
        p.peak_acc_q = coef_floor(plan.peak_acc * t * t);
        Ok(p)
    }

    /// The `f64` plan this profile samples.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Distance D, LSB.
    pub fn distance_lsb(&self) -> i64 {
        self.dist_lsb
    }

    /// The first tick whose sample is the target, ⌈T_move / T⌉ (0 for the empty move):
    /// a move is sampled at ticks `0..=end_tick`.
    pub fn end_tick(&self) -> u32 {
        self.end_tick
    }

    /// Fraction bits of the time format chosen for this move.
    pub fn time_frac_bits(&self) -> u32 {
        self.time_frac_bits
    }

    /// Position of the acceleration half at σ time units, Q.14 LSB.
    #[inline(always)]
    fn half_pos(&self, sigma: u64) -> i64 {
        if sigma < self.t_jerk {
            self.p1.pos(sigma)
        } else if sigma < self.t_jerk_acc {
            self.p2.pos(sigma.wrapping_sub(self.t_jerk))
        } else {
            self.p3.pos(sigma.wrapping_sub(self.t_jerk_acc))
        }
    }

    /// The phase polynomial and its local time for σ in the acceleration half.
    fn half_poly(&self, sigma: u64) -> (&Poly, u64) {
        if sigma < self.t_jerk {
            (&self.p1, sigma)
        } else if sigma < self.t_jerk_acc {
            (&self.p2, sigma.wrapping_sub(self.t_jerk))
        } else {
            (&self.p3, sigma.wrapping_sub(self.t_jerk_acc))
        }
    }

    /// **The per-period sample** (hot path): the position at tick `k` (t = k·T), LSB,
    /// rounded to nearest, within 0.5 + 2^-8 LSB of the exact profile; 0 at k = 0 and
    /// exactly D for every `k ≥ end_tick`. Pure: no state, cannot fail or panic.
    #[inline]
    pub fn position_at(&self, k: u32) -> i64 {
        if k >= self.end_tick {
            return self.dist_lsb;
        }
        // k < end_tick < 2^(64 − f − 1): the shift cannot overflow.
        let t = u64::from(k).wrapping_shl(self.time_frac_bits);
        let q = if t <= self.t_half {
            self.half_pos(t)
        } else if t < self.t_cruise_end {
            self.cruise.pos(t.wrapping_sub(self.t_half))
        } else {
            // t < t_end (k < end_tick) and t ≥ t_end − t_half: ρ ∈ (0, t_half].
            self.dist_q
                .wrapping_sub(self.half_pos(self.t_end.wrapping_sub(t)))
        };
        round_q(q)
    }

    /// Position, velocity and acceleration at tick `k` (for feed-forward and reports;
    /// about twice the cost of [`Profile::position_at`]).
    ///
    /// Velocity and acceleration are the derivatives of the phase polynomial, clamped
    /// to [0, vp] and [−ap, ap] (the plan's peaks rounded down, so a sample never
    /// exceeds a limit). Their resolution is that of the coefficients: about
    /// 5·2^(−14−e) LSB/tick (2^e ticks the phase's normaliser), i.e. finer than 2^-11
    /// LSB/tick for phases of a tick or longer.
    pub fn sample(&self, k: u32) -> Sample {
        let s = self.sample_unclamped(k);
        Sample {
            pos_lsb: s.pos_lsb,
            vel_q: s.vel_q.clamp(0, self.cruise_vel_q),
            acc_q: s
                .acc_q
                .clamp(self.peak_acc_q.wrapping_neg(), self.peak_acc_q),
        }
    }

    fn sample_unclamped(&self, k: u32) -> Sample {
        if k >= self.end_tick {
            return Sample {
                pos_lsb: self.dist_lsb,
                vel_q: 0,
                acc_q: 0,
            };
        }
        let t = u64::from(k).wrapping_shl(self.time_frac_bits);
        let pos_lsb = self.position_at(k);
        if t <= self.t_half {
            let (p, tau) = self.half_poly(t);
            Sample {
                pos_lsb,
                vel_q: p.vel(tau),
                acc_q: p.acc(tau),
            }
        } else if t < self.t_cruise_end {
            Sample {
                pos_lsb,
                vel_q: self.cruise_vel_q,
                acc_q: 0,
            }
        } else {
            let (p, tau) = self.half_poly(self.t_end.wrapping_sub(t));
            Sample {
                pos_lsb,
                vel_q: p.vel(tau),
                acc_q: p.acc(tau).wrapping_neg(),
            }
        }
    }

    /// A Q.14 LSB/tick velocity in LSB/s (host reports).
    pub fn vel_to_lsb_per_s(&self, vel_q: i64) -> f64 {
        vel_q as f64 / pow2(POS_FRAC_BITS as i32) / self.period_s
    }

    /// A Q.14 LSB/tick² acceleration in LSB/s² (host reports).
    pub fn acc_to_lsb_per_s2(&self, acc_q: i64) -> f64 {
        acc_q as f64 / pow2(POS_FRAC_BITS as i32) / (self.period_s * self.period_s)
    }
}

#[cfg(test)]
mod tests {
    use super::super::plan::{Limits, Regime};
    use super::*;

    fn profile(d: u64, v: f64, a: f64, j: f64, t: f64) -> Profile {
        let plan = Plan::new(
            d,
            &Limits {
                vel_lsb_per_s: v,
                acc_lsb_per_s2: a,
                jerk_lsb_per_s3: j,
            },
        )
        .unwrap();
        Profile::new(&plan, t).unwrap()
    }

    /// Max |sample − exact| in LSB over the whole move, and checks the end.
    fn max_err(p: &Profile) -> f64 {
        let mut worst = 0.0f64;
        for k in 0..=p.end_tick() {
            let exact = p.plan().state_at(f64::from(k) * p.period_s()).0;
            worst = worst.max((p.position_at(k) as f64 - exact).abs());
        }
        assert_eq!(p.position_at(p.end_tick()), p.distance_lsb());
        assert_eq!(p.position_at(u32::MAX), p.distance_lsb());
        assert_eq!(p.position_at(0), 0);
        worst
    }

    #[test]
    fn paper_case_in_um_lsb() {
        // A = 1, J = 1, V = 1.5 (mm units) with positions in 1/256 µm: ×256 000.
        let s = 256_000.0;
        for d_mm in [1u64, 2, 5, 10, 20, 50] {
            let p = profile(d_mm * 256_000, 1.5 * s, s, s, 0.05);
            let err = max_err(&p);
            assert!(err <= 0.5 + 1.0 / 256.0, "D = {d_mm} mm: {err}");
            let t_end = f64::from(p.end_tick()) * 0.05;
            let opt = p.plan().duration_s();
            assert!(t_end >= opt - 1e-9 && t_end < opt + 0.05 + 1e-9);
        }
    }

    #[test]
    fn velocity_and_acceleration_samples_match_plan() {
        let p = profile(10 * 256_000, 1.5 * 256e3, 256e3, 256e3, 0.01);
        assert_eq!(p.plan().regime, Regime::BothLimits);
        for k in 0..=p.end_tick() {
            let t = f64::from(k) * 0.01;
            let (_, v, a) = p.plan().state_at(t);
            let s = p.sample(k);
            assert!((p.vel_to_lsb_per_s(s.vel_q) - v).abs() < 1.0, "k {k}");
            assert!((p.acc_to_lsb_per_s2(s.acc_q) - a).abs() < 1.0, "k {k}");
        }
    }

    #[test]
    fn sub_tick_and_tiny_moves_end_exactly() {
        // Whole move shorter than one period: 0 at k = 0, D from k = 1.
        let p = profile(1000, 1e12, 1e15, 1e18, 0.001);
        assert_eq!(p.end_tick(), 1);
        assert_eq!((p.position_at(0), p.position_at(1)), (0, 1000));
        // One LSB.
        let p = profile(1, 10.0, 10.0, 10.0, 0.001);
        assert!(max_err(&p) <= 0.5 + 1.0 / 256.0);
    }

    #[test]
    fn longest_distance_fits() {
        let d = super::super::MAX_DISTANCE_LSB;
        let p = profile(d, 1e11, 1e10, 1e9, 0.01);
        assert!(max_err(&p) <= 0.5 + 1.0 / 256.0);
    }

    #[test]
    fn bad_period_and_too_long() {
        let plan = Plan::new(
            100,
            &Limits {
                vel_lsb_per_s: 1.0,
                acc_lsb_per_s2: 1.0,
                jerk_lsb_per_s3: 1.0,
            },
        )
        .unwrap();
        for t in [0.0, -1.0, f64::NAN, 1e6] {
            assert_eq!(Profile::new(&plan, t), Err(ScurveError::Period));
        }
        assert_eq!(Profile::new(&plan, 1e-9), Err(ScurveError::DurationTooLong));
    }
}
