//! Products and shifts that round to nearest (ties toward +∞), saturated where they can
//! overflow: every name says `round`.
//!
//! Products of two `i64` are formed in an `i128` (exact: |a·b| ≤ 2^126); products of two
//! `i32` in an `i64` (exact: ≤ 2^62). The `i64` helpers used per period
//! ([`mul_shr30_round_i32_i64`], [`mul_shr_round_i64_by_u32`], [`mul_shr32_round_i64_i32`],
//! [`mul_shr32_round_i64_small`], [`sq_mul_shr68_round`]) give exactly the `i128` form's
//! value ([`mul64_shr_round_sat`]) from 32-bit products when their operands are in range
//! (tested against it), and fall back to it otherwise.

use super::saturate::{sat_i32, sat_i64};

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

/// `(a · b) >> shift` with rounding to nearest, saturated to `i32`.
#[inline(always)]
pub const fn mul_shr_round_sat(a: i32, b: i32, shift: u32) -> i32 {
    let p = (a as i64).wrapping_mul(b as i64);
    let half = if shift == 0 {
        0
    } else {
        1i64.wrapping_shl(shift.wrapping_sub(1))
    };
    // p + half cannot overflow: |p| ≤ 2^62 and half ≤ 2^62.
    sat_i32(p.wrapping_add(half).wrapping_shr(shift))
}

/// `(a · b) >> s` rounded to nearest for `i32` operands (exact `i64` product).
#[inline(always)]
pub const fn mul_shr_round_i64(a: i32, b: i32, s: u32) -> i64 {
    shr_round_i64((a as i64).wrapping_mul(b as i64), s)
}

/// `(a · b) >> s` rounded to nearest, formed in an `i128`, saturated to `i64`.
#[inline(always)]
pub const fn mul64_shr_round_sat(a: i64, b: i64, s: u32) -> i64 {
    sat_i64(shr_round_i128((a as i128).wrapping_mul(b as i128), s))
}

/// `(a · b) >> 30` rounded to nearest for an `i32` (a unit-vector component, Q30) times
/// an `i64`, equal to `mul64_shr_round_sat(a, b, 30)` but from two 32-bit products:
///
/// ```text
/// b = b_h·2^32 + b_l  →  (a·b + 2^29) >> 30 = 4·a·b_h + (a·b_l + 2^29) >> 30   (exact)
/// ```
///
/// (`smull` for a·b_h, `umull` + `mla` for a·b_l); falls back to the `i128` form when
/// 4·a·b_h could leave the `i64` range.
#[inline(always)]
pub const fn mul_shr30_round_i32_i64(a: i32, b: i64) -> i64 {
    if b as i32 as i64 == b {
        // b fits an i32 (a path's r″ in Q32 is usually far below 2^31): one `smull`,
        // |a·b| ≤ 2^62, the rounding add cannot wrap; the exact value, as below.
        return (a as i64).wrapping_mul(b).wrapping_add(1 << 29) >> 30;
    }
    let hi = (a as i64).wrapping_mul(b >> 32);
    if hi.unsigned_abs() >= 1 << 60 {
        return mul64_shr_round_sat(a as i64, b, 30);
    }
    let lo = (a as i64).wrapping_mul(b as u32 as i64);
    // |lo| < 2^63; the rounded shift cannot overflow; |4·hi| < 2^62.
    (hi << 2).wrapping_add(lo.wrapping_add(1 << 29) >> 30)
}

/// `(a · b) >> s` rounded to nearest (2 ≤ s ≤ 32 on the fast path), saturated, for an `i64` times a
/// non-negative `i64` (a reciprocal such as 1/|r′| in Q30): equal to `mul64_shr_round_sat(a, b,
/// s)`. When b < 2^32 it is formed from two 32-bit products:
///
/// ```text
/// a = a_h·2^32 + a_l  →  (a·b + 2^(s−1)) >> s = a_h·b·2^(32−s) + (a_l·b + 2^(s−1)) >> s
/// ```
///
/// (exact; a_h·b is an `i32×u32` product, a_l·b a `umull`), else — or when the first
/// term could leave the `i64` range — by the `i128` form.
#[inline(always)]
pub const fn mul_shr_round_i64_by_u32(a: i64, b: i64, s: u32) -> i64 {
    if b < 0 || b > u32::MAX as i64 || s < 2 || s > 32 {
        return mul64_shr_round_sat(a, b, s);
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
        return mul64_shr_round_sat(a, b, s);
    }
    let lo = ((a as u32 as u64)
        .wrapping_mul(b as u64)
        .wrapping_add(1u64.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)) as i64;
    hi.wrapping_shl(32u32.wrapping_sub(s)).wrapping_add(lo)
}

/// `(a · b) >> 32` rounded to nearest, saturated, for two `i64`: equal to
/// `mul64_shr_round_sat(a, b, 32)`. When b fits an `i32` it is formed from two 32-bit products:
///
/// ```text
/// a = a_h·2^32 + a_l  →  (a·b + 2^31) >> 32 = a_h·b + (a_l·b + 2^31) >> 32   (exact)
/// ```
///
/// (|a_h·b| ≤ 2^62, an `smull`; |a_l·b| < 2^63 − 2^31, a `umull` and a sign correction;
/// the sum below 2^62 + 2^31: no saturation is reachable), else by the `i128` form.
#[inline(always)]
pub const fn mul_shr32_round_i64_i32(a: i64, b: i64) -> i64 {
    if b < i32::MIN as i64 || b > i32::MAX as i64 {
        return mul64_shr_round_sat(a, b, 32);
    }
    let hi = (a >> 32).wrapping_mul(b);
    let lo = (a as u32 as i64).wrapping_mul(b);
    hi.wrapping_add(lo.wrapping_add(1 << 31) >> 32)
}

/// `(a · b) >> 32` rounded to nearest, saturated, for two `i64`: equal to
/// `mul64_shr_round_sat(a, b, 32)`. When |a| < 2^40 and |b| < 2^49 (a parabola's u in Q16 times
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
pub const fn mul_shr32_round_i64_small(a: i64, b: i64) -> i64 {
    if (a.unsigned_abs() >> 40) | (b.unsigned_abs() >> 49) != 0 {
        return mul64_shr_round_sat(a, b, 32);
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
pub fn sq_mul_shr68_round(u: i64, k: i64) -> i64 {
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

#[cfg(test)]
mod tests {
    use crate::fixed_point::*;
    use proptest::prelude::*;

    #[test]
    fn rounding_helpers() {
        assert_eq!(shr_round_i64(5, 1), 3);
        assert_eq!(shr_round_i64(-5, 1), -2);
        assert_eq!(shr_round_i64(7, 0), 7);
        assert_eq!(mul64_shr_round_sat(3, 5, 1), 8);
        assert_eq!(mul64_shr_round_sat(i64::MAX, i64::MAX, 0), i64::MAX);
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
            prop_assert_eq!(mul_shr30_round_i32_i64(a, b), mul64_shr_round_sat(i64::from(a), b, 30));
        }

        #[test]
        fn mul_shr30_matches_on_unit_components(a in -(1i32 << 30)..=(1 << 30), b in -(1i64 << 45)..(1i64 << 45)) {
            prop_assert_eq!(mul_shr30_round_i32_i64(a, b), mul64_shr_round_sat(i64::from(a), b, 30));
        }

        #[test]
        fn mul_by_u32_matches_the_i128_form(a: i64, b in -(1i64 << 33)..(1i64 << 33), s in 0u32..40) {
            prop_assert_eq!(mul_shr_round_i64_by_u32(a, b, s), mul64_shr_round_sat(a, b, s));
        }

        #[test]
        fn mul_shr30_matches_on_i32_operands(a: i32, b: i32) {
            prop_assert_eq!(mul_shr30_round_i32_i64(a, i64::from(b)), mul64_shr_round_sat(i64::from(a), i64::from(b), 30));
        }

        #[test]
        fn mul_by_u32_matches_on_i32_operands(a: i32, b: u32, s in 0u32..40) {
            prop_assert_eq!(mul_shr_round_i64_by_u32(i64::from(a), i64::from(b), s), mul64_shr_round_sat(i64::from(a), i64::from(b), s));
        }

        #[test]
        fn mul_by_u32_matches_on_small_operands(a in -(1i64 << 50)..(1i64 << 50), b in 0i64..(1i64 << 32), s in 29u32..33) {
            prop_assert_eq!(mul_shr_round_i64_by_u32(a, b, s), mul64_shr_round_sat(a, b, s));
        }

        #[test]
        fn mul_by_u32_matches_at_the_extremes(a in prop_oneof![Just(i64::MAX), Just(i64::MIN), any::<i64>()], b in prop_oneof![Just(u32::MAX as i64), Just(0i64), 0i64..(1i64 << 32)], s in 0u32..34) {
            prop_assert_eq!(mul_shr_round_i64_by_u32(a, b, s), mul64_shr_round_sat(a, b, s));
        }

        #[test]
        fn mul_shr32_matches_the_i128_form(
            a in prop_oneof![any::<i64>(), Just(i64::MAX), Just(i64::MIN)],
            b in prop_oneof![any::<i32>().prop_map(i64::from), any::<i64>(), Just(i64::from(i32::MIN)), Just(i64::from(i32::MAX))],
        ) {
            prop_assert_eq!(mul_shr32_round_i64_i32(a, b), mul64_shr_round_sat(a, b, 32));
        }

        #[test]
        fn mul_shr32_small_matches_the_i128_form(
            a in prop_oneof![any::<i64>(), -(1i64 << 40)..(1i64 << 40), -(1i64 << 33)..(1i64 << 33)],
            b in prop_oneof![any::<i64>(), -(1i64 << 49)..(1i64 << 49), -(1i64 << 33)..(1i64 << 33)],
        ) {
            prop_assert_eq!(mul_shr32_round_i64_small(a, b), mul64_shr_round_sat(a, b, 32));
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
            prop_assert_eq!(sq_mul_shr68_round(u, k), exact);
        }
    }
}

#[cfg(test)]
mod edge_tests {
    use crate::fixed_point::*;

    /// u²·k within 2^67 of `i128::MAX`: the rounding must not wrap the sign.
    #[test]
    fn sq_mul_shr68_near_the_top_of_i128_keeps_its_sign() {
        let want = ((1i128 << 64) * i128::from(i64::MAX)) >> 68; // exact: bit 67 is 1 → +1
        let got = sq_mul_shr68_round(1 << 32, i64::MAX);
        assert_eq!(i128::from(got), want + 1);
        assert_eq!(sq_mul_shr68_round(-(1 << 32), i64::MAX), got);
        assert_eq!(sq_mul_shr68_round(1 << 40, i64::MAX), i64::MAX);
        assert_eq!(sq_mul_shr68_round(1 << 40, i64::MIN), i64::MIN);
    }
}
