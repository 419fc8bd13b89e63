//! Products and shifts that round toward −∞ (an arithmetic shift of the exact product,
//! i.e. floor), saturated to the result's type where the name says `_sat`; the high
//! halves of 64 × 64-bit products (the S-curve's Horner steps); floor division by a
//! small integer; the bit length.
//!
//! The control path multiplies two 32-bit raw values into an `i64` (exact, since
//! |a·b| ≤ 2^62), shifts the product back to the result's format and saturates it to 32
//! bits ([`mul_shr_floor_sat`]). On a Cortex-M4 that is `smull` plus a shift and a clamp:
//! a handful of instructions, never a library call. [`div_small`] divides an `i64` with
//! 32-bit divisions (a Cortex-M4 has no 64-bit divide).

use super::saturate::{sat_i32, sat_i64};

/// `(a · b) >> shift`, saturated to `i32` (arithmetic shift: rounds toward −∞).
/// `shift` must be below 64 (it is a constant at every call site).
#[inline(always)]
pub const fn mul_shr_floor_sat(a: i32, b: i32, shift: u32) -> i32 {
    // |a·b| ≤ 2^62: the product cannot overflow an i64.
    sat_i32((a as i64).wrapping_mul(b as i64).wrapping_shr(shift))
}

/// `(a · b) >> s` for two `i64`, exact (arithmetic shift: rounds toward −∞) and
/// saturated to `i64`; `s` ≤ 126. When both operands fit an `i32` (the common case:
/// gains and sines in Q30/Q24, commands in LSB Q16) and `s` < 64 the product is a single
/// `smull`; otherwise it is formed in an `i128` — a library routine on a Cortex-M4, so
/// keep operands that need it out of per-axis hot paths.
#[inline(always)]
pub const fn mul64_shr_floor_sat(a: i64, b: i64, s: u32) -> i64 {
    let (a32, b32) = (a as i32, b as i32);
    if s < 64 && a32 as i64 == a && b32 as i64 == b {
        // |a·b| ≤ 2^62: exact in an i64, and the shifted value cannot leave the range.
        (a32 as i64).wrapping_mul(b32 as i64).wrapping_shr(s)
    } else {
        mul64_shr_floor_sat_wide(a, b, s)
    }
}

/// [`mul64_shr_floor_sat`] always through the `i128` product (its reference).
#[inline(always)]
pub const fn mul64_shr_floor_sat_wide(a: i64, b: i64, s: u32) -> i64 {
    sat_i64((a as i128).wrapping_mul(b as i128).wrapping_shr(s))
}

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

/// Number of significant bits of `x` (0 for 0): `2^(bitlen − 1) ≤ x < 2^bitlen`.
#[inline(always)]
pub const fn bitlen(x: u64) -> u32 {
    64u32.wrapping_sub(x.leading_zeros())
}

#[cfg(test)]
mod tests {
    use crate::fixed_point::*;
    use proptest::prelude::*;

    #[test]
    fn saturates() {
        assert_eq!(mul_shr_floor_sat(i32::MAX, i32::MAX, 0), i32::MAX);
        assert_eq!(mul_shr_floor_sat(i32::MIN, i32::MAX, 0), i32::MIN);
        assert_eq!(mul_shr_floor_sat(i32::MIN, i32::MIN, 62), 1);
        assert_eq!(mul_shr_floor_sat(3, 5, 1), 7);
        assert_eq!(mul_shr_round_sat(3, 5, 1), 8);
        assert_eq!(mul_shr_floor_sat(-3, 5, 1), -8);
        assert_eq!(clamp_sym(10, 4), 4);
        assert_eq!(clamp_sym(-10, 4), -4);
    }

    proptest! {
        #[test]
        fn sat_matches_clamp(x: i64) {
            prop_assert_eq!(i64::from(sat_i32(x)), x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)));
        }

        #[test]
        fn matches_wide_reference(a: i32, b: i32, shift in 0u32..63) {
            let exact = (i128::from(a) * i128::from(b)) >> shift;
            let want = exact.clamp(i128::from(i32::MIN), i128::from(i32::MAX));
            prop_assert_eq!(i128::from(mul_shr_floor_sat(a, b, shift)), want);
        }
    }
}

#[cfg(test)]
mod mulhi_tests {
    use crate::fixed_point::*;
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
        fn div_small_equals_the_division(
            a in prop_oneof![0i64..=i64::MAX, 0i64..(1i64 << 40), Just(i64::MAX), Just(0i64)],
            n in prop_oneof![1u32..=65_536, 1u32..70, Just(65_536u32)],
        ) {
            prop_assert_eq!(div_small(a, n), Some(a / i64::from(n)));
        }

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
