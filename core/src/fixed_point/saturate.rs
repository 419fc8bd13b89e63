//! Saturation and clamps: a wide value brought back to a narrower range, never wrapped.
//!
//! `sat_*` saturate to a type's range, `clamp_*` to a given limit. On a Cortex-M4 each is
//! a compare and a select (or `ssat`); none calls a library routine.

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

#[cfg(test)]
mod tests {
    use crate::fixed_point::*;

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
}
