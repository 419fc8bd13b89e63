//! The per-tick position control laws of one slave axis.
//!
//! **Feedforward / NextNode** (positional):
//!
//! ```text
//! e(k)  = x_ref(k) − x(k)                                   µm
//! I(k)  = clamp(I(k−1) + s_I·Ki·T·e(k), ±I_max)   only if |e| ≤ m and the output is not
//!                                              saturated in the direction of e
//! u(k)  = s·(Kp·e + (Kd/T)·(e(k) − e(k−1))) + I + kv±·v_ff + ka·a_ff      LSB
//! ```
//!
//! (s ≤ 1, s_I ≤ 1: the gain backoff's scales of a following Feedforward axis,
//! [`super::backoff`]; 1 elsewhere.)
//!
//! **Paper** (SPEC §A eq. 6–9, incremental, integral separation):
//!
//! ```text
//! ΔU = Kp·(e − e1) + β·Ki·T·e + (Kd/T)·(e − 2e1 + e2),  β = [|e| ≤ m]
//! U  = clamp(U + ΔU, ±clamp)
//! ```
//!
//! Every product is a 32×32→64-bit multiply and a shift ([`crate::fixed_point::mul_shr_floor_sat`]); every
//! sum saturates. The command then goes through the valve output stage
//! ([`crate::valve::ValveCoeffs::output`]).

use super::backoff::BackoffState;
use super::config::{AxisCoeffs, ControlMode};
use crate::fixed_point::{clamp_sym, mul_shr_floor_sat, sat_i32};
use crate::units::{AccUmPerS2, CmdLsb, DacCode, PosUm, VelUmPerS};

/// What the follower computed for one axis this tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PosRef {
    /// The position the feedback acts on, µm: the table at the master estimate now
    /// (Feedforward), at the predicted master (Paper), or the next node (NextNode).
    pub x_ref_um: PosUm,
    /// Target velocity over the interval in which the command acts, µm/s.
    pub v_ff_um_per_s: VelUmPerS,
    /// Target acceleration, µm/s².
    pub a_ff_um_per_s2: AccUmPerS2,
}

/// Control state of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PosState {
    /// e(k−1), e(k−2), `I24F8` raw µm.
    e1: i32,
    e2: i32,
    /// Integrator (Feedforward/NextNode), `I16F16` raw LSB.
    integ: i32,
    /// U(k) of the incremental law (Paper), `I16F16` raw LSB.
    u_paper: i32,
    /// Whether e1/e2 hold real samples. After the first tick e1 = e2 = e(0), so one flag
    /// gives the same history as counting to two.
    primed: bool,
}

impl PosState {
    /// The reset state (the same as `Default`, as a `const`).
    pub(crate) const RESET: Self = Self {
        e1: 0,
        e2: 0,
        integ: 0,
        u_paper: 0,
        primed: false,
    };
}

impl PosState {
    /// Forgets the history and the integrator (after a fault or a mode change).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Integrator content, LSB.
    pub fn integrator(&self) -> CmdLsb {
        CmdLsb::from_bits(self.integ)
    }

    /// Sets the integrator so the positional law continues from `u` (bumpless entry).
    pub fn preset(&mut self, u: CmdLsb) {
        self.integ = u.to_bits();
        self.u_paper = u.to_bits();
    }

    /// Hands `took` (`I16F16` LSB raw) of the integrator over to the feed-forward trim
    /// ([`super::ff_trim`]): the integrator gives it up.
    #[inline(always)]
    pub(crate) fn offload_to_trim(
        &mut self,
        trim: &mut super::ff_trim::FfTrimState,
        c: &super::ff_trim::FfTrimCoeffs,
        ff: i32,
    ) {
        let took = trim.offload(c, ff, self.integ);
        self.integ = self.integ.saturating_sub(took);
    }

    /// (e(k−1), e(k−2)) for the error `e` of this tick (both `e` on the first tick).
    #[inline(always)]
    fn history(&self, e: i32) -> (i32, i32) {
        if self.primed {
            (self.e1, self.e2)
        } else {
            (e, e)
        }
    }

    /// e − e(k−1), µm `I24F8` raw: the error's change since the last tick (0 on the first
    /// after a reset), before `e` enters the history.
    #[inline(always)]
    pub fn error_change(&self, e: i32) -> i32 {
        let (e1, _) = self.history(e);
        e.saturating_sub(e1)
    }

    /// Shifts `e` into the history.
    #[inline(always)]
    fn push(&mut self, e: i32, e1: i32) {
        self.e2 = e1;
        self.e1 = e;
        self.primed = true;
    }
}

/// One tick of the position law: returns the command before the output stage.
#[inline]
pub fn position_law(c: &AxisCoeffs, st: &mut PosState, r: &PosRef, x: PosUm) -> CmdLsb {
    let e = r.x_ref_um.to_bits().saturating_sub(x.to_bits());
    let u = match c.mode {
        ControlMode::Paper => paper_law_bits(c, st, e),
        ControlMode::Feedforward | ControlMode::NextNode => positional_law_bits(
            c,
            st,
            e,
            r.v_ff_um_per_s.to_bits(),
            r.a_ff_um_per_s2.to_bits(),
        ),
    };
    CmdLsb::from_bits(u)
}

/// The integrator step Ki·T·e, `I16F16` LSB, for |e| ≤ m (inside the integration zone):
/// e (Q8) · Ki·T (Q24) = Q32 → >> 16. [`super::AxisConfig::build`] bounds m·Ki·T below
/// 2^47 (Q32), so the step is below 2^31 and needs no saturation.
#[inline(always)]
fn integ_step(c: &AxisCoeffs, e: i32) -> i32 {
    (i64::from(e).wrapping_mul(i64::from(c.ki_tick)) >> 16) as i32
}

/// The Paper law (eq. 6–9) on raw values: error `e` (`I24F8` µm) → U (`I16F16` LSB,
/// within ±clamp).
#[inline(always)]
pub(crate) fn paper_law_bits(c: &AxisCoeffs, st: &mut PosState, e: i32) -> i32 {
    let (e1, e2) = st.history(e);
    let clamp = c.valve.clamp_lsb().to_bits();
    // e (Q8) · gain (Q16) = Q24 → >> 8 = Q16;  e (Q8) · gain (Q24) = Q32 → >> 16 = Q16.
    let de = e.saturating_sub(e1);
    let dde = de.saturating_sub(e1.saturating_sub(e2));
    let mut du =
        mul_shr_floor_sat(de, c.kp, 8).saturating_add(mul_shr_floor_sat(dde, c.kd_tick, 8));
    if e.saturating_abs() <= c.i_zone {
        du = du.saturating_add(integ_step(c, e));
    }
    st.u_paper = clamp_sym(st.u_paper.saturating_add(du), clamp);
    st.push(e, e1);
    st.u_paper
}

/// The positional law (Feedforward, NextNode) on raw values: error `e` (`I24F8` µm),
/// target speed `v` (`I24F8` µm/s), target acceleration `a` (µm/s²) → u (`I16F16` LSB,
/// within ±clamp).
#[inline(always)]
pub(crate) fn positional_law_bits(
    c: &AxisCoeffs,
    st: &mut PosState,
    e: i32,
    v: i32,
    a: i32,
) -> i32 {
    let kv = if v >= 0 { c.kv_pos } else { c.kv_neg };
    // Validated gains are non-negative and below 2^31: each product is below 2^62 and
    // their sum below 2^63 (Q8 · Q24 = Q32 and Q0 · Q32 = Q32).
    let ff32 = i64::from(v)
        .wrapping_mul(i64::from(kv))
        .wrapping_add(i64::from(a).wrapping_mul(i64::from(c.ka)));
    positional_law_ff(c, st, e, sat_i32(ff32 >> 16))
}

/// [`positional_law_bits`] with the feed-forward kv±·v + ka·a already worked out: `ff`,
/// `I16F16` LSB (the follower's per-segment constants, see `follower::ff_plan`).
#[inline(always)]
pub(crate) fn positional_law_ff(c: &AxisCoeffs, st: &mut PosState, e: i32, ff: i32) -> i32 {
    positional_law_with::<false>(c, st, e, ff, &BackoffState::RESET)
}

/// [`positional_law_ff`]'s body; with `B` the proportional and derivative terms and the
/// integrator step are scaled at the gain backoff's level `bo` ([`super::backoff`]) —
/// decided at compile time, so the law without it has no trace of it.
#[inline(always)]
pub(crate) fn positional_law_with<const B: bool>(
    c: &AxisCoeffs,
    st: &mut PosState,
    e: i32,
    ff: i32,
    bo: &BackoffState,
) -> i32 {
    let (e1, _) = st.history(e);
    let clamp = c.valve.clamp_lsb().to_bits();
    // Validated gains are non-negative and below 2^31 (kp < 2^26), so each
    // product is below 2^62 and the pair's sum below 2^63: no overflow.
    // P + D in Q24 (e Q8 · gain Q16), shifted to Q16 and saturated to 32 bits, then one
    // saturating 32-bit add (`qadd`): cheaper on the Cortex-M4 than a 64-bit sum and a
    // 64-bit clamp.
    let pd24 = i64::from(e)
        .wrapping_mul(i64::from(c.kp))
        .wrapping_add(i64::from(e.saturating_sub(e1)).wrapping_mul(i64::from(c.kd_tick)));
    let pd = sat_i32(pd24 >> 8);
    let base = if B { bo.scale(pd) } else { pd }.saturating_add(ff);
    if e.saturating_abs() <= c.i_zone {
        let step = integ_step(c, e);
        let step = if B { bo.scale_i(step) } else { step };
        let cand = clamp_sym(st.integ.saturating_add(step), c.i_limit);
        let u_try = base.saturating_add(cand);
        // Anti-windup: never integrate further into a saturated output.
        let winding =
            (u_try > clamp && cand > st.integ) || (u_try < clamp.wrapping_neg() && cand < st.integ);
        if !winding {
            st.integ = cand;
        }
    }
    st.push(e, e1);
    clamp_sym(base.saturating_add(st.integ), clamp)
}

/// The valve code for a command (the axis' output stage).
#[inline]
pub fn output(c: &AxisCoeffs, u: CmdLsb) -> DacCode {
    c.valve.output(u)
}

#[cfg(test)]
mod tests {
    use super::super::config::{AxisConfig, PositionGains};
    use super::*;
    use proptest::prelude::*;

    fn coeffs(mode: ControlMode) -> AxisCoeffs {
        AxisConfig {
            gains: PositionGains {
                kp_lsb_per_um: 0.5,
                ki_lsb_per_um_s: 20.0,
                kd_lsb_s_per_um: 0.0,
                i_zone_um: 100.0,
                i_limit_lsb: 50.0,
                kv_pos_lsb_per_um_s: 0.02,
                kv_neg_lsb_per_um_s: 0.01,
                ..PositionGains::default()
            },
            mode,
            ..AxisConfig::default()
        }
        .build(1000)
        .unwrap()
    }

    fn r(x: f64, v: f64) -> PosRef {
        PosRef {
            x_ref_um: PosUm::from_num(x),
            v_ff_um_per_s: VelUmPerS::from_num(v),
            a_ff_um_per_s2: AccUmPerS2::ZERO,
        }
    }

    #[test]
    fn feedforward_terms_add_up() {
        let c = coeffs(ControlMode::Feedforward);
        let mut st = PosState::default();
        // e = 10 µm (inside zone): P 5 + I 0.2 + FF 0.02·1000 = 25.2
        let u = position_law(&c, &mut st, &r(110.0, 1000.0), PosUm::from_num(100));
        assert!((u.to_num::<f64>() - 25.2).abs() < 1e-3, "{u}");
        // negative speed uses kv⁻
        let mut st = PosState::default();
        let u = position_law(&c, &mut st, &r(100.0, -1000.0), PosUm::from_num(100));
        assert!((u.to_num::<f64>() + 10.0).abs() < 1e-3, "{u}");
    }

    #[test]
    fn integral_separation_and_clamp() {
        let c = coeffs(ControlMode::Feedforward);
        let mut st = PosState::default();
        // outside the zone: no integration
        position_law(&c, &mut st, &r(1000.0, 0.0), PosUm::ZERO);
        assert_eq!(st.integrator(), CmdLsb::ZERO);
        // inside: integrates up to the clamp of 50 LSB
        for _ in 0..10_000 {
            position_law(&c, &mut st, &r(50.0, 0.0), PosUm::ZERO);
        }
        assert_eq!(st.integrator(), CmdLsb::from_num(50));
    }

    #[test]
    fn paper_law_is_incremental() {
        let c = coeffs(ControlMode::Paper);
        let mut st = PosState::default();
        // first tick: ΔU = Kp·0 + Ki·T·e = 0.02·10 = 0.2
        let u1 = position_law(&c, &mut st, &r(10.0, 0.0), PosUm::ZERO);
        assert!((u1.to_num::<f64>() - 0.2).abs() < 1e-3);
        // e: 10 → 20: ΔU = 0.5·10 + 0.02·20 = 5.4
        let u2 = position_law(&c, &mut st, &r(20.0, 0.0), PosUm::ZERO);
        assert!((u2.to_num::<f64>() - 5.6).abs() < 1e-3, "{u2}");
        // outside the zone (e = 200 > 100): β = 0
        let u3 = position_law(&c, &mut st, &r(200.0, 0.0), PosUm::ZERO);
        assert!((u3.to_num::<f64>() - (5.6 + 90.0)).abs() < 1e-3, "{u3}");
    }

    proptest! {
        #[test]
        fn output_within_clamp_and_integrator_within_limit(
            steps in proptest::collection::vec((any::<i32>(), any::<i32>(), any::<i32>(), any::<i32>()), 1..200),
            mode in prop_oneof![Just(ControlMode::Feedforward), Just(ControlMode::Paper), Just(ControlMode::NextNode)],
            clamp in 1u16..2047, ilim in 0.0f32..2047.0, ka in 0.0f32..0.4)
        {
            let mut cfg = AxisConfig {
                gains: PositionGains {
                    kp_lsb_per_um: 3.0,
                    ki_lsb_per_um_s: 500.0,
                    kd_lsb_s_per_um: 0.01,
                    i_limit_lsb: ilim,
                    kv_pos_lsb_per_um_s: 0.5,
                    kv_neg_lsb_per_um_s: 0.5,
                    ka_lsb_per_um_s2: ka,
                    ..PositionGains::default()
                },
                mode,
                ..AxisConfig::default()
            };
            cfg.valve.clamp_lsb = clamp;
            let c = cfg.build(1000).unwrap();
            let mut st = PosState::default();
            for (x_ref, v, a, x) in steps {
                let rr = PosRef { x_ref_um: PosUm::from_bits(x_ref), v_ff_um_per_s: VelUmPerS::from_bits(v),
                                  a_ff_um_per_s2: AccUmPerS2::from_bits(a) };
                let u = position_law(&c, &mut st, &rr, PosUm::from_bits(x));
                prop_assert!(u.to_bits().abs() <= i32::from(clamp) << 16);
                prop_assert!(st.integrator().to_bits().abs() <= c.i_limit);
                prop_assert!(i32::from(output(&c, u).get()).abs() <= i32::from(clamp));
            }
        }
    }
}
