//! Han's `fal` function (SPEC §D): a power law with a linear zone around zero.
//!
//! ```text
//! fal(e, α, δ) = |e|^α·sign(e)   if |e| > δ
//!              = e / δ^(1−α)     if |e| ≤ δ          (δ > 0)
//! ```
//!
//! With α < 1 small errors get a higher gain and large errors a lower one; the linear
//! zone keeps the gain finite at e = 0 (no chattering). `e` is in any unit (µm, µm/s,
//! µm·s: the caller's choice) in Q16; the result is in unit^α, Q16.
//!
//! **Approximation.** `|e|^α` comes from [`hydra_core::fixed_point`] (base-2 log/exp tables,
//! relative error ≤ 1.3·10⁻⁴). The linear zone's slope is computed at build time as
//! `k = δ^α/δ` from the *same* fixed-point `δ^α`, so both branches meet at ±δ to within
//! the rounding of `k` (≤ 2⁻³⁰ relative): `fal` is continuous at ±δ by construction.
//!
//! **Cost.** `k` is stored as a 31-bit mantissa `k_m ∈ [2³⁰, 2³¹)` and a shift (`k =
//! k_m·2^−k_sh`), so the linear zone is one bounded `i64` product (`|e| ≤ δ < 2³²` in
//! Q16, `k_m < 2³¹`); α = 1 returns `e` without any arithmetic; the power runs on 32-bit
//! table interpolations ([`hydra_core::fixed_point`]).
//!
//! Ranges: 0 ≤ α ≤ 2, 2⁻¹⁰ ≤ δ ≤ 2¹⁵ (in the unit of `e`).

use super::FalError;
use hydra_core::fixed_point::{mul_bounded_shr, pow_q16};

/// `fal` parameters (validated by [`FalConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FalConfig {
    /// Exponent α (0 … 2).
    pub alpha: f64,
    /// Half-width δ of the linear zone, unit of `e` (2⁻¹⁰ … 2¹⁵).
    pub delta: f64,
}

/// Validated `fal` coefficients (hot path: [`fal`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FalCoeffs {
    /// α, Q16.
    alpha_q16: u32,
    /// δ, Q16 of the unit of e.
    delta_q16: i64,
    /// Linear-zone slope δ^(α−1) = `k_m·2^−k_sh`, mantissa in [2³⁰, 2³¹).
    k_m: i64,
    /// Shift of the slope (15 … 45 for the validated α and δ).
    k_sh: u32,
}

/// `k` as `(k_m, k_sh)` with `k_m ∈ [2³⁰, 2³¹)`, `k = k_m·2^−k_sh` (k ∈ [2⁻¹⁵, 2¹⁵]
/// for the validated α and δ, so `k_sh` ∈ 15…45; k = 0 gives `(0, 62)`).
fn slope_parts(k: f64) -> (i64, u32) {
    let mut m = k;
    let mut sh = 0u32;
    while m < 1_073_741_824.0 && sh < 62 {
        m *= 2.0;
        sh = sh.saturating_add(1);
    }
    ((m + 0.5).min(2_147_483_647.0) as i64, sh)
}

impl FalConfig {
    /// Validates α and δ and precomputes the linear-zone slope.
    pub fn build(&self) -> Result<FalCoeffs, FalError> {
        let a = self.alpha;
        if !(a.is_finite() && (0.0..=2.0).contains(&a)) {
            return Err(FalError::Alpha);
        }
        let d = self.delta;
        if !(d.is_finite() && (1.0 / 1024.0..=32768.0).contains(&d)) {
            return Err(FalError::Delta);
        }
        let alpha_q16 = (a * 65536.0 + 0.5) as u32;
        let delta_q16 = (d * 65536.0 + 0.5) as i64;
        // δ^α in Q16 by the hot path's own power, then k = δ^α/δ (Q16/Q16 → ·2^40).
        let dal = pow_q16(delta_q16.unsigned_abs(), alpha_q16);
        let k = dal as f64 / delta_q16 as f64;
        let (k_m, k_sh) = slope_parts(k);
        Ok(FalCoeffs {
            alpha_q16,
            delta_q16,
            k_m,
            k_sh,
        })
    }
}

impl FalCoeffs {
    /// α in Q16.
    pub(crate) fn alpha_q16(&self) -> u32 {
        self.alpha_q16
    }
    /// δ in Q16 of the unit of e (2⁶ … 2³¹).
    pub(crate) fn delta_q16(&self) -> i64 {
        self.delta_q16
    }
    /// The identity `fal(e, 1, δ) = e` (for linear laws built from the same parts).
    pub fn identity() -> Self {
        Self {
            alpha_q16: 1 << 16,
            delta_q16: 1 << 16,
            k_m: 1 << 30,
            k_sh: 30,
        }
    }
}

/// `fal(e, α, δ)`: `e` in Q16 of its unit, result in Q16 of unit^α. Never fails.
#[inline]
pub fn fal(c: &FalCoeffs, e_q16: i64) -> i64 {
    if c.alpha_q16 == 1 << 16 {
        // α = 1: fal(e) = e in both branches, exactly.
        e_q16
    } else if e_q16.unsigned_abs() > c.delta_q16 as u64 {
        // δ > 0 (validated).
        let p = pow_q16(e_q16.unsigned_abs(), c.alpha_q16);
        if e_q16 < 0 {
            p.wrapping_neg()
        } else {
            p
        }
    } else {
        // |e| ≤ δ ≤ 2^31 (Q16) and k_m < 2^31: the product is below 2^62.
        mul_bounded_shr(e_q16, c.k_m, c.k_sh)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// fal in f64, the reference of the fixed-point forms (also `term`'s tests).
    pub(crate) fn fal_f64(e: f64, a: f64, d: f64) -> f64 {
        if e.abs() > d {
            e.abs().powf(a) * e.signum()
        } else {
            e / d.powf(1.0 - a)
        }
    }

    #[test]
    fn continuous_at_plus_minus_delta() {
        for &a in &[0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0] {
            for &d in &[0.01, 0.5, 1.0, 7.0, 300.0, 20000.0] {
                let c = FalConfig { alpha: a, delta: d }.build().unwrap();
                let dq = c.delta_q16;
                for s in [1i64, -1] {
                    let inside = fal(&c, s * dq);
                    let outside = fal(&c, s * (dq + 1));
                    let scale = (inside.abs() as f64).max(1.0);
                    // One input LSB changes the output by at most the local slope.
                    let k = c.k_m as f64 / 2f64.powi(c.k_sh as i32);
                    let slope = k.max(1.0) * 2.0 + 2.0;
                    assert!(
                        ((outside - inside) as f64).abs() <= 2e-4 * scale + slope,
                        "α {a} δ {d}: {inside} vs {outside}"
                    );
                    assert_eq!(inside.signum(), s);
                }
            }
        }
    }

    #[test]
    fn matches_f64_with_bounded_error() {
        let mut worst: f64 = 0.0;
        for &a in &[0.0, 0.3, 0.5, 0.8, 1.0, 1.2, 1.5] {
            for &d in &[0.05, 1.0, 10.0] {
                let c = FalConfig { alpha: a, delta: d }.build().unwrap();
                let aq = f64::from(c.alpha_q16) / 65536.0;
                let dq = c.delta_q16 as f64 / 65536.0;
                let mut e: f64 = 1e-3;
                while e < 1e5 {
                    for s in [1.0f64, -1.0] {
                        let eq = ((s * e) * 65536.0).round();
                        let want = fal_f64(eq / 65536.0, aq, dq);
                        let got = fal(&c, eq as i64) as f64 / 65536.0;
                        if want.abs() > 0.05 {
                            worst = worst.max((got - want).abs() / want.abs());
                        }
                    }
                    e *= 1.07;
                }
            }
        }
        assert!(worst < 1e-3, "fal relative error {worst}");
    }

    #[test]
    fn identity_and_errors() {
        let c = FalCoeffs::identity();
        assert_eq!(fal(&c, 12345), 12345);
        assert_eq!(fal(&c, -7 << 20), -7 << 20);
        let bad = FalConfig {
            alpha: 2.5,
            delta: 1.0,
        };
        assert_eq!(bad.build(), Err(FalError::Alpha));
        let bad = FalConfig {
            alpha: 0.5,
            delta: 0.0,
        };
        assert_eq!(bad.build(), Err(FalError::Delta));
    }

    proptest! {
        #[test]
        fn odd_and_monotone(e in -(1i64 << 45)..(1i64 << 45), a in 0.0f64..2.0, d in 0.01f64..100.0) {
            let c = FalConfig { alpha: a, delta: d }.build().unwrap();
            let f = fal(&c, e);
            prop_assert_eq!(fal(&c, -e), -f);
            prop_assert_eq!(f.signum(), e.signum());
            // Monotone non-decreasing across a step of 1/16 of the value.
            let e2 = e.saturating_add(e.abs() / 16 + 1);
            prop_assert!(fal(&c, e2) >= f.saturating_sub(f.abs() >> 12).saturating_sub(1));
        }
    }
}
