//! 64 × 64-bit products kept to their high half: the S-curve's wide Horner steps.
//!
//! `mulhi(a, b) = ⌊a·b / 2^64⌋` with `a` a signed 64-bit value and `b` an unsigned
//! Q0.64 fraction in [0, 1): the result is `a·b` in `a`'s format, truncated toward −∞,
//! and |result| ≤ |a|. Built from four 32 × 32 → 64-bit products (`umull` on a
//! Cortex-M4), so it never calls a 128-bit library routine.

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
