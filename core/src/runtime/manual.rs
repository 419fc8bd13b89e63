//! Moving slaves by hand: jog with a deadman, move to a position by the S-curve, and the
//! approach to the table before following starts (the runtime's `Manual` state).
//!
//! Every slave in manual control follows a reference [`PosRef`] (position, velocity and
//! acceleration feed-forward) under the law's own position control
//! ([`super::Controller::tick_manual`]). Per slave the reference is one of:
//!
//! - **hold** at a position;
//! - **ramp** (jog): an online jerk-limited velocity ramp toward a target speed, renewed by
//!   the host; when no renewal came for [`JOG_DEADMAN_US`] the target speed becomes 0, so
//!   a host that stops sending (crash, cable) stops the axis. Once referenced, the ramp
//!   brakes so it stops inside the axis' limits;
//! - **move**: the time-optimal rest-to-rest 7-phase S-curve of [`crate::scurve`] from the
//!   held position to a target (planned once, sampled per tick).
//!
//! - **test**: the identification test move of [`super::test_move`] about the held
//!   position (step, chirp or PRBS), then a hold at that position.
//!
//! A move stopped early (Stop in manual, or a jog started on a moving axis) becomes a ramp
//! to speed 0 from the move's velocity and acceleration: no step in the reference. A test
//! stopped early holds at its centre (a step of at most its amplitude, like its own).
//!
//! ## The ramp, per tick (all quantities per tick, `i64` Q36 µm)
//!
//! ```text
//! tail(x) = x·|x|/(2J) − x/2        velocity gained ramping x to 0 at J per tick
//! x*      = the x with v + x + tail(x) = v_t: ±(√(J² + 8J·|v_t − v|) − J)/2
//! a'      = clamp(x*, max(a − J, −A), min(a + J, A))
//! v' = v + a',  p' = p + v'               (v' = v_t, a' = 0 once within J of it)
//! ```
//!
//! so |a| ≤ A and |Δa| ≤ J every tick. Braking for a limit: the distance to stop from
//! (v, a) is at most `v⁺·(|a|/J + 1) + v⁺·(v⁺/A + A/J)/2 + v⁺` with `v⁺ = max(|v|,
//! |v_coast|)` (the jerk-limited stop from rest acceleration needs `v·(v/A + A/J)/2` when
//! A is reached and `v·√(v/J)` ≤ that when it is not; the rest covers bringing a to 0
//! and one tick of margin); when the limit is nearer the target speed becomes 0, and the
//! position is clamped at the limit as the last guard.
//!
//! Q36 µm: resolution 1.5e-11 µm; positions up to 2^23 µm (the range of [`PosUm`]) are
//! below 2^59. A jerk of 1 mm/s³ at a 100 µs period is 1e-9 µm/tick³ = 69 LSB.

use super::test_move::{TestError, TestMove, TestSpec};
use crate::axis::PosRef;
use crate::scurve::{Limits, Plan, Profile};
use crate::units::{AccUmPerS2, PosUm, VelUmPerS};

/// A jog's deadman: the axis decelerates to rest when no jog command renewed it for this
/// long, µs (the host renews every 100 ms).
pub const JOG_DEADMAN_US: u32 = 300_000;

/// Fraction bits of the ramp's per-tick quantities.
const Q: u32 = 36;

/// Limits of a manual motion (a move, an approach, or a jog's acceleration and jerk).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionLimits {
    /// Velocity limit, µm/s (> 0; a jog's speed is its own).
    pub vel_um_per_s: u32,
    /// Acceleration limit, µm/s² (> 0).
    pub acc_um_per_s2: u32,
    /// Jerk limit, µm/s³ (> 0).
    pub jerk_um_per_s3: u32,
}

/// What a slave in manual control is doing (Status).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ManualKind {
    /// Holding a position (also: not in manual control).
    Hold,
    /// Jogging (or braking to rest).
    Jog,
    /// Moving by an S-curve.
    Move,
    /// Running an identification test move.
    Test,
}

impl ManualKind {
    /// Wire code: 0 hold, 1 jog, 2 move, 3 test.
    pub const fn code(self) -> u8 {
        match self {
            ManualKind::Hold => 0,
            ManualKind::Jog => 1,
            ManualKind::Move => 2,
            ManualKind::Test => 3,
        }
    }
}

/// Why a manual motion was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotionError {
    /// A limit (velocity, acceleration, jerk) is zero or too large for the period.
    Limits,
    /// The target is outside the axis' limits, or a jog points out of them.
    OutsideLimits,
    /// The axis is moving (a move is planned only from rest).
    Moving,
    /// The move cannot be planned (too long for the position format or the tick count).
    Plan,
    /// A test move's amplitude, duration, dwell or frequency is impossible
    /// ([`TestError::Spec`]).
    TestSpec,
    /// A test move's peak speed is above the axis' top speed.
    TooFast,
    /// A test move's step (`A`, PRBS `2A`) is not below the following-error limit.
    TestStep,
}

impl From<TestError> for MotionError {
    fn from(e: TestError) -> Self {
        match e {
            TestError::Spec => MotionError::TestSpec,
            TestError::OutsideLimits => MotionError::OutsideLimits,
            TestError::TooFast => MotionError::TooFast,
            TestError::Step => MotionError::TestStep,
        }
    }
}

/// Online jerk-limited velocity ramp (module docs), Q36 per tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ramp {
    p: i64,
    v: i64,
    a: i64,
    v_target: i64,
    acc: i64,
    jerk: i64,
    /// Position limits (min, max), Q36 µm; `None` while unreferenced.
    limits: Option<(i64, i64)>,
    /// Ticks until the deadman sets the target speed to 0.
    deadman: u32,
}

/// A planned S-curve move.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Move {
    from: PosUm,
    to: PosUm,
    negative: bool,
    profile: Profile,
    k: u32,
}

/// One slave's manual reference.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
// Every slave's slot can hold any of the three (no heap in `no_std`): its size is the
// move's, whichever it holds.
#[allow(clippy::large_enum_variant)]
enum AxisMotion {
    Hold(PosUm),
    Ramp(Ramp),
    Move(Move),
    Test(TestMove),
}

/// The manual references of every slave, and the period they are sampled at.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Manual<const S: usize> {
    axes: [AxisMotion; S],
    period_us: u32,
}

/// The velocity gained while acceleration `a` is ramped to 0 at `j` per tick after the
/// tick that applies it: `a·|a|/(2j) − a/2` (Q36 per tick; exact for the steps a − j,
/// a − 2j, … while they are ≥ j, so consecutive ticks agree on where the ramp ends).
fn tail(a: i64, j: i64) -> i64 {
    mul_div(a, a.saturating_abs(), j.max(1).saturating_mul(2)).saturating_sub(a / 2)
}

/// The acceleration x with `v + x + tail(x) = v_t`: the root of x² ± j·x − 2j·|v_t − v|,
/// `x = ±(√(j² + 8j·|v_t − v|) − j)/2`, signed as v_t − v.
/// Not inlined (nor [`mul_div`]): the 128-bit arithmetic is large on the M4 and only
/// the manual motions use it.
#[inline(never)]
fn accel_to_reach(v: i64, vt: i64, j: i64) -> i64 {
    let d = i128::from(vt).saturating_sub(i128::from(v));
    let j = i128::from(j.max(1));
    let disc = j
        .saturating_mul(j)
        .saturating_add(j.saturating_mul(8).saturating_mul(d.saturating_abs()));
    let root = i128::try_from(disc.unsigned_abs().isqrt()).unwrap_or(i128::MAX);
    let x = root.saturating_sub(j) / 2;
    let x = i64::try_from(x).unwrap_or(i64::MAX);
    if d < 0 {
        x.saturating_neg()
    } else {
        x
    }
}

/// `x · num / den` in i128, saturated to i64 (0 for den = 0).
#[inline(never)]
fn mul_div(x: i64, num: i64, den: i64) -> i64 {
    let p = i128::from(x).saturating_mul(i128::from(num));
    let q = p.checked_div(i128::from(den)).unwrap_or(0);
    i64::try_from(q).unwrap_or(if q < 0 { i64::MIN } else { i64::MAX })
}

/// A rate per second^n as a per-tick Q36 value: `x · (T/1 s)^n · 2^36`, `None` when it
/// is 0 or does not fit.
fn per_tick_q36(x_per_s: f64, period_us: u32, n: i32) -> Option<i64> {
    let t = f64::from(period_us) * 1e-6;
    let mut v = x_per_s * (1u64 << Q) as f64;
    for _ in 0..n {
        v *= t;
    }
    let r = libm::round(v);
    // Below 2^56: products of two such values in i128 and sums of a few stay in range.
    if r.is_finite() && r.abs() < (1u64 << 56) as f64 && r != 0.0 {
        Some(r as i64)
    } else {
        None
    }
}

fn q36_of(p: PosUm) -> i64 {
    i64::from(p.to_bits()).wrapping_shl(Q - 8)
}

fn pos_of_q36(p: i64) -> PosUm {
    // Q36 → Q8, rounded; |p| < 2^59 so the add cannot overflow.
    let q8 = p.saturating_add(1 << (Q - 9)) >> (Q - 8);
    PosUm::from_bits(i32::try_from(q8).unwrap_or(if q8 < 0 { i32::MIN } else { i32::MAX }))
}

impl Ramp {
    /// A ramp from position `p` at rest.
    fn at_rest(p: PosUm) -> Self {
        Self {
            p: q36_of(p),
            v: 0,
            a: 0,
            v_target: 0,
            acc: 1,
            jerk: 1,
            limits: None,
            deadman: 0,
        }
    }

    fn at_rest_now(&self) -> bool {
        self.v == 0 && self.a == 0 && self.v_target == 0
    }

    /// Distance to stop from the present velocity and acceleration (module docs), Q36 µm,
    /// in the direction of `v` (≥ 0).
    fn stop_distance(&self) -> i64 {
        let coast = self.v.saturating_add(self.coast());
        let v = self.v.unsigned_abs().max(coast.unsigned_abs());
        let v = i64::try_from(v).unwrap_or(i64::MAX);
        let a = self.a.saturating_abs();
        let t_a = mul_div(v, 1, self.acc); // v/A, ticks
        let t_j = mul_div(self.acc, 1, self.jerk); // A/J, ticks
        let t_n = mul_div(a, 1, self.jerk); // |a|/J, ticks
        let brake = mul_div(v, t_a.saturating_add(t_j), 2);
        v.saturating_mul(t_n.saturating_add(2))
            .saturating_add(brake)
    }

    /// The velocity gained while the present acceleration is ramped to 0 at J per tick.
    fn coast(&self) -> i64 {
        tail(self.a, self.jerk)
    }

    /// One tick; returns the reference.
    fn step(&mut self, period_us: u32) -> PosRef {
        self.deadman = self.deadman.saturating_sub(1);
        let mut vt = if self.deadman == 0 { 0 } else { self.v_target };
        if let Some((lo, hi)) = self.limits {
            let d = self.stop_distance();
            let heading_up = self.v > 0 || (self.v == 0 && vt > 0);
            let heading_down = self.v < 0 || (self.v == 0 && vt < 0);
            if (heading_up && self.p.saturating_add(d) >= hi)
                || (heading_down && self.p.saturating_sub(d) <= lo)
            {
                vt = 0;
            }
        }
        if vt == 0 {
            self.v_target = 0;
        }
        let (a, j, amax) = (self.a, self.jerk, self.acc);
        // The acceleration whose ramp to 0 ends at v_t, within the jerk and acceleration
        // limits of this tick.
        let lo = a.saturating_sub(j).max(amax.saturating_neg());
        let hi = a.saturating_add(j).min(amax);
        let a_next = accel_to_reach(self.v, vt, j).clamp(lo.min(hi), hi.max(lo));
        let mut v = self.v.saturating_add(a_next);
        let mut a_next = a_next;
        if v.saturating_sub(vt).saturating_abs() <= j && a.saturating_abs() <= j {
            v = vt;
            a_next = 0;
        }
        self.a = a_next;
        self.v = v;
        let before = self.p;
        self.p = self.p.saturating_add(v);
        if let Some((lo, hi)) = self.limits {
            // The last guard, only when this tick crosses a limit: a slave outside the
            // limits (set-position, drift with the valves off, re-referenced while
            // jogging) is braked, never stepped onto the limit.
            if (v > 0 && before <= hi && self.p > hi) || (v < 0 && before >= lo && self.p < lo) {
                self.p = self.p.clamp(lo, hi);
                self.v = 0;
                self.a = 0;
                self.v_target = 0;
            }
        }
        PosRef {
            x_ref_um: pos_of_q36(self.p),
            v_ff_um_per_s: vel_ff(self.v, Q - 8, period_us),
            a_ff_um_per_s2: acc_ff(self.a, Q, period_us),
        }
    }
}

/// A per-tick velocity with `shift` fraction bits above Q8 µm → µm/s, `I24F8`:
/// `v · 10^6 / T_us >> shift`.
fn vel_ff(v: i64, shift: u32, period_us: u32) -> VelUmPerS {
    VelUmPerS::from_bits(sat32(mul_div(v, 1_000_000, i64::from(period_us)) >> shift))
}

/// A per-tick acceleration with `shift` fraction bits (µm) → µm/s²:
/// `a · 10^12 / T_us² >> shift` (in two steps, each within i128).
fn acc_ff(a: i64, shift: u32, period_us: u32) -> AccUmPerS2 {
    let per_s = mul_div(a, 1_000_000, i64::from(period_us));
    AccUmPerS2::from_bits(sat32(
        mul_div(per_s, 1_000_000, i64::from(period_us)) >> shift,
    ))
}

fn sat32(x: i64) -> i32 {
    i32::try_from(x).unwrap_or(if x < 0 { i32::MIN } else { i32::MAX })
}

impl Move {
    /// The reference at the move's tick `k`, and the move's velocity and acceleration
    /// (Q36 per tick) for a ramp taking over.
    fn sample(&self, period_us: u32) -> (PosRef, i64, i64) {
        let s = self.profile.sample(self.k);
        let sign = |x: i64| if self.negative { x.saturating_neg() } else { x };
        let pos = i64::from(self.from.to_bits()).saturating_add(sign(s.pos_lsb));
        // Q14 LSB (1/256 µm) per tick → Q36 µm per tick: << (36 − 14 − 8).
        let v = sign(s.vel_q).saturating_mul(1 << (Q - 22));
        let a = sign(s.acc_q).saturating_mul(1 << (Q - 22));
        let r = PosRef {
            x_ref_um: PosUm::from_bits(sat32(pos)),
            // Q14 LSB (Q22 µm) per tick → Q8 µm/s (= LSB/s), µm/s².
            v_ff_um_per_s: vel_ff(sign(s.vel_q), 14, period_us),
            a_ff_um_per_s2: acc_ff(sign(s.acc_q), 22, period_us),
        };
        (r, v, a)
    }
}

impl<const S: usize> Manual<S> {
    /// Every slave holding at `pos` (entering manual control from rest).
    pub fn holding(pos: &[PosUm; S], period_us: u32) -> Self {
        Self {
            axes: pos.map(AxisMotion::Hold),
            period_us,
        }
    }

    /// What each slave is doing.
    pub fn kinds(&self) -> [ManualKind; S] {
        self.axes.map(|m| match m {
            AxisMotion::Hold(_) => ManualKind::Hold,
            AxisMotion::Ramp(_) => ManualKind::Jog,
            AxisMotion::Move(_) => ManualKind::Move,
            AxisMotion::Test(_) => ManualKind::Test,
        })
    }

    /// Whether every slave holds (no jog, no move in progress).
    pub fn at_rest(&self) -> bool {
        self.axes.iter().all(|m| matches!(m, AxisMotion::Hold(_)))
    }

    /// Where every slave holds, when all are at rest.
    pub fn held_positions(&self) -> Option<[PosUm; S]> {
        let mut out = [PosUm::ZERO; S];
        for (o, m) in out.iter_mut().zip(self.axes.iter()) {
            let AxisMotion::Hold(p) = m else {
                return None;
            };
            *o = *p;
        }
        Some(out)
    }

    /// Jogs slave `axis` at `speed` (renews the deadman; 0 brakes to rest) with the
    /// acceleration and jerk of `lim`; `limits` (min, max) once the axis is referenced.
    pub fn jog(
        &mut self,
        axis: usize,
        speed: VelUmPerS,
        lim: &MotionLimits,
        limits: Option<(PosUm, PosUm)>,
    ) -> Result<(), MotionError> {
        let period = self.period_us;
        let slot = self.axes.get_mut(axis).ok_or(MotionError::Limits)?;
        let acc = per_tick_q36(f64::from(lim.acc_um_per_s2), period, 2);
        let jerk = per_tick_q36(f64::from(lim.jerk_um_per_s3), period, 3);
        let (Some(acc), Some(jerk)) = (acc, jerk) else {
            return Err(MotionError::Limits);
        };
        let vt = if speed.to_bits() == 0 {
            0
        } else {
            per_tick_q36(speed.to_num::<f64>(), period, 1).ok_or(MotionError::Limits)?
        };
        let mut ramp = match *slot {
            AxisMotion::Ramp(r) => r,
            AxisMotion::Hold(p) => Ramp {
                acc,
                jerk,
                ..Ramp::at_rest(p)
            },
            AxisMotion::Move(m) => {
                let (r, v, a) = m.sample(period);
                Ramp {
                    v,
                    a,
                    acc,
                    jerk,
                    ..Ramp::at_rest(r.x_ref_um)
                }
            }
            // A test runs to its end (or Hold): a jog does not take it over.
            AxisMotion::Test(_) => return Err(MotionError::Moving),
        };
        let lims = limits.map(|(lo, hi)| (q36_of(lo), q36_of(hi)));
        if let Some((lo, hi)) = lims {
            // Refused when the jog points out of the limits from where the axis is. A slave
            // already jogging that way (it was just referenced by a home edge and is past
            // a limit in the new frame) brakes to rest, with the limits in force.
            if (vt > 0 && ramp.p >= hi) || (vt < 0 && ramp.p <= lo) {
                if let AxisMotion::Ramp(r) = slot {
                    if (vt > 0 && r.v > 0) || (vt < 0 && r.v < 0) {
                        r.v_target = 0;
                        r.limits = lims;
                    }
                }
                return Err(MotionError::OutsideLimits);
            }
        }
        // A renewal takes the jog's own acceleration and jerk (also after a braked move,
        // whose ramp had the move's).
        ramp.acc = acc;
        ramp.jerk = jerk;
        ramp.v_target = vt;
        ramp.limits = lims;
        ramp.deadman = JOG_DEADMAN_US.div_ceil(period.max(1)).saturating_add(1);
        *slot = AxisMotion::Ramp(ramp);
        Ok(())
    }

    /// Moves slave `axis` from where it holds to `to` by the S-curve of `lim`.
    pub fn move_to(
        &mut self,
        axis: usize,
        to: PosUm,
        lim: &MotionLimits,
    ) -> Result<(), MotionError> {
        let period = self.period_us;
        let slot = self.axes.get_mut(axis).ok_or(MotionError::Limits)?;
        let AxisMotion::Hold(from) = *slot else {
            return Err(MotionError::Moving);
        };
        *slot = AxisMotion::Move(plan_move(from, to, lim, period)?);
        Ok(())
    }

    /// Runs the test move `spec` on slave `axis` about where it holds, within `range`
    /// (min, max), the top speed `max_speed_um_per_s` (µm/s) and the following-error
    /// limit `max_error` ([`TestMove::new`]).
    pub fn test(
        &mut self,
        axis: usize,
        spec: &TestSpec,
        range: (PosUm, PosUm),
        max_speed_um_per_s: u32,
        max_error: PosUm,
    ) -> Result<(), MotionError> {
        let period = self.period_us;
        let slot = self.axes.get_mut(axis).ok_or(MotionError::Limits)?;
        let AxisMotion::Hold(center) = *slot else {
            return Err(MotionError::Moving);
        };
        *slot = AxisMotion::Test(TestMove::new(
            spec,
            center,
            range,
            max_speed_um_per_s,
            max_error,
            period,
        )?);
        Ok(())
    }

    /// Shifts slave `axis`' reference by `delta` (µm): its measured position moved by
    /// `delta` because the axis was just referenced (a home edge while jogging), so the
    /// reference follows and the error does not step.
    pub fn rebase(&mut self, axis: usize, delta: PosUm) {
        let shift = |p: PosUm| p.saturating_add(delta);
        let Some(m) = self.axes.get_mut(axis) else {
            return;
        };
        match m {
            AxisMotion::Hold(p) => *p = shift(*p),
            AxisMotion::Ramp(r) => r.p = r.p.saturating_add(q36_of(delta)),
            AxisMotion::Move(mv) => {
                mv.from = shift(mv.from);
                mv.to = shift(mv.to);
            }
            AxisMotion::Test(t) => t.rebase(delta),
        }
    }

    /// Brakes every moving slave to rest (a move becomes a ramp to speed 0).
    pub fn stop_all(&mut self) {
        let period = self.period_us;
        for m in &mut self.axes {
            match m {
                AxisMotion::Ramp(r) => r.v_target = 0,
                AxisMotion::Move(mv) => {
                    let (r, v, a) = mv.sample(period);
                    let lim = plan_limits(&mv.profile, period);
                    *m = AxisMotion::Ramp(Ramp {
                        v,
                        a,
                        acc: lim.0,
                        jerk: lim.1,
                        ..Ramp::at_rest(r.x_ref_um)
                    });
                }
                AxisMotion::Test(t) => *m = AxisMotion::Hold(t.center()),
                AxisMotion::Hold(_) => {}
            }
        }
    }

    /// This tick's reference of every slave; finished moves and ramps at rest become holds.
    pub fn step(&mut self) -> [PosRef; S] {
        let period = self.period_us;
        let mut out = [PosRef::default(); S];
        for (m, o) in self.axes.iter_mut().zip(out.iter_mut()) {
            *o = match m {
                AxisMotion::Hold(p) => PosRef {
                    x_ref_um: *p,
                    ..PosRef::default()
                },
                AxisMotion::Ramp(r) => {
                    let rf = r.step(period);
                    if r.at_rest_now() {
                        *m = AxisMotion::Hold(rf.x_ref_um);
                    }
                    rf
                }
                AxisMotion::Move(mv) => {
                    mv.k = mv.k.saturating_add(1);
                    let (rf, _, _) = mv.sample(period);
                    if mv.k >= mv.profile.end_tick() {
                        *m = AxisMotion::Hold(mv.to);
                    }
                    rf
                }
                AxisMotion::Test(t) => {
                    let rf = t.step();
                    if t.done() {
                        *m = AxisMotion::Hold(t.center());
                    }
                    rf
                }
            };
        }
        out
    }
}

/// The per-tick (acceleration, jerk) of a planned move, Q36 (for a ramp braking it).
fn plan_limits(p: &Profile, period_us: u32) -> (i64, i64) {
    // The plan is in LSB (1/256 µm) per second^n.
    let plan = p.plan();
    let acc = per_tick_q36(plan.peak_acc.max(1.0) / 256.0, period_us, 2).unwrap_or(1);
    let jerk = per_tick_q36(plan.jerk.max(1.0) / 256.0, period_us, 3).unwrap_or(1);
    (acc.max(1), jerk.max(1))
}

/// The S-curve from `from` to `to` under `lim` at `period_us`.
fn plan_move(
    from: PosUm,
    to: PosUm,
    lim: &MotionLimits,
    period_us: u32,
) -> Result<Move, MotionError> {
    if lim.vel_um_per_s == 0 || lim.acc_um_per_s2 == 0 || lim.jerk_um_per_s3 == 0 {
        return Err(MotionError::Limits);
    }
    let d = i64::from(to.to_bits()).saturating_sub(i64::from(from.to_bits()));
    // Limits in LSB (1/256 µm) per second^n.
    let limits = Limits {
        vel_lsb_per_s: f64::from(lim.vel_um_per_s) * 256.0,
        acc_lsb_per_s2: f64::from(lim.acc_um_per_s2) * 256.0,
        jerk_lsb_per_s3: f64::from(lim.jerk_um_per_s3) * 256.0,
    };
    let plan = Plan::new(d.unsigned_abs(), &limits).map_err(|_| MotionError::Limits)?;
    let profile =
        Profile::new(&plan, f64::from(period_us) * 1e-6).map_err(|_| MotionError::Plan)?;
    Ok(Move {
        from,
        to,
        negative: d < 0,
        profile,
        k: 0,
    })
}

#[cfg(test)]
mod tests;
