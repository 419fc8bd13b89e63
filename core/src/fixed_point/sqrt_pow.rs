//! Fixed-point helpers of the nonlinear PID: wide products, an integer square root and
//! the power |x|^α through a base-2 logarithm and exponential.
//!
//! **Power.** `|x|^α = 2^(α·log2|x|)`:
//!
//! * `log2` — the input is normalised so its leading one is bit 63; the integer part of
//!   the logarithm is the bit position, the fractional part `log2(1 + m)`, m ∈ [0, 1),
//!   is read from a 65-entry table (step 1/64, Q30) with linear interpolation. The
//!   interpolation error is at most `max|f″|·Δ²/8 = (1/ln 2)/8/64² = 4.4·10⁻⁵` (absolute,
//!   in log2 units).
//! * `exp2` — `2^(n + f) = 2^n · 2^f`, f ∈ [0, 1) from a 65-entry table of `2^(i/64)`
//!   (Q30) with linear interpolation: at most `ln²2·2/8/64² = 2.9·10⁻⁵` relative.
//!
//! For α ≤ 2 the combined relative error of `|x|^α` is below
//! `α·ln2·4.4·10⁻⁵ + 2.9·10⁻⁵ + 2⁻²³ ≈ 1.0·10⁻⁴` (the tests measure ≤ 1.3·10⁻⁴ over
//! x ∈ [10⁻³, 10⁶], α ∈ [0, 2]), ten times under the 10⁻³ budget of the issue.
//!
//! **Square root.** [`sqrt_u64`]: the argument is normalised by an even shift so its
//! leading one is bit 63 or 62; its top 32 bits `t` ∈ [2³⁰, 2³²) index a 49-entry table
//! of `√(i/64)` (Q31, i = 16…64, built at compile time by the exact `u64::isqrt`) with
//! linear interpolation: error ≤ `max|f″|·Δ²/8 = (¼·0.25^−1.5)/8/64² = 6.1·10⁻⁵`
//! absolute on a value ≥ ½, i.e. ≤ 1.2·10⁻⁴ relative. One Newton step `s += (M − s²)/(2s)`
//! on the full 62-bit argument (exact `umull` residual, one 32-bit `sdiv`) squares that
//! to ≈ 10⁻⁸; the quotient's 16-bit divisor and truncation add ≈ 10⁻⁹ (test
//! `sqrt_relative_error`: measured 0.9·10⁻⁸ over 2¹⁰ … 2⁶⁴). No loop, no library call: about 30
//! instructions on a Cortex-M4 (the bit-by-bit `u64::isqrt` took several hundred).
//!
//! **Products on a 32-bit CPU.** An `i128` product is a library routine on the
//! Cortex-M4 (≈ 40 instructions plus the saturation); an `i64 × i64` product that is
//! known not to overflow is three instructions (`umull`, 2 × `mla`), an `i32 × i32 →
//! i64` product one (`smull`). [`crate::fixed_point::mul64_shr_floor_sat`] takes the `smull` path whenever both
//! operands fit 32 bits and keeps the exact `i128` path (with saturation) otherwise; the
//! hot paths of the TD, `fhan` and the NPID use [`mul_bounded_shr`] where the ranges
//! documented at each call site bound the product below 2⁶³.
//!
//! Every helper saturates instead of overflowing and never panics.

/// `log2(1 + i/64)`, i = 0…64, Q30 (`round(log2(1 + i/64)·2^30)`).
const LOG2_TAB: [u32; 65] = [
    0, 24017256, 47667823, 70962728, 93912511, 116527248, 138816582, 160789745, 182455581,
    203822568, 224898839, 245692198, 266210141, 286459867, 306448299, 326182095, 345667660,
    364911162, 383918542, 402695523, 421247625, 439580170, 457698295, 475606957, 493310944,
    510814882, 528123241, 545240343, 562170370, 578917365, 595485245, 611877800, 628098702,
    644151509, 660039669, 675766525, 691335320, 706749198, 722011213, 737124328, 752091421,
    766915285, 781598637, 796144114, 810554283, 824831638, 838978604, 852997541, 866890747,
    880660455, 894308843, 907838029, 921250079, 934547002, 947730758, 960803257, 973766362,
    986621888, 999371606, 1012017244, 1024560487, 1037002979, 1049346328, 1061592099, 1073741824,
];

/// `2^(i/64)`, i = 0…64, Q30 (`round(2^(i/64)·2^30)`).
const EXP2_TAB: [u32; 65] = [
    1073741824, 1085434106, 1097253708, 1109202018, 1121280436, 1133490379, 1145833280, 1158310587,
    1170923762, 1183674286, 1196563654, 1209593378, 1222764986, 1236080024, 1249540052, 1263146652,
    1276901417, 1290805962, 1304861917, 1319070932, 1333434672, 1347954824, 1362633090, 1377471191,
    1392470869, 1407633882, 1422962010, 1438457051, 1454120821, 1469955159, 1485961921, 1502142985,
    1518500250, 1535035634, 1551751076, 1568648537, 1585730000, 1602997467, 1620452965, 1638098541,
    1655936265, 1673968228, 1692196547, 1710623359, 1729250827, 1748081133, 1767116489, 1786359126,
    1805811301, 1825475297, 1845353420, 1865448001, 1885761398, 1906295993, 1927054196, 1948038440,
    1969251188, 1990694927, 2012372174, 2034285470, 2056437387, 2078830522, 2101467502, 2124350982,
    2147483648,
];

/// `(a · b) >> s` for a product the caller has bounded: `|a · b| < 2⁶³` (each call
/// site states why). Three multiply instructions on a Cortex-M4; wrapping, so an
/// unproven bound would give a wrong value, never a panic.
#[inline(always)]
pub const fn mul_bounded_shr(a: i64, b: i64, s: u32) -> i64 {
    a.wrapping_mul(b).wrapping_shr(s)
}

/// `√(i/64)` in Q31 for i = 16…64 (`floor(√(i·2⁵⁶))`, exact integer square root at
/// compile time).
const SQRT_TAB: [u32; 49] = {
    let mut t = [0u32; 49];
    let mut i = 0;
    while i < 49 {
        #[allow(clippy::arithmetic_side_effects, clippy::indexing_slicing)]
        {
            t[i] = ((16 + i as u64) << 56).isqrt() as u32;
            i += 1;
        }
    }
    t
};

/// `√x`, returned as `(s, k)`: `√x ≈ s · 2^(1 − k)` with `s` ∈ [2³⁰, 2³¹] (√ of the
/// normalised argument, Q31) and `k` ∈ 0…31 (half the even normalising shift).
/// Relative error ≤ 2·10⁻⁸ (measured 0.9·10⁻⁸, module docs). `x = 0` gives `s = 0`.
#[inline]
pub fn sqrt_u64(x: u64) -> (u32, u32) {
    let k = x.leading_zeros() / 2;
    // m ∈ [2^62, 2^64): leading one at bit 63 or 62.
    let m = x.wrapping_shl(k.wrapping_mul(2));
    let top = m.wrapping_shr(32) as u32;
    // top ∈ [2^30, 2^32): index = top >> 26 ∈ 16…63, weight = the 26 bits below.
    let idx = (top >> 26).wrapping_sub(16) as usize;
    let lo = SQRT_TAB.get(idx).copied().unwrap_or(0);
    let hi = SQRT_TAB.get(idx.wrapping_add(1)).copied().unwrap_or(0);
    // 0 ≤ hi − lo < 2^25 (slope of √ on [¼, 1] ≤ 1, step 2^31/64), weight < 2^26.
    let s0 = lo.wrapping_add(
        u64::from(hi.wrapping_sub(lo))
            .wrapping_mul(u64::from(top & 0x3FF_FFFF))
            .wrapping_shr(26) as u32,
    );
    // One Newton step on M = m/4 ∈ [2^60, 2^62), √M ≈ s0 (|s0 − √M| ≤ 6.1·10⁻⁵·2^31 <
    // 2^17): s1 = s0 + (M − s0²)/(2·s0). |M − s0²| ≤ 2·2^31·2^17 = 2^49, so the residual
    // >> 19 (< 2^30) and 2·s0 >> 16 = s0 >> 15 ∈ [2^15, 2^16] are 32-bit: one `sdiv`,
    // and (M − s0²)/(2·s0) = (num/den)·2^3.
    let rho =
        (m.wrapping_shr(2) as i64).wrapping_sub(u64::from(s0).wrapping_mul(u64::from(s0)) as i64);
    let num = rho.wrapping_shr(19) as i32;
    let den = s0.wrapping_shr(15) as i32;
    let delta = num.checked_div(den).unwrap_or(0).wrapping_shl(3);
    (s0.wrapping_add_signed(delta), k)
}

/// √x rounded to the nearest integer (e.g. a length in LSB from a squared length), from
/// [`sqrt_u64`]: √x = s·2^(1−k), error ≤ ½ + 2·10⁻⁸·√x (≤ 1 LSB below 2^50, test
/// `sqrt_round_matches_f64`). The crate's one square root: bench-m4 chose it (61
/// instructions) over the reciprocal-square-root form (three Newton steps of 1/√x, no
/// division: 99 instructions; docs/bench.md).
#[inline]
pub fn sqrt_round_u64(x: u64) -> u64 {
    let (s, k) = sqrt_u64(x);
    // √x·2^k = 2s ≤ 2^32.
    let v = u64::from(s).wrapping_shl(1);
    if k == 0 {
        v
    } else {
        v.wrapping_add(1u64.wrapping_shl(k.wrapping_sub(1)))
            .wrapping_shr(k)
    }
}

/// `sign(x)` with `sign(0) = 0`, as −1, 0, +1.
#[inline(always)]
pub const fn sign(x: i64) -> i64 {
    x.signum()
}

/// Linear interpolation in a 65-entry Q30 table: `idx` ∈ 0…63, `w` the weight of the
/// next entry in Q(`wbits`). Returns Q30.
#[inline(always)]
fn interp(tab: &[u32; 65], idx: usize, w: u32, wbits: u32) -> u32 {
    let lo = tab.get(idx).copied().unwrap_or(0);
    let hi = tab.get(idx.wrapping_add(1)).copied().unwrap_or(0);
    // Both tables increase: 0 ≤ hi − lo < 2^25, w < 2^32: one `umull`, product < 2^57.
    let step = u64::from(hi.wrapping_sub(lo))
        .wrapping_mul(u64::from(w))
        .wrapping_shr(wbits) as u32;
    lo.wrapping_add(step)
}

/// `log2(x / 2^frac)` in Q24 for `x > 0` (`x = 0` returns `i32::MIN / 4`, "−∞");
/// `frac` ≤ 32.
///
/// Range: `[−frac, 64 − frac)` (within ±2³⁰ in Q24), absolute error ≤ 4.5·10⁻⁵. The
/// interpolation runs on the top 32 bits of the normalised argument: one `umull`.
#[inline]
pub fn log2_q24(x: u64, frac: u32) -> i32 {
    if x == 0 {
        return i32::MIN / 4;
    }
    let lz = x.leading_zeros();
    let msb = 63u32.wrapping_sub(lz);
    // Leading one at bit 63; of the top word, the next 6 bits index the table and the
    // 25 below (as a Q32 weight) interpolate.
    let top = x.wrapping_shl(lz).wrapping_shr(32) as u32;
    let idx = (top.wrapping_shr(25) & 63) as usize;
    let w = top.wrapping_shl(7);
    let frac_q30 = interp(&LOG2_TAB, idx, w, 32);
    let int = (msb as i32).wrapping_sub(frac as i32);
    int.wrapping_shl(24)
        .wrapping_add(frac_q30.wrapping_shr(6) as i32)
}

/// `2^(l / 2^24)` in Q(`out_frac`), saturated to `[0, i64::MAX]`. `out_frac` ≤ 32.
///
/// Relative error ≤ 3·10⁻⁵ (plus one LSB of the output format).
#[inline]
pub fn exp2_q24(l: i32, out_frac: u32) -> i64 {
    let n = l.wrapping_shr(24); // floor, −128 … 127
    let f = (l & 0xFF_FFFF) as u32; // Q24 in [0, 1)
    let idx = f.wrapping_shr(18) as usize;
    let v = interp(&EXP2_TAB, idx, f & 0x3_FFFF, 18); // Q30 in [2^30, 2^31]
                                                      // value = v·2^(n − 30) in units, ·2^out_frac in the output format.
    let sh = n.wrapping_add(out_frac as i32).wrapping_sub(30);
    if sh >= 32 {
        i64::MAX
    } else if sh >= 0 {
        // v < 2^32, sh < 32: below 2^63.
        i64::from(v).wrapping_shl(sh as u32)
    } else if sh > -32 {
        i64::from(v.wrapping_shr(sh.unsigned_abs()))
    } else {
        0
    }
}

/// `log2(x)` in Q24 for a `u32` `x > 0` (`x = 0` returns `i32::MIN / 4`, "−∞"): the
/// 32-bit form of [`log2_q24`] (one `clz`, one `umull`). Range `[0, 32)`, absolute error
/// ≤ 4.5·10⁻⁵.
#[inline(always)]
pub fn log2_q24_u32(x: u32) -> i32 {
    if x == 0 {
        return i32::MIN / 4;
    }
    let lz = x.leading_zeros();
    let msb = 31u32.wrapping_sub(lz);
    // Leading one at bit 31; the next 6 bits index the table, the 25 below interpolate.
    let top = x.wrapping_shl(lz);
    let idx = (top.wrapping_shr(25) & 63) as usize;
    let frac_q30 = interp(&LOG2_TAB, idx, top.wrapping_shl(7), 32);
    (msb as i32)
        .wrapping_shl(24)
        .wrapping_add(frac_q30.wrapping_shr(6) as i32)
}

/// `2^(l / 2^24)` as an integer, saturated to `[0, i32::MAX]`: the 32-bit form of
/// [`exp2_q24`] with `out_frac = 0`. Relative error ≤ 3·10⁻⁵ (plus one LSB).
#[inline(always)]
pub fn exp2_q24_sat_i32(l: i32) -> i32 {
    let n = l.wrapping_shr(24); // floor, −128 … 127
    let f = (l & 0xFF_FFFF) as u32;
    let v = interp(&EXP2_TAB, f.wrapping_shr(18) as usize, f & 0x3_FFFF, 18); // [2^30, 2^31]
                                                                              // value = v·2^(n − 30).
    let sh = n.wrapping_sub(30);
    if sh > 0 {
        i32::MAX
    } else if sh == 0 {
        v.min(i32::MAX as u32) as i32
    } else if sh > -32 {
        v.wrapping_shr(sh.unsigned_abs()) as i32
    } else {
        0
    }
}

/// `|x|^α` for `x` in Q16 (any unit) and `α` in Q16 (0 ≤ α ≤ 2): the result is in Q16
/// of unit^α, saturated to `i64::MAX`. `0^α = 0` (also for α = 0, where the caller's
/// linear zone takes over anyway).
///
/// Relative error ≤ 1.3·10⁻⁴ (see the module docs).
#[inline]
pub fn pow_q16(x: u64, alpha_q16: u32) -> i64 {
    if x == 0 {
        return 0;
    }
    let l = log2_q24(x, 16);
    // l ∈ [−16, 48)·2^24 (|l| < 2^30) and α ≤ 2^17: one `smull`, and the product
    // shifted by 16 lies in [−2^29, 3·2^30): an i32.
    let p = i64::from(l)
        .wrapping_mul(i64::from(alpha_q16 as i32))
        .wrapping_shr(16) as i32;
    exp2_q24(p, 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_f64() {
        for (i, (&l, &e)) in LOG2_TAB.iter().zip(EXP2_TAB.iter()).enumerate() {
            let x = i as f64 / 64.0;
            assert!(((1.0 + x).log2() * 2f64.powi(30) - f64::from(l)).abs() <= 0.5);
            assert!((2f64.powf(x) * 2f64.powi(30) - f64::from(e)).abs() <= 0.5);
        }
    }

    #[test]
    fn log2_and_exp2_errors() {
        let mut worst_l: f64 = 0.0;
        let mut worst_e: f64 = 0.0;
        for k in 0..20_000u64 {
            let x = 1 + k.wrapping_mul(2_654_435_761) % (1u64 << 40);
            let got = log2_q24(x, 16) as f64 / 2f64.powi(24);
            let want = (x as f64 / 65536.0).log2();
            worst_l = worst_l.max((got - want).abs());
            let l = (k as i32 - 10_000) * 40_000; // ±24 in log2
            let got = exp2_q24(l, 16) as f64 / 65536.0;
            let want = 2f64.powf(l as f64 / 2f64.powi(24));
            if want > 1.0 {
                worst_e = worst_e.max((got - want).abs() / want);
            }
        }
        assert!(worst_l < 5e-5, "log2 error {worst_l}");
        assert!(worst_e < 4e-5, "exp2 error {worst_e}");
    }

    #[test]
    fn pow_relative_error_under_budget() {
        let mut worst: f64 = 0.0;
        for ai in 0..=40 {
            let alpha = ai as f64 * 0.05;
            let a_q16 = (alpha * 65536.0).round() as u32;
            let alpha_q = f64::from(a_q16) / 65536.0;
            let mut x: f64 = 1e-3;
            while x < 1e6 {
                let xr = (x * 65536.0).round() as u64;
                let xq = xr as f64 / 65536.0;
                let got = pow_q16(xr, a_q16) as f64 / 65536.0;
                let want = xq.powf(alpha_q);
                if want > 0.5 {
                    // Below 0.5 the Q16 output LSB (1.5e-5) starts to dominate.
                    worst = worst.max((got - want).abs() / want);
                }
                x *= 1.013;
            }
        }
        assert!(worst < 1.3e-4, "pow error {worst}");
    }

    #[test]
    fn sqrt_round_small_values_and_extremes() {
        assert_eq!(sqrt_round_u64(0), 0);
        assert_eq!(sqrt_round_u64(1), 1);
        assert_eq!(sqrt_round_u64(8), 3);
        assert_eq!(sqrt_round_u64(6), 2);
        assert_eq!(sqrt_round_u64(25 << 40), 5 << 20);
        assert!(sqrt_round_u64(u64::MAX).abs_diff(1 << 32) <= 90);
        for v in 0..100_000u64 {
            let e = (v as f64).sqrt();
            assert!((sqrt_round_u64(v) as f64 - e).abs() <= 0.5 + 1e-9, "{v}");
        }
    }

    proptest::proptest! {
        #[test]
        fn sqrt_round_matches_f64(v: u64) {
            let r = sqrt_round_u64(v) as f64;
            let e = (v as f64).sqrt();
            proptest::prop_assert!((r - e).abs() <= 0.5 + e * 2e-8, "{v}: {r} vs {e}");
        }
    }

    #[test]
    fn sqrt_relative_error() {
        let mut worst: f64 = 0.0;
        let mut x: f64 = 1024.0;
        while x < 1.8e19 {
            for d in [0u64, 1, 7, 12_345] {
                let xi = (x as u64).saturating_add(d);
                let (s, k) = sqrt_u64(xi);
                let got = f64::from(s) * 2f64.powi(1 - k as i32);
                let want = (xi as f64).sqrt();
                worst = worst.max((got - want).abs() / want);
            }
            x *= 1.0037;
        }
        assert!(worst < 2e-8, "sqrt error {worst}");
        let (s, k) = sqrt_u64(u64::MAX);
        assert!((f64::from(s) * 2f64.powi(1 - k as i32) / 2f64.powi(32) - 1.0).abs() < 1e-5);
        assert_eq!(sqrt_u64(0).0, 0);
    }

    #[test]
    fn mul_shr_fast_path_matches_i128() {
        let vals = [
            0i64,
            1,
            -1,
            12_345,
            -98_765_432,
            i64::from(i32::MAX),
            i64::from(i32::MIN),
            1 << 31,
            -(1 << 31) - 1,
            1 << 40,
            i64::MAX,
            i64::MIN,
        ];
        for &a in &vals {
            for &b in &vals {
                for s in [0, 1, 16, 24, 30, 40, 62] {
                    assert_eq!(
                        crate::fixed_point::mul64_shr_floor_sat(a, b, s),
                        crate::fixed_point::mul64_shr_floor_sat_wide(a, b, s),
                        "{a} {b} {s}"
                    );
                }
            }
        }
    }

    #[test]
    fn u32_forms_match_the_u64_forms() {
        for k in 0..20_000u32 {
            let x = 1 + k.wrapping_mul(2_654_435_761) % (u32::MAX - 1);
            assert_eq!(log2_q24_u32(x), log2_q24(u64::from(x), 0), "{x}");
            let l = (k as i32 - 10_000) * 60_000; // ±36 in log2
            let want = exp2_q24(l, 0).min(i64::from(i32::MAX));
            assert_eq!(i64::from(exp2_q24_sat_i32(l)), want, "{l}");
        }
        assert_eq!(exp2_q24_sat_i32(31 << 24), i32::MAX);
        assert_eq!(exp2_q24_sat_i32(-40 << 24), 0);
    }

    #[test]
    fn extremes_saturate() {
        assert_eq!(pow_q16(0, 32768), 0);
        assert_eq!(pow_q16(u64::MAX, 2 << 16), i64::MAX);
        assert_eq!(exp2_q24(i32::MIN / 4, 16), 0);
        assert_eq!(crate::fixed_point::sat_i64(i128::MAX), i64::MAX);
        assert_eq!(
            crate::fixed_point::mul64_shr_floor_sat(i64::MAX, i64::MAX, 0),
            i64::MAX
        );
        assert_eq!(crate::fixed_point::mul64_shr_floor_sat(-3, 5, 1), -8);
    }
}
