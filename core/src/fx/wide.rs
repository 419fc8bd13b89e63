//! Wide products, rounding shifts, the reciprocal square root and the normalisation of a vector to a unit vector and a length.
//!
//! Every helper saturates instead of overflowing and never panics. Products of two
//! `i64` are formed in an `i128` (exact: |a·b| ≤ 2^126); products of two `i32` in an
//! `i64` (exact: ≤ 2^62). The `i64` helpers used per period (`mul_shr30_i32_i64`,
//! `mul_shr_i64_by_u32`, `mul_shr32_i64_i32`, `mul_shr32_i64_small`, `sq_mul_shr68`) give
//! exactly the `i128` form's value from 32-bit products when their operands are in range
//! (tested against it), and fall back to it otherwise; `div_small` divides an `i64` by a
//! small integer with 32-bit divisions (a Cortex-M4 has no 64-bit divide). Range tests
//! that the compiler would otherwise turn into branch-free 64-bit clamps keep their
//! saturating branch in a separate cold function (`clamp_rel`).
//!
//! | quantity | format | range |
//! |---|---|---|
//! | 1/√x (`rsqrt_q30`) | `u32` Q2.30 | x ∈ [0.25, 2), result ∈ (0.707, 2], < 4·10⁻⁹ relative |
//! | unit vector (`normalize`) | `i32` Q2.30 | ±2^30, < 8·10⁻⁹ |
//! | 1/|d| (`UnitLen::rsq`, `exp`) | `u32` Q2.30 × 2^exp | (2^29.5, 2^31] |

use super::sat::sat_i64;

/// `x >> s` rounded to nearest (ties toward +∞), for `0 ≤ s ≤ 126` and |x| ≤ 2^126
/// (every caller passes a product of two `i64`: then adding the rounding half cannot
/// overflow, so it is a plain add, not a saturating one).
#[inline(always)]
pub const fn shr_round_i128(x: i128, s: u32) -> i128 {
    if s == 0 {
        return x;
    }
    x.wrapping_add(1i128.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)
}

/// `x >> s` rounded to nearest (ties toward +∞), for `0 ≤ s ≤ 62`.
#[inline(always)]
pub const fn shr_round_i64(x: i64, s: u32) -> i64 {
    if s == 0 {
        return x;
    }
    x.saturating_add(1i64.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)
}

/// `(a · b) >> s` rounded to nearest, formed in an `i128`, saturated to `i64`.
#[inline(always)]
pub const fn mul_shr_i64(a: i64, b: i64, s: u32) -> i64 {
    sat_i64(shr_round_i128((a as i128).wrapping_mul(b as i128), s))
}

/// `(a · b) >> 30` rounded to nearest for an `i32` (a unit-vector component, Q30) times
/// an `i64`, equal to `mul_shr_i64(a, b, 30)` but from two 32-bit products:
///
/// ```text
/// b = b_h·2^32 + b_l  →  (a·b + 2^29) >> 30 = 4·a·b_h + (a·b_l + 2^29) >> 30   (exact)
/// ```
///
/// (`smull` for a·b_h, `umull` + `mla` for a·b_l); falls back to the `i128` form when
/// 4·a·b_h could leave the `i64` range.
#[inline(always)]
pub const fn mul_shr30_i32_i64(a: i32, b: i64) -> i64 {
    if b as i32 as i64 == b {
        // b fits an i32 (a path's r″ in Q32 is usually far below 2^31): one `smull`,
        // |a·b| ≤ 2^62, the rounding add cannot wrap; the exact value, as below.
        return (a as i64).wrapping_mul(b).wrapping_add(1 << 29) >> 30;
    }
    let hi = (a as i64).wrapping_mul(b >> 32);
    if hi.unsigned_abs() >= 1 << 60 {
        return mul_shr_i64(a as i64, b, 30);
    }
    let lo = (a as i64).wrapping_mul(b as u32 as i64);
    // |lo| < 2^63; the rounded shift cannot overflow; |4·hi| < 2^62.
    (hi << 2).wrapping_add(lo.wrapping_add(1 << 29) >> 30)
}

/// `(a · b) >> s` rounded to nearest (2 ≤ s ≤ 32 on the fast path), saturated, for an `i64` times a
/// non-negative `i64` (a reciprocal such as 1/|r′| in Q30): equal to `mul_shr_i64(a, b,
/// s)`. When b < 2^32 it is formed from two 32-bit products:
///
/// ```text
/// a = a_h·2^32 + a_l  →  (a·b + 2^(s−1)) >> s = a_h·b·2^(32−s) + (a_l·b + 2^(s−1)) >> s
/// ```
///
/// (exact; a_h·b is an `i32×u32` product, a_l·b a `umull`), else — or when the first
/// term could leave the `i64` range — by the `i128` form.
#[inline(always)]
pub const fn mul_shr_i64_by_u32(a: i64, b: i64, s: u32) -> i64 {
    if b < 0 || b > u32::MAX as i64 || s < 2 || s > 32 {
        return mul_shr_i64(a, b, s);
    }
    if a as i32 as i64 == a {
        // a fits an i32: |a·b| < 2^31·2^32 − 2^32, so a·b + 2^(s−1) < 2^63 (s ≤ 32);
        // one `i32×u32` product, the exact value.
        return a
            .wrapping_mul(b)
            .wrapping_add(1i64.wrapping_shl(s.wrapping_sub(1)))
            .wrapping_shr(s);
    }
    let hi = (a >> 32).wrapping_mul(b);
    // |hi·2^(32−s)| < 2^62 and the second term < 2^62 (s ≥ 2): the sum fits an i64.
    if hi.unsigned_abs() >= 1u64.wrapping_shl(s.wrapping_add(30)) {
        return mul_shr_i64(a, b, s);
    }
    let lo = ((a as u32 as u64)
        .wrapping_mul(b as u64)
        .wrapping_add(1u64.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)) as i64;
    hi.wrapping_shl(32u32.wrapping_sub(s)).wrapping_add(lo)
}

/// `(a · b) >> 32` rounded to nearest, saturated, for two `i64`: equal to
/// `mul_shr_i64(a, b, 32)`. When b fits an `i32` it is formed from two 32-bit products:
///
/// ```text
/// a = a_h·2^32 + a_l  →  (a·b + 2^31) >> 32 = a_h·b + (a_l·b + 2^31) >> 32   (exact)
/// ```
///
/// (|a_h·b| ≤ 2^62, an `smull`; |a_l·b| < 2^63 − 2^31, a `umull` and a sign correction;
/// the sum below 2^62 + 2^31: no saturation is reachable), else by the `i128` form.
#[inline(always)]
pub const fn mul_shr32_i64_i32(a: i64, b: i64) -> i64 {
    if b < i32::MIN as i64 || b > i32::MAX as i64 {
        return mul_shr_i64(a, b, 32);
    }
    let hi = (a >> 32).wrapping_mul(b);
    let lo = (a as u32 as i64).wrapping_mul(b);
    hi.wrapping_add(lo.wrapping_add(1 << 31) >> 32)
}

/// `(a · b) >> 32` rounded to nearest, saturated, for two `i64`: equal to
/// `mul_shr_i64(a, b, 32)`. When |a| < 2^40 and |b| < 2^49 (a parabola's u in Q16 times
/// its 1/p in Q48) it is formed from four 32-bit products of the halves
/// (a = a_h·2^32 + a_l, b = b_h·2^32 + b_l, a_h and b_h signed, a_l and b_l unsigned):
///
/// ```text
/// (a·b + 2^31) >> 32 = a_h·b_h·2^32 + a_h·b_l + a_l·b_h + (a_l·b_l + 2^31) >> 32   (exact)
/// ```
///
/// (|a_h| < 2^8, |b_h| < 2^17: |a_h·b_h·2^32| < 2^57, |a_h·b_l| < 2^40, |a_l·b_h| < 2^49,
/// a_l·b_l + 2^31 < 2^64: the sum is below 2^58, no saturation is reachable), else by
/// the `i128` form.
#[inline(always)]
pub const fn mul_shr32_i64_small(a: i64, b: i64) -> i64 {
    if (a.unsigned_abs() >> 40) | (b.unsigned_abs() >> 49) != 0 {
        return mul_shr_i64(a, b, 32);
    }
    let (ah, al) = (a >> 32, a as u32 as u64);
    let (bh, bl) = (b >> 32, b as u32 as u64);
    let low = (al.wrapping_mul(bl).wrapping_add(1 << 31) >> 32) as i64;
    (ah.wrapping_mul(bh) << 32)
        .wrapping_add(ah.wrapping_mul(bl as i64))
        .wrapping_add((al as i64).wrapping_mul(bh))
        .wrapping_add(low)
}

/// `(u² · k + 2^67) >> 68` (round to nearest, ties toward +∞), saturated, for
/// |u| ≤ 2^39 and |k| < 2^63: equal to `sat_i64(shr_round_i128(u²·k, 68))` (a parabola's
/// y_l = u²/(2p): u in Q16, 1/(2p) in Q48, result Q12). When |u| < 2^32 (|x_l| < 65.5 mm)
/// u² is one `u32×u32→u64` product and u²·|k| an unsigned 64×64-bit product (no sign
/// handling in the 128-bit part); a negative k rounds the magnitude with ties toward 0
/// (floor(−X/2^68 + 1/2) = −⌊(X + 2^67 − 1)/2^68⌋). Otherwise the `i128` form.
#[inline(always)]
pub fn sq_mul_shr68(u: i64, k: i64) -> i64 {
    let ua = u.unsigned_abs();
    if ua >> 32 != 0 {
        let sq = i128::from(u).wrapping_mul(i128::from(u));
        return sat_i64(shr_round_i128(sq.wrapping_mul(i128::from(k)), 68));
    }
    // ua < 2^32: ua² < 2^64; ·|k| < 2^127; the rounding add < 2^128.
    let sq = ua.wrapping_mul(ua);
    let x = u128::from(sq).wrapping_mul(u128::from(k.unsigned_abs()));
    if k >= 0 {
        sat_i64((x.wrapping_add(1 << 67) >> 68) as i128)
    } else {
        sat_i64((x.wrapping_add((1 << 67) - 1) >> 68) as i128).wrapping_neg()
    }
}

/// ⌊a / n⌋ for a ≥ 0 and 1 ≤ n ≤ 65 536 without a 64-bit division (the Cortex-M4 has
/// none: `__aeabi_ldivmod` costs about a hundred instructions): long division in base
/// 2^16 with four 32-bit `udiv`s — each partial dividend r·2^16 + digit < n·2^16 ≤ 2^32
/// (the remainder r < n), each quotient digit < 2^16. Equal to `a / n`; `None` outside
/// the domain.
#[inline(always)]
pub fn div_small(a: i64, n: u32) -> Option<i64> {
    if a < 0 || n == 0 || n > 1 << 16 {
        return None;
    }
    let a = a as u64;
    let mut q = 0u64;
    let mut r = 0u32;
    for k in (0..4u32).rev() {
        let digit = ((a >> k.wrapping_mul(16)) & 0xFFFF) as u32;
        // r < n ≤ 2^16: r·2^16 + digit < 2^32.
        let cur = (r << 16) | digit;
        // n ≥ 1 (checked above): the division cannot fail.
        let qd = cur.checked_div(n).unwrap_or(0);
        r = cur.wrapping_sub(qd.wrapping_mul(n));
        q = (q << 16) | u64::from(qd);
    }
    Some(q as i64)
}

/// `(a · b) >> s` rounded to nearest for `i32` operands (exact `i64` product).
#[inline(always)]
pub const fn mul_shr_i32(a: i32, b: i32, s: u32) -> i64 {
    shr_round_i64((a as i64).wrapping_mul(b as i64), s)
}

/// Initial guesses of 1/√x for x ∈ [i/16, (i+1)/16), i = 4 … 31, Q2.30 (relative
/// error ≤ 5.8 %).
const RSQRT_SEED: [u32; 32] = [
    0,
    0,
    0,
    0,
    2_024_667_000,
    1_831_380_208,
    1_684_624_773,
    1_568_300_315,
    1_473_161_629,
    1_393_471_397,
    1_325_455_684,
    1_266_516_759,
    1_214_800_200,
    1_168_942_037,
    1_127_913_670,
    1_090_922_784,
    1_057_347_856,
    1_026_693_558,
    998_559_613,
    972_618_566,
    948_599_586,
    926_276_469,
    905_458_609,
    885_984_104,
    867_714_429,
    850_530_263,
    834_328_203,
    819_018_128,
    804_521_086,
    790_767_575,
    777_696_137,
    765_252_196,
];

/// y = 1/√x for x ∈ [0.25, 2) in Q2.30 (`x` raw in [2^28, 2^31)), Q2.30 result:
///
/// ```text
/// y0 = table[⌊16x⌋],   y ← y·(3 − (x·y)·y)/2   (three times)
/// ```
///
/// Newton's iteration for the inverse square root squares the relative error (×1.5):
/// 5.8 % → 0.5 % → 4·10⁻⁵ → 2·10⁻⁹, plus the Q30 truncations: below 4·10⁻⁹. All in
/// `u32` with `u32×u32→u64` products, one `umull` each, and no saturation: the seed is
/// within 5.8 % of 1/√x, and f(y) = y·(3 − x·y²)/2 never exceeds 1/√x (its maximum over
/// y, at y = 1/√x), so after the seed y ≤ 1.058/√x ≤ 2^31.1 and after every step
/// y ≤ 1/√x ≤ 2^31 (+ 2 LSB of truncation); hence x·y < 2^62 and its Q30 result
/// x·y ≈ √x < 2^32; (x·y)·y ≈ x·y² ≤ 1.12 (< 2^31 in Q30) so 3 − x·y² > 0;
/// y·t < 2^63 and y·t/2 < 2^32. Each u64 → u32 cast below keeps a value that fits.
/// No division.
#[inline(always)]
pub fn rsqrt_q30(x: u32) -> u32 {
    let mut y = RSQRT_SEED
        .get((x >> 26) as usize)
        .copied()
        .unwrap_or(1 << 30);
    for _ in 0..3 {
        let xy = (u64::from(x).wrapping_mul(u64::from(y)) >> 30) as u32;
        let xy2 = (u64::from(xy).wrapping_mul(u64::from(y)) >> 30) as u32;
        // xy2 ≤ 1.12·2^30 < 3·2^30 (see above): no wrap.
        let t = (3u32 << 30).wrapping_sub(xy2);
        y = (u64::from(y).wrapping_mul(u64::from(t)) >> 31) as u32;
    }
    y
}

/// Saturates an `i64` to `[-lim, lim]` and returns it as `i32` (`0 ≤ lim ≤ i32::MAX`).
#[inline(always)]
pub const fn clamp_to_i32(x: i64, lim: i32) -> i32 {
    let l = lim as i64;
    if x > l {
        lim
    } else if x < l.wrapping_neg() {
        lim.wrapping_neg()
    } else {
        x as i32
    }
}

/// Saturates an `i64` to ±2^30 (the estimator's relative-vector limit, `REL_LIMIT`)
/// and returns it as `i32`; equal to `clamp_to_i32(x, 1 << 30)` with one range test
/// (x + 2^30 < 2^31 unsigned: an add with carry and one `orrs` on a Cortex-M4) on the
/// common in-range path. The saturating branch is a separate cold function so that the
/// compiler keeps the single test instead of turning the whole into a branch-free
/// 64-bit min/max (four 64-bit compares, 11 instructions per component).
#[inline(always)]
pub const fn clamp_rel(x: i64) -> i32 {
    if (x.wrapping_add(1 << 30) as u64) >> 31 == 0 {
        x as i32
    } else {
        clamp_rel_out_of_range(x)
    }
}

/// The saturating branch of [`clamp_rel`] (x outside ±2^30).
#[cold]
#[inline(never)]
const fn clamp_rel_out_of_range(x: i64) -> i32 {
    if x < 0 {
        -(1 << 30)
    } else {
        1 << 30
    }
}

/// A unit vector in Q2.30 (`I2F30`: 2^30 = 1.0, resolution 9.3·10⁻¹⁰), the length of
/// the vector it was made from in the input's own format, and its reciprocal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnitLen {
    /// x component, Q2.30.
    pub ux: i32,
    /// y component, Q2.30.
    pub uy: i32,
    /// |(dx, dy)| in the input's format, rounded, saturated to `i64::MAX`.
    pub len: i64,
    /// 1/|d| = `rsq`·2^(`exp`) in reciprocal input units (`rsq` Q2.30 raw ∈ (2^29.5, 2^31]).
    pub rsq: u32,
    /// Binary exponent of the reciprocal (see `rsq`).
    pub exp: i32,
}

impl UnitLen {
    /// 1/|d| as a fixed-point number with `frac` fractional bits (reciprocal input
    /// units), saturated.
    pub fn recip(&self, frac: u32) -> i64 {
        let e = self.exp.saturating_add(frac as i32);
        let y = i64::from(self.rsq);
        if (0..=31).contains(&e) {
            // y < 2^32: the shifted value fits an i64 (the usual case, no i128 shift).
            y.wrapping_shl(e as u32)
        } else if e >= 0 {
            sat_i64((y as i128).wrapping_shl(e.min(100) as u32))
        } else {
            shr_round_i64(y, e.unsigned_abs().min(63))
        }
    }
}

/// The scaling step of [`normalize`]: `d·2^s` with the larger |component| in
/// [2^29, 2^30) (so both fit an `i32`), and `s`. `None` for the zero vector.
///
/// s = lz(max|d|) − 34 ∈ [−34, 29]: for s ≥ 0 the shifted value fits 30 bits, so the low
/// word of d shifted left is exact; for s < 0 an arithmetic shift right (floor).
#[inline(always)]
fn scale(dx: i64, dy: i64) -> Option<(i32, i32, i32)> {
    let m = dx.unsigned_abs().max(dy.unsigned_abs());
    if m == 0 {
        return None;
    }
    let s = (m.leading_zeros() as i32).wrapping_sub(34);
    Some(if s >= 0 {
        // |d|·2^s < 2^30: the 32-bit shift of the low word is the exact result.
        (
            (dx as i32).wrapping_shl(s as u32),
            (dy as i32).wrapping_shl(s as u32),
            s,
        )
    } else {
        let r = s.unsigned_abs();
        (dx.wrapping_shr(r) as i32, dy.wrapping_shr(r) as i32, s)
    })
}

/// The unit vector of a scaled vector n (max|n| ∈ [2^29, 2^30)) and y = 1/√(|n|²/2^60)
/// (Q2.30, so 1/|n| = y·2^-60):
///
/// ```text
/// x = |n|²/2^90 ∈ [2^28, 2^31) (Q30),  y = rsqrt_q30(x),  u = (n·y + 2^29) >> 30
/// ```
///
/// |n·y| < 2^30·2^31 = 2^61 (`smull`-class products, the rounding add cannot wrap);
/// |u| ≤ 2^30·(1 + 4·10⁻⁹) fits an `i32` before it is clamped to ±2^30.
#[inline(always)]
fn unit_of(nx: i32, ny: i32) -> (i32, i32, u32) {
    // n² < 2^60, sum < 2^61; and ≥ 2^58 since max|n| ≥ 2^29.
    let l2 = (i64::from(nx).wrapping_mul(i64::from(nx)) as u64)
        .wrapping_add(i64::from(ny).wrapping_mul(i64::from(ny)) as u64);
    let y = rsqrt_q30((l2 >> 30) as u32);
    let yi = i64::from(y);
    let unit = |n: i32| {
        let v = (i64::from(n).wrapping_mul(yi).wrapping_add(1 << 29) >> 30) as i32;
        v.clamp(-(1 << 30), 1 << 30)
    };
    (unit(nx), unit(ny), y)
}

/// Normalises `(dx, dy)` (any common fixed-point format, |components| < 2^63):
///
/// ```text
/// s so that max(|dx|,|dy|)·2^s ∈ [2^29, 2^30);   d' = d·2^s,  x = |d'|²/2^60 ∈ [0.25, 2)
/// y = 1/√x (rsqrt_q30);  u = d'·y (Q2.30);  len = (d'·u)/2^s;  1/|d| = y·2^(s−60)
/// ```
///
/// No division and no square root: the normalisation shift, one inverse square root
/// (three Newton steps) and `i32×i32` products. Relative error of u and len below
/// 2^-27 (7·10⁻⁹). `None` for the zero vector.
#[inline(always)]
pub fn normalize(dx: i64, dy: i64) -> Option<UnitLen> {
    let (nx, ny, s) = scale(dx, dy)?;
    let (ux, uy, y) = unit_of(nx, ny);
    // |n| = n·u (Q30 → shift 30): |n·u| ≤ 2^30·2^30 each, the sum < 2^61, so the
    // rounded shift is below 2^31 (|n| < 2^30.5): it fits a `u32`.
    let ln = (i64::from(nx)
        .wrapping_mul(i64::from(ux))
        .wrapping_add(i64::from(ny).wrapping_mul(i64::from(uy)))
        .wrapping_add(1 << 29)
        >> 30) as u32;
    // Undo the scaling by 2^s.
    let len = if s > 0 {
        // ln < 2^31, s ≤ 29: ln + 2^(s−1) < 2^32.
        i64::from(ln.wrapping_add(1u32.wrapping_shl((s as u32).wrapping_sub(1))) >> s as u32)
    } else if s == 0 {
        i64::from(ln)
    } else {
        let r = s.unsigned_abs();
        // ln < 2^31: ln·2^r fits an i64 for r ≤ 32; beyond, saturate.
        if r <= 32 {
            i64::from(ln).wrapping_shl(r)
        } else {
            sat_i64(i128::from(ln).wrapping_shl(r))
        }
    };
    Some(UnitLen {
        ux,
        uy,
        len,
        rsq: y,
        exp: s.wrapping_sub(60),
    })
}

/// The unit vector and 1/|d| of [`normalize`] without the length (bit for bit the same
/// `ux`, `uy`, `rsq`, `exp`; `len` is 0).
#[inline(always)]
pub fn normalize_no_len(dx: i64, dy: i64) -> Option<UnitLen> {
    let (nx, ny, s) = scale(dx, dy)?;
    let (ux, uy, y) = unit_of(nx, ny);
    Some(UnitLen {
        ux,
        uy,
        len: 0,
        rsq: y,
        exp: s.wrapping_sub(60),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // ---- the previous implementations, as references (bit for bit) ----
    /// y = 1/√x for x ∈ [0.25, 2) in Q2.30 (`x` raw in [2^28, 2^31)), Q2.30 result:
    ///
    /// ```text
    /// y0 = table[⌊16x⌋],   y ← y·(3 − (x·y)·y)/2   (three times)
    /// ```
    ///
    /// Newton's iteration for the inverse square root squares the relative error (×1.5):
    /// 5.8 % → 0.5 % → 4·10⁻⁵ → 2·10⁻⁹, plus the Q30 truncations: below 4·10⁻⁹. All in
    /// `u32` with `u32×u32→u64` products (one `umull` each: x·y < 2^62 and its Q30 result
    /// x·y ≈ √x < 2^31; (x·y)·y ≈ 1 is saturated to `u32`; 3 − x·y² < 2^32; y·t < 2^63
    /// and y·t/2 < 2^32), no division.
    fn rsqrt_ref(x: u32) -> u32 {
        let mut y = RSQRT_SEED
            .get((x >> 26) as usize)
            .copied()
            .unwrap_or(1 << 30);
        for _ in 0..3 {
            let xy = (u64::from(x).wrapping_mul(u64::from(y)) >> 30) as u32;
            let xy2 =
                (u64::from(xy).wrapping_mul(u64::from(y)) >> 30).min(u64::from(u32::MAX)) as u32;
            let t = (3u32 << 30).saturating_sub(xy2);
            y = (u64::from(y).wrapping_mul(u64::from(t)) >> 31).min(u64::from(u32::MAX)) as u32;
        }
        y
    }

    /// Normalises `(dx, dy)` (any common fixed-point format, |components| < 2^63):
    ///
    /// ```text
    /// s so that max(|dx|,|dy|)·2^s ∈ [2^29, 2^30);   d' = d·2^s,  x = |d'|²/2^60 ∈ [0.25, 2)
    /// y = 1/√x (rsqrt_q30);  u = d'·y (Q2.30);  len = (d'·u)/2^s;  1/|d| = y·2^(s−60)
    /// ```
    ///
    /// No division and no square root: the normalisation shift, one inverse square root
    /// (three Newton steps) and `i32×i32` products. Relative error of u and len below
    /// 2^-27 (7·10⁻⁹). `None` for the zero vector.
    fn normalize_ref(dx: i64, dy: i64) -> Option<UnitLen> {
        let m = dx.unsigned_abs().max(dy.unsigned_abs());
        if m == 0 {
            return None;
        }
        // Top bit of m at 63 − lz; we want it at bit 29.
        let lz = m.leading_zeros() as i32;
        let s = lz.wrapping_sub(34);
        let (nx, ny) = if s >= 0 {
            // |d|·2^s < 2^30: no overflow.
            (dx.wrapping_shl(s as u32), dy.wrapping_shl(s as u32))
        } else {
            let r = s.unsigned_abs();
            (dx.wrapping_shr(r), dy.wrapping_shr(r))
        };
        // |n| < 2^30: i32 components, so every product below is one `smull`/`smlal`.
        let (nx, ny) = (nx as i32, ny as i32);
        // n² < 2^60, sum < 2^61; and ≥ 2^58 since max|n| ≥ 2^29.
        let l2 = (i64::from(nx).wrapping_mul(i64::from(nx)) as u64)
            .wrapping_add(i64::from(ny).wrapping_mul(i64::from(ny)) as u64);
        let y = rsqrt_ref((l2 >> 30) as u32);
        // u = n/|n| = n·y/2^60 in units of 2^-30: (n·y) >> 30 (|n·y| < 2^61).
        let yi = i64::from(y);
        let ux = clamp_to_i32(shr_round_i64(i64::from(nx).wrapping_mul(yi), 30), 1 << 30);
        let uy = clamp_to_i32(shr_round_i64(i64::from(ny).wrapping_mul(yi), 30), 1 << 30);
        // |n| = n·u (Q30 → shift 30), then undo the scaling by 2^s.
        let ln = shr_round_i64(
            i64::from(nx)
                .wrapping_mul(i64::from(ux))
                .saturating_add(i64::from(ny).wrapping_mul(i64::from(uy))),
            30,
        );
        let len = if s >= 0 {
            shr_round_i64(ln, s as u32)
        } else {
            sat_i64((ln as i128).wrapping_shl(s.unsigned_abs()))
        };
        Some(UnitLen {
            ux,
            uy,
            len,
            rsq: y,
            exp: s.wrapping_sub(60),
        })
    }

    #[test]
    fn sat_i64_is_the_clamp() {
        for x in [
            0i128,
            1,
            -1,
            i128::from(i64::MAX),
            i128::from(i64::MAX) + 1,
            i128::from(i64::MIN),
            i128::from(i64::MIN) - 1,
            i128::MAX,
            i128::MIN,
            1 << 100,
            -(1 << 100),
            (1 << 64) + 5,
            -(1 << 64) + 5,
        ] {
            let clamped = x.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64;
            assert_eq!(sat_i64(x), clamped, "{x}");
        }
    }

    #[test]
    fn rounding_helpers() {
        assert_eq!(shr_round_i64(5, 1), 3);
        assert_eq!(shr_round_i64(-5, 1), -2);
        assert_eq!(shr_round_i64(7, 0), 7);
        assert_eq!(mul_shr_i64(3, 5, 1), 8);
        assert_eq!(mul_shr_i64(i64::MAX, i64::MAX, 0), i64::MAX);
        assert_eq!(clamp_to_i32(1 << 40, 100), 100);
        assert_eq!(clamp_to_i32(-(1 << 40), 100), -100);
        for x in [
            0i64,
            5,
            -5,
            (1 << 30) - 1,
            1 << 30,
            (1 << 30) + 1,
            -(1 << 30),
            -(1 << 30) - 1,
            i64::MAX,
            i64::MIN,
            1 << 40,
            -(1 << 40),
        ] {
            assert_eq!(clamp_rel(x), clamp_to_i32(x, 1 << 30), "{x}");
        }
        assert_eq!(normalize(0, 0), None);
        let u = normalize(3 << 20, 4 << 20).unwrap();
        assert_eq!(u.len, 5 << 20);
        assert!((u.ux - (0.6 * (1u64 << 30) as f64) as i32).abs() <= 1);
    }

    /// Every input of the rsqrt domain (1.9·10⁹ values: `--ignored`, ≈ 1 min in release).
    #[test]
    #[ignore]
    fn rsqrt_equals_the_reference_exhaustively() {
        for x in (1u32 << 28)..(1u32 << 31) {
            assert_eq!(rsqrt_q30(x), rsqrt_ref(x), "{x}");
        }
    }

    #[test]
    fn rsqrt_is_accurate_over_its_range() {
        let mut worst = 0f64;
        let mut x = 1u32 << 28;
        while x < (1u32 << 31) - 1000 {
            let y = rsqrt_q30(x) as f64 / (1u64 << 30) as f64;
            let xf = x as f64 / (1u64 << 30) as f64;
            worst = worst.max((y * xf.sqrt() - 1.0).abs());
            x += 99_991;
        }
        assert!(worst < 4e-9, "{worst}");
    }

    proptest! {
        #[test]
        fn mul_shr30_matches_the_i128_form(a: i32, b: i64) {
            prop_assert_eq!(mul_shr30_i32_i64(a, b), mul_shr_i64(i64::from(a), b, 30));
        }

        #[test]
        fn mul_shr30_matches_on_unit_components(a in -(1i32 << 30)..=(1 << 30), b in -(1i64 << 45)..(1i64 << 45)) {
            prop_assert_eq!(mul_shr30_i32_i64(a, b), mul_shr_i64(i64::from(a), b, 30));
        }

        #[test]
        fn mul_by_u32_matches_the_i128_form(a: i64, b in -(1i64 << 33)..(1i64 << 33), s in 0u32..40) {
            prop_assert_eq!(mul_shr_i64_by_u32(a, b, s), mul_shr_i64(a, b, s));
        }

        #[test]
        fn mul_shr30_matches_on_i32_operands(a: i32, b: i32) {
            prop_assert_eq!(mul_shr30_i32_i64(a, i64::from(b)), mul_shr_i64(i64::from(a), i64::from(b), 30));
        }

        #[test]
        fn mul_by_u32_matches_on_i32_operands(a: i32, b: u32, s in 0u32..40) {
            prop_assert_eq!(mul_shr_i64_by_u32(i64::from(a), i64::from(b), s), mul_shr_i64(i64::from(a), i64::from(b), s));
        }

        #[test]
        fn mul_by_u32_matches_on_small_operands(a in -(1i64 << 50)..(1i64 << 50), b in 0i64..(1i64 << 32), s in 29u32..33) {
            prop_assert_eq!(mul_shr_i64_by_u32(a, b, s), mul_shr_i64(a, b, s));
        }

        #[test]
        fn mul_by_u32_matches_at_the_extremes(a in prop_oneof![Just(i64::MAX), Just(i64::MIN), any::<i64>()], b in prop_oneof![Just(u32::MAX as i64), Just(0i64), 0i64..(1i64 << 32)], s in 0u32..34) {
            prop_assert_eq!(mul_shr_i64_by_u32(a, b, s), mul_shr_i64(a, b, s));
        }

        #[test]
        fn mul_shr32_matches_the_i128_form(
            a in prop_oneof![any::<i64>(), Just(i64::MAX), Just(i64::MIN)],
            b in prop_oneof![any::<i32>().prop_map(i64::from), any::<i64>(), Just(i64::from(i32::MIN)), Just(i64::from(i32::MAX))],
        ) {
            prop_assert_eq!(mul_shr32_i64_i32(a, b), mul_shr_i64(a, b, 32));
        }

        #[test]
        fn mul_shr32_small_matches_the_i128_form(
            a in prop_oneof![any::<i64>(), -(1i64 << 40)..(1i64 << 40), -(1i64 << 33)..(1i64 << 33)],
            b in prop_oneof![any::<i64>(), -(1i64 << 49)..(1i64 << 49), -(1i64 << 33)..(1i64 << 33)],
        ) {
            prop_assert_eq!(mul_shr32_i64_small(a, b), mul_shr_i64(a, b, 32));
        }

        #[test]
        fn sq_mul_shr68_matches_the_i128_form(
            u in prop_oneof![-(1i64 << 39)..=(1i64 << 39), -(1i64 << 32)..(1i64 << 32), -100_000i64..100_000],
            k in prop_oneof![any::<i64>(), -(1i64 << 48)..(1i64 << 48), Just(i64::MIN), Just(i64::MAX)],
        ) {
            let exact = sat_i64(shr_round_i128(
                i128::from(u) * i128::from(u) * i128::from(k),
                68,
            ));
            prop_assert_eq!(sq_mul_shr68(u, k), exact);
        }

        #[test]
        fn div_small_equals_the_division(
            a in prop_oneof![0i64..=i64::MAX, 0i64..(1i64 << 40), Just(i64::MAX), Just(0i64)],
            n in prop_oneof![1u32..=65_536, 1u32..70, Just(65_536u32)],
        ) {
            prop_assert_eq!(div_small(a, n), Some(a / i64::from(n)));
        }

        #[test]
        fn rsqrt_equals_the_saturating_reference(x in (1u32 << 28)..(1u32 << 31)) {
            prop_assert_eq!(rsqrt_q30(x), rsqrt_ref(x));
        }

        #[test]
        fn normalize_equals_the_reference(
            dx in prop_oneof![any::<i64>(), -(1i64 << 40)..(1i64 << 40), -(1i64 << 31)..(1i64 << 31), -1000i64..1000],
            dy in prop_oneof![any::<i64>(), -(1i64 << 40)..(1i64 << 40), -(1i64 << 31)..(1i64 << 31), -1000i64..1000],
        ) {
            let r = normalize_ref(dx, dy);
            prop_assert_eq!(normalize(dx, dy), r);
            prop_assert_eq!(normalize_no_len(dx, dy), r.map(|u| UnitLen { len: 0, ..u }));
        }

        #[test]
        fn normalize_matches_f64(dx in -(1i64 << 62)..(1i64 << 62), dy in -(1i64 << 62)..(1i64 << 62)) {
            prop_assume!(dx != 0 || dy != 0);
            let u = normalize(dx, dy).unwrap();
            let (fx, fy) = (dx as f64, dy as f64);
            let l = (fx * fx + fy * fy).sqrt();
            let q30 = (1u64 << 30) as f64;
            prop_assert!((u.ux as f64 / q30 - fx / l).abs() < 8e-9);
            prop_assert!((u.uy as f64 / q30 - fy / l).abs() < 8e-9);
            prop_assert!((u.len as f64 - l).abs() <= l * 8e-9 + 1.0);
            // 1/|d| with 40 fractional bits, when representable.
            if l > 1e-3 && l < 1e6 {
                let r = u.recip(40) as f64 / (1u64 << 40) as f64;
                prop_assert!((r * l - 1.0).abs() < 1e-8 + 1.0 / (l * (1u64 << 40) as f64));
            }
        }
    }
}
