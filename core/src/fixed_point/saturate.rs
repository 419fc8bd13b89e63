//! Fixed-point primitives: widening products with an explicit shift, and saturation.
//!
//! The control path multiplies two 32-bit raw values into an `i64` (exact, since
//! |a·b| ≤ 2^62), shifts the product back to the result's format and saturates it to 32
//! bits. On a Cortex-M4 that is `smull` plus a shift and `ssat`-like clamp: a handful of
//! instructions, never a library call.

/// Saturates an `i64` to the `i32` range.
#[inline(always)]
pub const fn sat_i32(x: i64) -> i32 {
    sat_i32_words((x >> 32) as i32, x as u32)
}

/// [`sat_i32`] of the `i64` whose high and low words are `hi` and `lo`: for a value
/// built word by word (LLVM turns an `i64` sum followed by [`sat_i32`] into a 64-bit
/// clamp, several instructions dearer on the Cortex-M4).
#[inline(always)]
pub const fn sat_i32_words(hi: i32, lo: u32) -> i32 {
    // The value fits an i32 exactly when its high word is the sign extension of its low
    // word; otherwise the result is MAX or MIN by its sign (`hi >> 31` is 0 or −1).
    let lo = lo as i32;
    if hi == lo >> 31 {
        lo
    } else {
        (hi >> 31) ^ i32::MAX
    }
}

/// Saturates an `i128` to the `i64` range: one test, does the high half equal the sign
/// extension of the low half (two word compares on a Cortex-M4 instead of two 128-bit
/// comparisons)?
#[inline(always)]
pub const fn sat_i64(x: i128) -> i64 {
    let lo = x as i64;
    if (x >> 64) as i64 == lo >> 63 {
        lo
    } else if x < 0 {
        i64::MIN
    } else {
        i64::MAX
    }
}

/// `(a · b) >> s` for two `i64`, exact (arithmetic shift: rounds toward −∞) and
/// saturated to `i64`; `s` ≤ 126. When both operands fit an `i32` (the common case:
/// gains and sines in Q30/Q24, commands in LSB Q16) and `s` < 64 the product is a single
/// `smull`; otherwise it is formed in an `i128` — a library routine on a Cortex-M4, so
/// keep operands that need it out of per-axis hot paths.
#[inline(always)]
pub const fn mul64_shr(a: i64, b: i64, s: u32) -> i64 {
    let (a32, b32) = (a as i32, b as i32);
    if s < 64 && a32 as i64 == a && b32 as i64 == b {
        // |a·b| ≤ 2^62: exact in an i64, and the shifted value cannot leave the range.
        (a32 as i64).wrapping_mul(b32 as i64).wrapping_shr(s)
    } else {
        mul64_shr_wide(a, b, s)
    }
}

/// [`mul64_shr`] always through the `i128` product (its reference).
#[inline(always)]
pub const fn mul64_shr_wide(a: i64, b: i64, s: u32) -> i64 {
    sat_i64((a as i128).wrapping_mul(b as i128).wrapping_shr(s))
}

/// `(a · b) >> shift`, saturated to `i32` (arithmetic shift: rounds toward −∞).
/// `shift` must be below 64 (it is a constant at every call site).
#[inline(always)]
pub const fn mul_shr(a: i32, b: i32, shift: u32) -> i32 {
    // |a·b| ≤ 2^62: the product cannot overflow an i64.
    sat_i32((a as i64).wrapping_mul(b as i64).wrapping_shr(shift))
}

/// `(a · b) >> shift` with rounding to nearest, saturated to `i32`.
#[inline(always)]
pub const fn mul_shr_round(a: i32, b: i32, shift: u32) -> i32 {
    let p = (a as i64).wrapping_mul(b as i64);
    let half = if shift == 0 {
        0
    } else {
        1i64.wrapping_shl(shift.wrapping_sub(1))
    };
    // p + half cannot overflow: |p| ≤ 2^62 and half ≤ 2^62.
    sat_i32(p.wrapping_add(half).wrapping_shr(shift))
}

/// Clamps `x` to `[-limit, limit]` (`limit ≥ 0`).
#[inline(always)]
pub const fn clamp_sym(x: i32, limit: i32) -> i32 {
    if x > limit {
        limit
    } else if x < limit.wrapping_neg() {
        limit.wrapping_neg()
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn saturates() {
        assert_eq!(mul_shr(i32::MAX, i32::MAX, 0), i32::MAX);
        assert_eq!(mul_shr(i32::MIN, i32::MAX, 0), i32::MIN);
        assert_eq!(mul_shr(i32::MIN, i32::MIN, 62), 1);
        assert_eq!(mul_shr(3, 5, 1), 7);
        assert_eq!(mul_shr_round(3, 5, 1), 8);
        assert_eq!(mul_shr(-3, 5, 1), -8);
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
            prop_assert_eq!(i128::from(mul_shr(a, b, shift)), want);
        }
    }
}
