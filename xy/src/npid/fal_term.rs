//! One term `β·fal(e, α, δ)` of the nonlinear PID ([`super::npid`]), fused and on
//! 32-bit words.
//!
//! ```text
//! term(e) = β·|e|^α·sign(e)          if |e| > δ      (α ≠ 1)
//!         = k·e,  k = β·δ^α/δ        if |e| ≤ δ, or everywhere when α = 1
//! ```
//!
//! **Fusion.** The power zone is one base-2 log/exp evaluation with β folded into the
//! exponent: `term = 2^(α·log2|e_raw| + log2 β + 16 − α·f)` for an input in Q(f), the
//! result directly in LSB Q16 ([`hydra_core::fixed_point`]'s tables, relative error ≤ 1.3·10⁻⁴ as
//! `fal` alone; `log2 β` is exact to 6·10⁻⁸ in Q24). The linear zone (and α = 1) is one
//! `smull` by the slope `k` as a 31-bit mantissa and a shift; the slope is formed at
//! build time from the hot path's own power at δ, so the zones meet at ±δ. β = 0 skips
//! the term (`Off`), α = 1 skips the power (`Linear`): the mode is chosen by the build.
//!
//! Formats:
//!
//! | quantity | unit | format | range |
//! |---|---|---|---|
//! | input e | µm·s, µm, µm/s | Q(f) `i32`, f = 16 (e0) or 8 (e1, e2) | the `i32` range |
//! | output | DAC LSB | Q16 `i32` | ±2¹⁵ LSB (saturated) |
//! | slope k | LSB Q16 per input LSB | `k_m·2^−k_sh`, `k_sh` ≤ 31, `k_m` ∈ [2³⁰, 2³¹) for k ≥ ½ | 0 … 2³¹ (resolution 2⁻³¹) |
//! | α | 1 | Q16 | 0 … 2 |
//! | exponent offset `log2 β + 16 − α·f` | 1 | Q24 `i32` | ±60 |
//!
//! **Saturation.** A term saturates at ±2¹⁵ LSB (16 × the 12-bit DAC's range): the output
//! clamp (≤ 2047 LSB) then differs from the unsaturated sum only if the other two terms
//! cancel more than 30 000 LSB of it. A slope above 2³¹ output per input LSB (a term that
//! saturates from one input LSB on) is stored as 2³¹ − 1: the same saturated values.

use super::fal::FalCoeffs;
use hydra_core::fixed_point::{exp2_q24_sat_i32, log2_q24_u32};

/// How a term is evaluated (chosen by [`TermCoeffs::new`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) enum TermMode {
    /// β = 0: the term is zero.
    #[default]
    Off,
    /// α = 1: `k·e` everywhere.
    Linear,
    /// α ≠ 1: the power law outside ±δ, `k·e` inside.
    Power,
}

/// Validated coefficients of one term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct TermCoeffs {
    pub(crate) mode: TermMode,
    /// δ in input LSB (≥ 1).
    delta: u32,
    /// Slope mantissa, [2³⁰, 2³¹) (smaller only when `k_sh` is capped at 31, k < ½:
    /// the rounding of `k_m` then moves the output by ≤ ½ LSB of Q16 over the whole
    /// `i32` input).
    k_m: i32,
    /// Slope shift, 0 … 31 (a 64-bit shift below 32: no second word to test).
    k_sh: u32,
    /// α, Q16 (0 … 2¹⁷).
    alpha_q16: i32,
    /// `log2 β + 16 − α·f`, Q24.
    log_off_q24: i32,
}

/// `log2 x` for a finite `x > 0` in `f64` (build time only; `core` has no `f64::log2`):
/// the exponent from the bits, the mantissa by the `atanh` series (z ≤ 1/3: 30 terms,
/// below 10⁻¹⁵).
fn log2_f64(x: f64) -> f64 {
    let bits = x.to_bits();
    // The biased exponent is 0 … 2047: the difference is within ±1024.
    let exp = (((bits >> 52) & 0x7FF) as i32).wrapping_sub(1023);
    let m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    let z = (m - 1.0) / (m + 1.0);
    let z2 = z * z;
    let mut term = z;
    let mut sum = 0.0;
    let mut k = 1.0;
    for _ in 0..30 {
        sum += term / k;
        term *= z2;
        k += 2.0;
    }
    f64::from(exp) + 2.0 * sum / core::f64::consts::LN_2
}

/// `(k_m, k_sh)` with `k = k_m·2^−k_sh`, `k_m` ∈ [2³⁰, 2³¹) where `k_sh` ≤ 31 allows;
/// `k ≥ 2³¹` gives `(2³¹ − 1, 0)` (see the module docs), `k = 0` `(0, 31)`.
fn slope_parts(k: f64) -> (i32, u32) {
    if k.is_nan() || k <= 0.0 {
        return (0, 31);
    }
    if k >= 2_147_483_647.0 {
        return (i32::MAX, 0);
    }
    let mut m = k;
    let mut sh = 0u32;
    while m < 1_073_741_824.0 && sh < 31 {
        m *= 2.0;
        sh = sh.saturating_add(1);
    }
    let m = (m + 0.5).min(2_147_483_647.0) as i32;
    (m, sh)
}

/// `2^n` for `n` ≥ 0 in `f64` (build time).
fn pow2(n: i32) -> f64 {
    let mut v = 1.0;
    for _ in 0..n {
        v *= 2.0;
    }
    v
}

impl TermCoeffs {
    /// The term `β·fal(e, α, δ)` for an input in Q(`frac`) (`frac` 8 or 16) and β ∈
    /// [0, 10⁶] (validated by the caller), α and δ from the validated `fal`.
    pub(crate) fn new(beta: f64, fal: &FalCoeffs, frac: u32) -> Self {
        if beta.is_nan() || beta <= 0.0 {
            return Self::default();
        }
        let alpha_q16 = fal.alpha_q16().min(2 << 16) as i32;
        // δ (Q16 of the unit, 2^6 … 2^31) in input LSB, at least 1.
        let delta = (fal.delta_q16() >> 16u32.saturating_sub(frac)).clamp(1, 1 << 31) as u32;
        let scale = f64::from(1u32 << 16) / f64::from(1u32 << frac.min(16));
        if alpha_q16 == 1 << 16 {
            // β in LSB per unit: β·2^(16 − f) output LSB per input LSB.
            let (k_m, k_sh) = slope_parts(beta * scale);
            return Self {
                mode: TermMode::Linear,
                delta,
                k_m,
                k_sh,
                alpha_q16,
                log_off_q24: 0,
            };
        }
        let alpha = f64::from(alpha_q16) / 65536.0;
        let off = (log2_f64(beta) + 16.0 - alpha * f64::from(frac)).clamp(-100.0, 100.0);
        let log_off_q24 = (off * 16_777_216.0 + if off < 0.0 { -0.5 } else { 0.5 }) as i32;
        let mut c = Self {
            mode: TermMode::Power,
            delta,
            k_m: 0,
            k_sh: 31,
            alpha_q16,
            log_off_q24,
        };
        // The slope from the hot path's own power at δ (continuous at ±δ), evaluated
        // 2^-sh lower where β·δ^α itself would saturate: exponent p = α·log2 δ + off.
        let p = i64::from(log2_q24_u32(delta))
            .saturating_mul(i64::from(alpha_q16))
            .wrapping_shr(16)
            .saturating_add(i64::from(log_off_q24))
            .wrapping_shr(24);
        let sh = p.saturating_sub(29).clamp(0, 100) as i32;
        let lowered = Self {
            log_off_q24: log_off_q24.saturating_sub(sh.saturating_mul(1 << 24)),
            ..c
        };
        let at_delta = f64::from(lowered.power(delta)) * pow2(sh);
        let (k_m, k_sh) = slope_parts(at_delta / f64::from(delta));
        c.k_m = k_m;
        c.k_sh = k_sh;
        c
    }

    /// `k·e`, LSB Q16, saturated.
    #[inline(always)]
    fn linear(&self, e: i32) -> i32 {
        // |e·k_m| < 2^62; k_sh < 32.
        hydra_core::fixed_point::sat_i32(
            i64::from(e)
                .wrapping_mul(i64::from(self.k_m))
                .wrapping_shr(self.k_sh & 31),
        )
    }

    /// `β·|e|^α` for `|e| = ae` > 0, LSB Q16, saturated at 2³¹ − 1.
    #[inline(always)]
    fn power(&self, ae: u32) -> i32 {
        // log2 ∈ [0, 32)·2^24 < 2^29, α ≤ 2^17: the product >> 16 is below 2^30, and the
        // offset is within ±100·2^24 < 2^31 − 2^30.
        let l = i64::from(log2_q24_u32(ae))
            .wrapping_mul(i64::from(self.alpha_q16))
            .wrapping_shr(16) as i32;
        exp2_q24_sat_i32(l.wrapping_add(self.log_off_q24))
    }

    /// The term for input `e` (Q(f)), LSB Q16 (±2³¹ − 1).
    #[inline(always)]
    pub(crate) fn eval(&self, e: i32) -> i32 {
        match self.mode {
            TermMode::Off => 0,
            TermMode::Linear => self.linear(e),
            TermMode::Power => {
                let ae = e.unsigned_abs();
                if ae > self.delta {
                    // 0 ≤ power ≤ i32::MAX: the negation cannot overflow.
                    let p = self.power(ae);
                    if e < 0 {
                        p.wrapping_neg()
                    } else {
                        p
                    }
                } else {
                    self.linear(e)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::fal::{fal, FalConfig};
    use super::*;
    use proptest::prelude::*;

    use super::super::fal::tests::fal_f64;

    #[test]
    fn log2_f64_is_exact_enough() {
        for &x in &[1e-9, 0.3, 1.0, 1.5, 2.0, 3.0, 15.0, 1e6] {
            assert!((log2_f64(x) - x.log2()).abs() < 1e-13, "{x}");
        }
    }

    #[test]
    fn modes() {
        let lin = FalConfig {
            alpha: 1.0,
            delta: 1.0,
        }
        .build()
        .unwrap();
        assert_eq!(TermCoeffs::new(0.0, &lin, 8).mode, TermMode::Off);
        assert_eq!(TermCoeffs::new(0.0, &lin, 8).eval(12345), 0);
        let t = TermCoeffs::new(0.8, &lin, 8);
        assert_eq!(t.mode, TermMode::Linear);
        // 0.8 LSB/µm · 100 µm = 80 LSB.
        assert!((t.eval(100 << 8) - (80 << 16)).abs() <= 1);
        // Saturation at ±2^15 LSB.
        let big = TermCoeffs::new(1e6, &lin, 8);
        assert_eq!(big.eval(1 << 20), i32::MAX);
        assert!(big.eval(-(1 << 20)) <= -i32::MAX);
        assert_eq!(big.eval(0), 0);
    }

    proptest! {
        /// Against the f64 equation β·fal(e, α, δ) on the quantised α, δ: relative
        /// 2·10⁻⁴ (the tables' 1.3·10⁻⁴ and the slope's rounding) + 2 LSB of Q16, up to
        /// the saturation.
        #[test]
        fn matches_the_f64_term(
            e in any::<i32>(), a in 0.0f64..2.0, d in 0.01f64..1000.0,
            beta in 1e-3f64..1e3, q16_input in any::<bool>(),
        ) {
            let f = FalConfig { alpha: a, delta: d }.build().unwrap();
            let frac = if q16_input { 16 } else { 8 };
            let t = TermCoeffs::new(beta, &f, frac);
            let aq = f64::from(f.alpha_q16()) / 65536.0;
            let dq = t.delta as f64 / f64::from(1u32 << frac);
            let ef = f64::from(e) / f64::from(1u32 << frac);
            let want = beta * fal_f64(ef, aq, dq) * 65536.0;
            let got = f64::from(t.eval(e));
            if want.abs() < 2.1e9 {
                prop_assert!((got - want).abs() <= 2e-4 * want.abs() + 2.0,
                    "e {e} α {a} δ {d} β {beta}: {got} vs {want}");
            } else if want.abs() > 2.2e9 {
                prop_assert!(got.abs() >= f64::from(i32::MAX));
                prop_assert_eq!(got.signum(), want.signum());
            } else {
                // Within the tables' error of the saturation.
                prop_assert!(got.abs() >= 2.09e9);
                prop_assert_eq!(got.signum(), want.signum());
            }
        }

        /// Against the i64 `fal` the law used before (Q16 input, β in Q24), same tolerance.
        #[test]
        fn matches_fal_times_beta(
            e in -(1i32 << 28)..(1i32 << 28), a in 0.0f64..2.0, d256 in 13u32..25_600,
            beta in 1e-2f64..10.0,
        ) {
            // δ a multiple of the Q8 input LSB: the same δ in both forms.
            let d = f64::from(d256) / 256.0;
            let f = FalConfig { alpha: a, delta: d }.build().unwrap();
            let t = TermCoeffs::new(beta, &f, 8);
            let beta_q24 = (beta * 16_777_216.0 + 0.5) as i64;
            let old = (i128::from(fal(&f, i64::from(e) << 8)) * i128::from(beta_q24)) >> 24;
            let got = i128::from(t.eval(e));
            if old.abs() < 2_000_000_000 {
                let tol = (old.abs() as f64 * 2e-4) as i128 + 2;
                prop_assert!((got - old).abs() <= tol, "{got} vs {old}");
            }
        }
    }
}
