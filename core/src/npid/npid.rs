//! The single-axis nonlinear PID of SPEC §D.
//!
//! ```text
//! TD-I:  (z11, z12) tracks the reference v(k)       (position µm, velocity µm/s)
//! TD-II: (z21, z22) tracks the measurement y(k)
//! e1 = z11 − z21  [µm],   e2 = z12 − z22  [µm/s],   e0(k) = e0(k−1) + e1·h  [µm·s]
//! u  = β0·fal(e0, α0, δ0) + β1·fal(e1, α1, δ1) + β2·fal(e2, α2, δ2)   [DAC LSB]
//! ```
//!
//! β0 is in LSB/(µm·s)^α0, β1 in LSB/µm^α1, β2 in LSB/(µm/s)^α2. The output is clamped
//! to ±`output_limit_lsb`; `e0` is clamped to ±`integral_limit_um_s` and, as anti-windup,
//! not integrated in the direction that pushes an output already at its limit further.
//!
//! For the contour loop ([`super::ccc`]) the same law runs on an error signal: TD-I
//! tracks ε(k) (`e1 = z11`, `e2 = z12`) and TD-II is not used ([`Npid::regulate`]).
//!
//! Formats: TD states µm and µm/s in Q16 (`i64`, |z1| ≤ 2⁴¹, |z2| ≤ 2³⁹), `e0` µm·s in
//! Q32 (`i64`, ≤ 10⁶·2³² < 2⁵²), β in Q24 (≤ 10⁶·2²⁴ < 2⁴⁴), the output [`CmdLsb`].
//!
//! **Cost.** Every product is an `i64` product bounded below 2⁶³ (no `i128` routine on
//! the Cortex-M4): `e1·h` by the TD clamps, `β·fal` by clamping each `fal` value to
//! `|fal| ≤ 2⁶²/β_q24` first, i.e. each term to ±2²² LSB. That clamp only acts when a
//! single term alone exceeds 2²² LSB (2000 × the DAC range), where the old `i128` form
//! would have given the same clamped output unless the other terms cancelled more than
//! 4·10⁶ LSB of it. The build decides per term (`TermMode`): a term with β = 0 is
//! skipped, and the clamp is left out where `|fal|` over the term's whole input range
//! (`|e0| ≤` integral limit, `|e1| ≤ 2⁴²`, `|e2| ≤ 2⁴⁰` in Q16) cannot reach it.

use super::fal::{fal, FalCoeffs, FalConfig};
use super::fhan::FhanConfig;
use super::fxmath::mul_bounded_shr;
use super::td::{Td, TdCoeffs, TdConfig};
use super::{ErrorLaw, NpidError};
use crate::units::{CmdLsb, PosUm};

/// Nonlinear PID parameters in engineering units (validated by [`NpidConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NpidConfig {
    /// Control period h, s (10 µs … 10 ms): the TD step and the integration step.
    pub period_s: f64,
    /// TD-I (reference) speed and filter factors.
    pub td_reference: FhanConfig,
    /// TD-II (measurement) speed and filter factors.
    pub td_measurement: FhanConfig,
    /// β0, LSB/(µm·s)^α0 (0 … 10⁶).
    pub beta0: f64,
    /// β1, LSB/µm^α1 (0 … 10⁶).
    pub beta1: f64,
    /// β2, LSB/(µm/s)^α2 (0 … 10⁶).
    pub beta2: f64,
    /// `fal` of the integral term (e0 in µm·s).
    pub fal0: FalConfig,
    /// `fal` of the proportional term (e1 in µm).
    pub fal1: FalConfig,
    /// `fal` of the derivative term (e2 in µm/s).
    pub fal2: FalConfig,
    /// Clamp of |e0|, µm·s (0 … 10⁶).
    pub integral_limit_um_s: f64,
    /// Clamp of |u|, LSB (1 … 2047).
    pub output_limit_lsb: f64,
}

/// Validated nonlinear PID coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NpidCoeffs {
    td_ref: TdCoeffs,
    td_meas: TdCoeffs,
    /// β0, β1, β2 in Q24.
    beta_q24: [i64; 3],
    /// Clamp of each `fal` value before its product, Q16: `2⁶²/β_q24` (`i64::MAX` for
    /// β = 0), so `|β·fal|` ≤ 2⁶² in Q40.
    fal_max_q16: [i64; 3],
    /// How each term is evaluated.
    mode: [TermMode; 3],
    fal: [FalCoeffs; 3],
    /// e0 clamp, µm·s Q32.
    e0_max_q32: i64,
    /// Output clamp, LSB Q16.
    u_max_q16: i64,
}

/// How a term `β·fal(e)` of the law is evaluated (chosen by [`NpidConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum TermMode {
    /// β = 0: the term is zero.
    Off,
    /// `|fal|` over the whole input range stays below the clamp: plain product.
    Direct,
    /// `fal` clamped to `±2⁶²/β_q24` before the product.
    Clamped,
}

fn gain_q24(b: f64, term: u8) -> Result<i64, NpidError> {
    if b.is_finite() && (0.0..=1e6).contains(&b) {
        Ok((b * 16_777_216.0 + 0.5) as i64)
    } else {
        Err(NpidError::Gain(term))
    }
}

impl NpidConfig {
    /// Validates every parameter; the error names the first bad one.
    pub fn build(&self) -> Result<NpidCoeffs, NpidError> {
        let h = self.period_s;
        let td = |f: &FhanConfig| TdConfig {
            r_um_per_s2: f.r_um_per_s2,
            h0_s: f.h0_s,
            h_s: h,
        };
        let td_ref = td(&self.td_reference)
            .build()
            .map_err(NpidError::TdReference)?;
        let td_meas = td(&self.td_measurement)
            .build()
            .map_err(NpidError::TdMeasurement)?;
        let fal = [
            self.fal0.build().map_err(|e| NpidError::Fal(0, e))?,
            self.fal1.build().map_err(|e| NpidError::Fal(1, e))?,
            self.fal2.build().map_err(|e| NpidError::Fal(2, e))?,
        ];
        let beta_q24 = [
            gain_q24(self.beta0, 0)?,
            gain_q24(self.beta1, 1)?,
            gain_q24(self.beta2, 2)?,
        ];
        let il = self.integral_limit_um_s;
        if !(il.is_finite() && (0.0..=1e6).contains(&il)) {
            return Err(NpidError::IntegralLimit);
        }
        let ol = self.output_limit_lsb;
        if !(ol.is_finite() && (1.0..=2047.0).contains(&ol)) {
            return Err(NpidError::OutputLimit);
        }
        let fal_max = |b: i64| (1i64 << 62).checked_div(b).unwrap_or(i64::MAX);
        let [b0, b1, b2] = beta_q24;
        let e0_max_q32 = (il * 4_294_967_296.0) as i64;
        // Largest |input| of each term, Q16: e0 (the integral limit), e1 (2^42: two TD
        // positions of ±2^41), e2 (2^40: two TD velocities of ±2^39).
        let bounds = [e0_max_q32 >> 16, 1i64 << 42, 1i64 << 40];
        let mode = |i: usize| {
            let b = beta_q24.get(i).copied().unwrap_or(0);
            let (Some(f), Some(&e)) = (fal.get(i), bounds.get(i)) else {
                return TermMode::Clamped;
            };
            // fal is odd and (up to 2^-12 relative, see its tests) monotone: the largest
            // |fal| is at the bound; keep a 1/256 margin.
            let out = super::fal::fal(f, e).unsigned_abs();
            if b == 0 {
                TermMode::Off
            } else if out.saturating_add(out >> 8).saturating_add(1) <= fal_max(b) as u64 {
                TermMode::Direct
            } else {
                TermMode::Clamped
            }
        };
        Ok(NpidCoeffs {
            td_ref,
            td_meas,
            beta_q24,
            fal_max_q16: [fal_max(b0), fal_max(b1), fal_max(b2)],
            mode: [mode(0), mode(1), mode(2)],
            fal,
            e0_max_q32,
            u_max_q16: (ol * 65536.0) as i64,
        })
    }
}

/// Nonlinear PID state (two TDs, the integral, the last saturation direction).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Npid {
    td_ref: Td,
    td_meas: Td,
    /// e0, µm·s Q32.
    e0_q32: i64,
    /// −1/0/+1: the output was clamped at −limit / not clamped / +limit.
    sat: i8,
}

impl Npid {
    /// Both TDs at rest at `position_um`, integral zero.
    pub fn at_rest(position_um: PosUm) -> Self {
        Self {
            td_ref: Td::at_rest(position_um),
            td_meas: Td::at_rest(position_um),
            e0_q32: 0,
            sat: 0,
        }
    }

    /// The tracked reference (TD-I).
    pub fn td_reference(&self) -> &Td {
        &self.td_ref
    }

    /// The tracked measurement (TD-II).
    pub fn td_measurement(&self) -> &Td {
        &self.td_meas
    }

    /// `u` from `e1` (µm Q8) and `e2` (µm/s Q8), integrating `e0` first.
    #[inline(always)]
    fn law(&mut self, c: &NpidCoeffs, e1_q8: i32, e2_q8: i32) -> CmdLsb {
        let [f0, f1, f2] = &c.fal;
        let [b0, b1, b2] = c.beta_q24;
        let [m0, m1, m2] = c.fal_max_q16;
        let [k0, k1, k2] = c.mode;
        // Conditional integration: not while the output is clamped and e1 pushes further
        // into the clamp (e1 = 0 adds nothing either way).
        let push = if self.sat > 0 {
            e1_q8 > 0
        } else if self.sat < 0 {
            e1_q8 < 0
        } else {
            false
        };
        if !push {
            // Q8·Q32 >> 8 = Q32: one `smull`, |e1·h| < 2^31·2^26.
            let de0 = i64::from(e1_q8)
                .wrapping_mul(i64::from(c.td_ref.h_q32()))
                .wrapping_shr(8);
            // |e0| ≤ 2^52 before the add: no overflow.
            self.e0_q32 = self
                .e0_q32
                .wrapping_add(de0)
                .clamp(c.e0_max_q32.wrapping_neg(), c.e0_max_q32);
        }
        let e1 = i64::from(e1_q8).wrapping_shl(8);
        let e2 = i64::from(e2_q8).wrapping_shl(8);
        // β·fal with |fal| ≤ 2^62/β: each product ≤ 2^62, each term ≤ 2^38 (Q16), the
        // sum ≤ 3·2^38.
        let term = |k: TermMode, f: &FalCoeffs, e: i64, b: i64, m: i64| {
            if k == TermMode::Off {
                return 0;
            }
            let v = fal(f, e);
            let v = if k == TermMode::Clamped {
                v.clamp(m.wrapping_neg(), m)
            } else {
                v
            };
            mul_bounded_shr(v, b, 24)
        };
        let u = term(k0, f0, self.e0_q32.wrapping_shr(16), b0, m0)
            .wrapping_add(term(k1, f1, e1, b1, m1))
            .wrapping_add(term(k2, f2, e2, b2, m2));
        let lim = c.u_max_q16;
        let (u, sat) = if u > lim {
            (lim, 1)
        } else if u < lim.wrapping_neg() {
            (lim.wrapping_neg(), -1)
        } else {
            (u, 0)
        };
        self.sat = sat;
        // |u| ≤ 2047·2^16 < 2^31.
        CmdLsb::from_bits(u as i32)
    }
}

impl ErrorLaw for Npid {
    type Coeffs = NpidCoeffs;

    /// One period of the axis law: TD-I on the reference, TD-II on the measurement.
    #[inline]
    fn track(&mut self, c: &NpidCoeffs, reference_um: PosUm, measured_um: PosUm) -> CmdLsb {
        self.td_ref.step(&c.td_ref, reference_um);
        self.td_meas.step(&c.td_meas, measured_um);
        // Saturating (±8.4 m); |z2| ≤ 2^30 (TD clamp): the velocity difference fits.
        let e1 = self.td_ref.z1_q8().saturating_sub(self.td_meas.z1_q8());
        let e2 = self.td_ref.z2_q8().saturating_sub(self.td_meas.z2_q8());
        self.law(c, e1, e2)
    }

    /// One period of the law on an error signal (TD-I only).
    #[inline]
    fn regulate(&mut self, c: &NpidCoeffs, error_um: PosUm) -> CmdLsb {
        self.td_ref.step(&c.td_ref, error_um);
        self.law(c, self.td_ref.z1_q8(), self.td_ref.z2_q8())
    }

    fn reset(&mut self, position_um: PosUm) {
        *self = Self::at_rest(position_um);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn config() -> NpidConfig {
        let td = FhanConfig {
            r_um_per_s2: 2e7,
            h0_s: 2e-3,
        };
        NpidConfig {
            period_s: 1e-3,
            td_reference: td,
            td_measurement: td,
            beta0: 2.0,
            beta1: 1.0,
            beta2: 0.002,
            fal0: FalConfig {
                alpha: 1.0,
                delta: 1.0,
            },
            fal1: FalConfig {
                alpha: 0.7,
                delta: 20.0,
            },
            fal2: FalConfig {
                alpha: 1.0,
                delta: 1.0,
            },
            integral_limit_um_s: 500.0,
            output_limit_lsb: 2047.0,
        }
    }

    #[test]
    fn builds_and_names_bad_parameters() {
        assert!(config().build().is_ok());
        let mut c = config();
        c.beta1 = -1.0;
        assert_eq!(c.build(), Err(NpidError::Gain(1)));
        let mut c = config();
        c.fal2.alpha = 3.0;
        assert_eq!(
            c.build(),
            Err(NpidError::Fal(2, super::super::FalError::Alpha))
        );
        let mut c = config();
        // h0 = 0.5 ms < h (d0 = r·h0² = 5 µm is still valid).
        c.td_measurement.h0_s = 5e-4;
        assert_eq!(
            c.build(),
            Err(NpidError::TdMeasurement(
                super::super::TdError::FilterBelowStep
            ))
        );
        let mut c = config();
        c.output_limit_lsb = 5000.0;
        assert_eq!(c.build(), Err(NpidError::OutputLimit));
    }

    #[test]
    fn zero_error_gives_zero_and_sign_follows_error() {
        let c = config().build().unwrap();
        let p = PosUm::from_num(1000);
        let mut n = Npid::at_rest(p);
        for _ in 0..10 {
            assert_eq!(n.track(&c, p, p), CmdLsb::ZERO);
        }
        let mut n = Npid::at_rest(p);
        let mut last = CmdLsb::ZERO;
        for _ in 0..20 {
            last = n.track(&c, PosUm::from_num(1100), p);
        }
        assert!(last > CmdLsb::ZERO);
        let mut n = Npid::at_rest(p);
        for _ in 0..20 {
            last = n.regulate(&c, PosUm::from_num(-50));
        }
        assert!(last < CmdLsb::ZERO);
    }

    #[test]
    fn output_clamped_and_integral_bounded() {
        let mut cfg = config();
        cfg.output_limit_lsb = 300.0;
        let c = cfg.build().unwrap();
        let mut n = Npid::at_rest(PosUm::ZERO);
        for _ in 0..5000 {
            let u = n.track(&c, PosUm::from_num(1e6), PosUm::ZERO);
            assert!(u.abs() <= CmdLsb::from_num(300));
        }
        // The integral stopped growing while the output was at its limit.
        assert!(n.e0_q32.abs() <= c.e0_max_q32);
        assert!(n.e0_q32 < c.e0_max_q32);
    }

    #[test]
    fn term_modes_match_wide_reference() {
        // β = 0 → Off; small gains → Direct; a huge β1 with α = 1 → Clamped.
        let mut cfg = config();
        cfg.beta2 = 0.0;
        let c = cfg.build().unwrap();
        assert_eq!(c.mode, [TermMode::Direct, TermMode::Direct, TermMode::Off]);
        cfg.beta1 = 5e5;
        cfg.fal1 = FalConfig {
            alpha: 1.0,
            delta: 1.0,
        };
        let big = cfg.build().unwrap();
        assert_eq!(big.mode[1], TermMode::Clamped);
        // Against an i128 evaluation of the same law: identical while the clamp is idle,
        // and the clamped term still saturates the output with the right sign.
        for (coeffs, errs) in [
            (&c, [3i64 << 16, -(70 << 16), 12 << 16]),
            (&big, [0, -(1 << 38), 1 << 20]),
            (&big, [0, 1 << 38, -(1 << 20)]),
        ] {
            let mut n = Npid::at_rest(PosUm::ZERO);
            let u = n.law(coeffs, (errs[1] >> 8) as i32, (errs[2] >> 8) as i32);
            let mut wide: i128 = 0;
            for (i, e) in [n.e0_q32 >> 16, errs[1], errs[2]].into_iter().enumerate() {
                let f = fal(&coeffs.fal[i], e);
                wide += (i128::from(f) * i128::from(coeffs.beta_q24[i])) >> 24;
            }
            let lim = i128::from(coeffs.u_max_q16);
            let want = wide.clamp(-lim, lim) as i64;
            assert!((i64::from(u.to_bits()) - want).abs() <= 1, "{u} vs {want}");
        }
    }
}
