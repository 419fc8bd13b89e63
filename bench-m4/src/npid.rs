//! Nonlinear PID figure (SPEC §D): one axis of the cross-coupled nonlinear PID.
//!
//! `npid_td_fal`: [`Npid::track`] — TD-I on the reference, TD-II on the measurement
//! (two `fhan` evaluations), the integral, and the three `β·fal` terms. Gains: a
//! nonlinear axis setting (`axis_nonlinear`: β = (15, 1.6·20^0.2, 0), α = (1, 0.8, 1),
//! δ = (1 µm·s, 20 µm, 1 µm/s), TD r = 5·10⁷ µm/s², h0 = 1 ms, period 1 ms, integral
//! limit 1000 LSB / β0, output ±2047 LSB). host-sim's tuned X–Y gains
//! (`host-sim/src/xy/gains.rs`) have α1 = 1 (a linear fal, the identity path, cheaper);
//! the figure keeps α1 = 0.8 so that
//! it measures the fal power law a nonlinear setting pays — the conservative case. The reference moves at 50 mm/s (the scenario's feed: 50 µm per
//! period); the measurement lags it by one period with a ±3 µm ripple.
//!
//! Branches this exercises (per call): both TDs near fhan's `|y| = d0` boundary (at 50
//! mm/s the TD's steady lag gives |y| = h0·v = 50 µm = d0 = r·h0², so the ripple moves
//! them between the square-root zone and the linear zone) and in its linear `|a| ≤ d`
//! output zone; the proportional `fal` on its power law (|e1| ≈ 50 µm > δ1 = 20 µm, α1 =
//! 0.8: log2/exp2 tables); the integral term on its α = 1 identity path, integrating
//! until it reaches its clamp (the constant one-period lag is never removed here); the
//! β2 = 0 derivative term skipped (`TermMode::Off`).

use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::units::{CmdLsb, PosUm};
use hydra_xy::npid::{ErrorLaw, FalConfig, FhanConfig, Npid, NpidCoeffs, NpidConfig};

/// Reference advance per period, raw `PosUm` (50 µm).
const STEP_BITS: i32 = 50 << 8;

/// One nonlinear PID as host-sim's `xy/gains.rs` builds it: β, α, δ per term; TD r =
/// 5·10⁷ µm/s², h0 = 1 ms; period 1 ms; |β0·e0| ≤ 1000 LSB; output ±2047 LSB.
fn nl(beta: [f64; 3], alpha: [f64; 3], delta: [f64; 3]) -> Option<NpidCoeffs> {
    let td = FhanConfig {
        r_um_per_s2: 5e7,
        h0_s: 1e-3,
    };
    let fal = |i: usize| FalConfig {
        alpha: alpha[i],
        delta: delta[i],
    };
    NpidConfig {
        period_s: 1e-3,
        td_reference: td,
        td_measurement: td,
        beta0: beta[0],
        beta1: beta[1],
        beta2: beta[2],
        fal0: fal(0),
        fal1: fal(1),
        fal2: fal(2),
        integral_limit_um_s: if beta[0] > 0.0 {
            (1000.0 / beta[0]).min(1e6)
        } else {
            0.0
        },
        output_limit_lsb: 2047.0,
    }
    .build()
    .ok()
}

/// A nonlinear axis law (`axis_nonlinear`): small-signal kp 1.6 LSB/µm through fal, β =
/// (15, 1.6·20^0.2, 0), α = (1, 0.8, 1), δ = (1 µm·s, 20 µm, 1 µm/s).
pub fn axis_coeffs() -> Option<NpidCoeffs> {
    nl(
        [15.0, 2.912_902_724_841_728, 0.0],
        [1.0, 0.8, 1.0],
        [1.0, 20.0, 1.0],
    )
}

/// A nonlinear contour law (`contour_nonlinear`): small-signal kc 0.2 LSB/µm through fal,
/// β = (0, 0.2·5^0.5, 0), α = (1, 0.5, 1), δ = (1 µm·s, 5 µm, 1 µm/s).
pub fn contour_coeffs() -> Option<NpidCoeffs> {
    nl(
        [0.0, 0.447_213_595_499_958, 0.0],
        [1.0, 0.5, 1.0],
        [1.0, 5.0, 1.0],
    )
}

/// The measured call: one period of the axis law.
#[inline(never)]
fn track(n: &mut Npid, c: &NpidCoeffs, reference: PosUm, measured: PosUm) -> CmdLsb {
    n.track(c, reference, measured)
}

/// `npid_td_fal`.
pub struct NpidTrack {
    c: NpidCoeffs,
    n: Npid,
    reference: PosUm,
    measured: PosUm,
    out: CmdLsb,
}

impl NpidTrack {
    /// The law at rest at 0.
    pub fn new() -> Option<Self> {
        Some(Self {
            c: axis_coeffs()?,
            n: Npid::at_rest(PosUm::ZERO),
            reference: PosUm::ZERO,
            measured: PosUm::ZERO,
            out: CmdLsb::ZERO,
        })
    }

    /// Inputs of call `k`: the reference at 50 µm per period, the measurement one period
    /// behind with a ±3 µm ripple (period 16 calls).
    #[inline(always)]
    fn next_inputs(&mut self, k: u32) {
        let r = (k as i32).wrapping_mul(STEP_BITS);
        let ripple = ((k & 15) as i32 - 8) * (3 << 8) / 8;
        self.reference = PosUm::from_bits(r);
        self.measured = PosUm::from_bits(r.wrapping_sub(STEP_BITS).wrapping_add(ripple));
    }
}

impl Figure for NpidTrack {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.next_inputs(k);
        self.out = track(&mut self.n, &self.c, self.reference, self.measured);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.next_inputs(k);
        black_box(&mut self.reference);
        black_box(&mut self.measured);
        black_box(&mut self.out);
    }

    /// The command stays inside the DAC range without saturating.
    fn healthy(&self) -> bool {
        self.out.saturating_abs() < CmdLsb::from_num(2047)
    }
}
