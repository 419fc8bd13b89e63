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
//! Formats (all `i32`; the TD's in [`super::td`]):
//!
//! | quantity | unit | format | resolution | range |
//! |---|---|---|---|---|
//! | e1 = z11 − z21 | µm | Q8 | 3.9·10⁻³ µm | ±8.4 m (saturating) |
//! | e2 = z12 − z22 | µm/s | Q8 | 3.9·10⁻³ µm/s | ±8.4 m/s (TD velocities ±4.2 m/s) |
//! | e0 | µm·s | Q16 | 1.5·10⁻⁵ µm·s | ±integral limit ≤ 32 767 µm·s |
//! | each term β·fal, u | DAC LSB | Q16 | 1.5·10⁻⁵ LSB | ±2¹⁵ LSB (term), ±output limit (u) |
//!
//! **Cost.** Every product is one 32 × 32 → 64-bit `smull`, every sum a saturating
//! 32-bit `qadd`: `e0 += e1·h` rounded to nearest (no drift from a floored increment;
//! increments below ½ LSB, |e1| < 2 nm at 1 ms, are lost), each term fused with its gain
//! (`fal_term.rs`: one log/exp for a power law with β in the exponent, one `smull` by
//! the small-signal slope in the linear zone and for α = 1). The build decides per term:
//! β = 0 skips it, α = 1 skips the power law. Each term saturates at ±2¹⁵ LSB (16 × the
//! DAC range) before the sum (see `fal_term.rs`).

use super::fal::FalConfig;
use super::fal_term::TermCoeffs;
use super::fhan::FhanConfig;
use super::td::{Td, TdCoeffs, TdConfig};
use super::{ErrorLaw, NpidError};
use hydra_core::units::{CmdLsb, PosUm};

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
    /// Clamp of |e0|, µm·s (0 … 32 767: the Q16 `i32` integral).
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
    /// β0·fal0 (input e0 µm·s Q16), β1·fal1 (e1 µm Q8), β2·fal2 (e2 µm/s Q8).
    terms: [TermCoeffs; 3],
    /// e0 clamp, µm·s Q16 (≤ 32 767·2¹⁶).
    e0_max_q16: i32,
    /// Output clamp, LSB Q16 (≤ 2047·2¹⁶).
    u_max_q16: i32,
}

fn gain(b: f64, term: u8) -> Result<f64, NpidError> {
    if b.is_finite() && (0.0..=1e6).contains(&b) {
        Ok(b)
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
        let beta = [
            gain(self.beta0, 0)?,
            gain(self.beta1, 1)?,
            gain(self.beta2, 2)?,
        ];
        let il = self.integral_limit_um_s;
        if !(il.is_finite() && (0.0..=32_767.0).contains(&il)) {
            return Err(NpidError::IntegralLimit);
        }
        let ol = self.output_limit_lsb;
        if !(ol.is_finite() && (1.0..=2047.0).contains(&ol)) {
            return Err(NpidError::OutputLimit);
        }
        let [f0, f1, f2] = &fal;
        let [b0, b1, b2] = beta;
        Ok(NpidCoeffs {
            td_ref,
            td_meas,
            terms: [
                TermCoeffs::new(b0, f0, 16),
                TermCoeffs::new(b1, f1, 8),
                TermCoeffs::new(b2, f2, 8),
            ],
            e0_max_q16: (il * 65536.0) as i32,
            u_max_q16: (ol * 65536.0) as i32,
        })
    }
}

/// Nonlinear PID state (two TDs, the integral, the last saturation direction).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Npid {
    td_ref: Td,
    td_meas: Td,
    /// e0, µm·s Q16.
    e0_q16: i32,
    /// −1/0/+1: the output was clamped at −limit / not clamped / +limit.
    sat: i8,
}

impl Npid {
    /// Both TDs at rest at `position_um`, integral zero.
    pub fn at_rest(position_um: PosUm) -> Self {
        Self {
            td_ref: Td::at_rest(position_um),
            td_meas: Td::at_rest(position_um),
            e0_q16: 0,
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
        let [t0, t1, t2] = &c.terms;
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
            // Q8·Q32 = Q40, rounded to Q16 (`smlal` on 2^23): |e1·h| < 2^31·2^26, the sum
            // below 2^58; saturated to 32 bits (only |e1|·h > 32 767 µm·s does).
            let de0 = hydra_core::fixed_point::sat_i32(
                i64::from(e1_q8)
                    .wrapping_mul(i64::from(c.td_ref.h_q32()))
                    .wrapping_add(1 << 23)
                    .wrapping_shr(24),
            );
            self.e0_q16 = self
                .e0_q16
                .saturating_add(de0)
                .clamp(c.e0_max_q16.wrapping_neg(), c.e0_max_q16);
        }
        let u = t0
            .eval(self.e0_q16)
            .saturating_add(t1.eval(e1_q8))
            .saturating_add(t2.eval(e2_q8));
        let lim = c.u_max_q16;
        let (u, sat) = if u > lim {
            (lim, 1)
        } else if u < lim.wrapping_neg() {
            (lim.wrapping_neg(), -1)
        } else {
            (u, 0)
        };
        self.sat = sat;
        CmdLsb::from_bits(u)
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
            assert!(u.saturating_abs() <= CmdLsb::from_num(300));
        }
        // The integral stopped growing while the output was at its limit.
        assert!(n.e0_q16.abs() <= c.e0_max_q16);
        assert!(n.e0_q16 < c.e0_max_q16);
    }

    #[test]
    fn law_matches_the_f64_equation() {
        // Against β0·fal0(e0) + β1·fal1(e1) + β2·fal2(e2) in f64 on the integrated e0,
        // through the clamp; the test config has α1 = 0.7 (power law) and β2 ≠ 0.
        let c = config().build().unwrap();
        let cfg = config();
        let f = |e: f64, a: f64, d: f64| {
            if e.abs() > d {
                e.abs().powf(a) * e.signum()
            } else {
                e / d.powf(1.0 - a)
            }
        };
        let mut n = Npid::at_rest(PosUm::ZERO);
        let mut k: i32 = 0;
        for e1 in [-3000i32, -70, -5, 0, 3, 20, 90, 4000] {
            for e2 in [-20_000i32, -40, 0, 7, 30_000] {
                k += 1;
                let (e1q, e2q) = ((e1 << 8) + k, (e2 << 8) - k);
                let u = f64::from(n.law(&c, e1q, e2q).to_bits()) / 65536.0;
                let e0 = f64::from(n.e0_q16) / 65536.0;
                let want = cfg.beta0 * f(e0, 1.0, 1.0)
                    + cfg.beta1 * f(f64::from(e1q) / 256.0, 0.7, 20.0)
                    + cfg.beta2 * f(f64::from(e2q) / 256.0, 1.0, 1.0);
                let want = want.clamp(-2047.0, 2047.0);
                assert!(
                    (u - want).abs() <= 2e-4 * want.abs() + 1e-3,
                    "e1 {e1} e2 {e2}: {u} vs {want}"
                );
            }
        }
    }

    #[test]
    fn integral_limit_range() {
        let mut c = config();
        c.integral_limit_um_s = 32_767.0;
        assert!(c.build().is_ok());
        c.integral_limit_um_s = 40_000.0;
        assert_eq!(c.build(), Err(NpidError::IntegralLimit));
    }
}
