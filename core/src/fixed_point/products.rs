//! Wide products and rounding shifts: `i64` products through 32 × 32 → 64-bit multiplies
//! (Cortex-M4 `smull`/`umull`), the high halves of 64 × 64-bit products (the S-curve's
//! Horner steps), division of an `i64` by a small integer, saturating clamps to `i32`.
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

use super::saturate::sat_i64;

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

/// `(u² · k + 2^67) >> 68` (round to nearest, ties toward +∞), saturated, for any u and
/// k: u²·k / 2^68 exactly rounded (as `shr_round_i128` would, without its add's wrap near
/// `i128::MAX`) where u²·k fits an `i128`, and
/// `i64::MAX` / `i64::MIN` (the sign of k) beyond (a parabola's
/// y_l = u²/(2p): u in Q16, 1/(2p) in Q48, result Q12). When |u| < 2^32 (|x_l| < 65.5 mm)
/// u² is one `u32×u32→u64` product and u²·|k| an unsigned 64×64-bit product (no sign
/// handling in the 128-bit part); a negative k rounds the magnitude with ties toward 0
/// (floor(−X/2^68 + 1/2) = −⌊(X + 2^67 − 1)/2^68⌋). Otherwise the `i128` form.
#[inline(always)]
pub fn sq_mul_shr68(u: i64, k: i64) -> i64 {
    let ua = u.unsigned_abs();
    if ua >> 32 != 0 {
        // u² ≤ 2^126 fits; u²·k may not (|u| > 2^32 with |k| near 2^63): saturate.
        let sq = i128::from(u).wrapping_mul(i128::from(u));
        return match sq.checked_mul(i128::from(k)) {
            // (x >> 68) + bit 67: the rounded shift without the add that could wrap
            // within 2^67 of i128::MAX.
            Some(x) => sat_i64((x >> 68).wrapping_add((x >> 67) & 1)),
            None if k < 0 => i64::MIN,
            None => i64::MAX,
        };
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

// ---- 64 × 64-bit products kept to their high half (the S-curve's Horner steps) ----

/// `⌊a·b / 2^64⌋` for unsigned `a`, `b` (the high half of the 128-bit product).
#[inline(always)]
pub const fn umulhi(a: u64, b: u64) -> u64 {
    const LO: u64 = 0xFFFF_FFFF;
    let (a0, a1) = (a & LO, a.wrapping_shr(32));
    let (b0, b1) = (b & LO, b.wrapping_shr(32));
    // Each partial product is < 2^64 (both factors < 2^32): exact.
    let p00 = a0.wrapping_mul(b0);
    let p01 = a0.wrapping_mul(b1);
    let p10 = a1.wrapping_mul(b0);
    let p11 = a1.wrapping_mul(b1);
    // Column 32…63: three terms < 2^32 each, the sum < 2^34: no overflow.
    let mid = p00
        .wrapping_shr(32)
        .wrapping_add(p01 & LO)
        .wrapping_add(p10 & LO);
    // The high half of a 128-bit product is < 2^64: the wrapping adds are exact.
    p11.wrapping_add(p01.wrapping_shr(32))
        .wrapping_add(p10.wrapping_shr(32))
        .wrapping_add(mid.wrapping_shr(32))
}

/// `⌊a·b / 2^64⌋` for signed `a` and unsigned `b` (floor, i.e. toward −∞).
///
/// For `a < 0` the unsigned product of `a + 2^64` and `b` is `a·b + 2^64·b`, so the
/// high half is `⌊a·b / 2^64⌋ + b`: subtracting `b` is exact.
#[inline(always)]
pub const fn mulhi(a: i64, b: u64) -> i64 {
    let hi = umulhi(a as u64, b);
    if a < 0 {
        hi.wrapping_sub(b) as i64
    } else {
        hi as i64
    }
}

/// Number of significant bits of `x` (0 for 0): `2^(bitlen − 1) ≤ x < 2^bitlen`.
#[inline(always)]
pub const fn bitlen(x: u64) -> u32 {
    64u32.wrapping_sub(x.leading_zeros())
}

/// `x · 2^s` for a signed shift `s`, saturated to the `i64` range (right shifts floor).
#[inline]
pub const fn shl_signed_sat(x: i64, s: i32) -> i64 {
    if s >= 0 {
        let s = s as u32;
        if s >= 63 {
            return if x > 0 {
                i64::MAX
            } else if x < 0 {
                i64::MIN
            } else {
                0
            };
        }
        // Saturate unless x has s + 1 redundant sign bits.
        let lim = i64::MAX.wrapping_shr(s);
        if x > lim {
            i64::MAX
        } else if x < lim.wrapping_neg().wrapping_sub(1) {
            i64::MIN
        } else {
            x.wrapping_shl(s)
        }
    } else {
        let r = s.unsigned_abs();
        if r >= 63 {
            if x < 0 {
                -1
            } else {
                0
            }
        } else {
            x.wrapping_shr(r)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
            u in prop_oneof![-(1i64 << 39)..=(1i64 << 39), -(1i64 << 32)..(1i64 << 32), -100_000i64..100_000, Just(1i64 << 32), Just(-(1i64 << 32))],
            k in prop_oneof![any::<i64>(), -(1i64 << 48)..(1i64 << 48), Just(i64::MIN), Just(i64::MAX)],
        ) {
            // u²·k beyond i128 (|u| > 2^32, |k| near 2^63) saturates to k's sign; the
            // rounding by Euclidean division, independent of the shifts under test.
            let exact = (i128::from(u) * i128::from(u))
                .checked_mul(i128::from(k))
                .map_or(if k < 0 { i64::MIN } else { i64::MAX }, |x| {
                    let d = 1i128 << 68;
                    sat_i64(x.div_euclid(d) + i128::from(x.rem_euclid(d) >= d / 2))
                });
            prop_assert_eq!(sq_mul_shr68(u, k), exact);
        }

        #[test]
        fn div_small_equals_the_division(
            a in prop_oneof![0i64..=i64::MAX, 0i64..(1i64 << 40), Just(i64::MAX), Just(0i64)],
            n in prop_oneof![1u32..=65_536, 1u32..70, Just(65_536u32)],
        ) {
            prop_assert_eq!(div_small(a, n), Some(a / i64::from(n)));
        }
    }
}

#[cfg(test)]
mod mulhi_tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn edges() {
        assert_eq!(umulhi(u64::MAX, u64::MAX), u64::MAX - 1);
        assert_eq!(mulhi(-1, 1), -1);
        assert_eq!(mulhi(-1, 0), 0);
        assert_eq!(mulhi(i64::MIN, u64::MAX), i64::MIN);
        assert_eq!(mulhi(i64::MIN, 1 << 63), -(1 << 62));
        assert_eq!(bitlen(0), 0);
        assert_eq!(bitlen(1), 1);
        assert_eq!(bitlen(u64::MAX), 64);
        assert_eq!(shl_signed_sat(3, 2), 12);
        assert_eq!(shl_signed_sat(-13, -2), -4);
        assert_eq!(shl_signed_sat(1 << 40, 30), i64::MAX);
        assert_eq!(shl_signed_sat(-(1 << 40), 30), i64::MIN);
        assert_eq!(shl_signed_sat(5, 70), i64::MAX);
        assert_eq!(shl_signed_sat(-5, -70), -1);
    }

    proptest! {
        #[test]
        fn mulhi_matches_i128(a: i64, b: u64) {
            let want = (i128::from(a) * i128::from(b)) >> 64;
            prop_assert_eq!(i128::from(mulhi(a, b)), want);
        }

        #[test]
        fn umulhi_matches_u128(a: u64, b: u64) {
            prop_assert_eq!(u128::from(umulhi(a, b)), (u128::from(a) * u128::from(b)) >> 64);
        }

        #[test]
        fn shl_matches_i128(x in -(1i64 << 50)..(1i64 << 50), s in -70i32..70) {
            let want = if s >= 0 {
                (i128::from(x) << s.min(100)).clamp(i128::from(i64::MIN), i128::from(i64::MAX))
            } else {
                i128::from(x) >> (-s).min(127)
            };
            prop_assert_eq!(i128::from(shl_signed_sat(x, s)), want);
        }
    }
}

#[cfg(test)]
mod edge_tests {
    use super::*;

    /// u²·k within 2^67 of `i128::MAX`: the rounding must not wrap the sign.
    #[test]
    fn sq_mul_shr68_near_the_top_of_i128_keeps_its_sign() {
        let want = ((1i128 << 64) * i128::from(i64::MAX)) >> 68; // exact: bit 67 is 1 → +1
        let got = sq_mul_shr68(1 << 32, i64::MAX);
        assert_eq!(i128::from(got), want + 1);
        assert_eq!(sq_mul_shr68(-(1 << 32), i64::MAX), got);
        assert_eq!(sq_mul_shr68(1 << 40, i64::MAX), i64::MAX);
        assert_eq!(sq_mul_shr68(1 << 40, i64::MIN), i64::MIN);
    }
}
