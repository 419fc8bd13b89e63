//! Fixed-point helpers of the contour module: wide products, rounding shifts, square
//! roots and the normalisation of a vector to a unit vector and a length.
//!
//! Every helper saturates instead of overflowing and never panics. Products of two
//! `i64` are formed in an `i128` (exact: |a·b| ≤ 2^126); products of two `i32` in an
//! `i64` (exact: ≤ 2^62).

/// Saturates an `i128` to the `i64` range.
#[inline(always)]
pub(crate) const fn sat_i64(x: i128) -> i64 {
    if x > i64::MAX as i128 {
        i64::MAX
    } else if x < i64::MIN as i128 {
        i64::MIN
    } else {
        x as i64
    }
}

/// `x >> s` rounded to nearest (ties toward +∞), for `1 ≤ s ≤ 126`.
#[inline(always)]
pub(crate) const fn shr_round_i128(x: i128, s: u32) -> i128 {
    if s == 0 {
        return x;
    }
    x.saturating_add(1i128.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)
}

/// `x >> s` rounded to nearest (ties toward +∞), for `0 ≤ s ≤ 62`.
#[inline(always)]
pub(crate) const fn shr_round_i64(x: i64, s: u32) -> i64 {
    if s == 0 {
        return x;
    }
    x.saturating_add(1i64.wrapping_shl(s.wrapping_sub(1)))
        .wrapping_shr(s)
}

/// `(a · b) >> s` rounded to nearest, formed in an `i128`, saturated to `i64`.
#[inline(always)]
pub(crate) const fn mul_shr_i64(a: i64, b: i64, s: u32) -> i64 {
    sat_i64(shr_round_i128((a as i128).wrapping_mul(b as i128), s))
}

/// `(a · b) >> s` rounded to nearest for `i32` operands (exact `i64` product).
#[inline(always)]
pub(crate) const fn mul_shr_i32(a: i32, b: i32, s: u32) -> i64 {
    shr_round_i64((a as i64).wrapping_mul(b as i64), s)
}

/// ⌊√x⌉: the integer square root rounded to nearest.
#[inline]
pub(crate) fn sqrt_round_u64(x: u64) -> u64 {
    let r = x.isqrt();
    // x − r² ≥ 0 and r² ≤ x < 2^64; rounding up when x − r² > r (i.e. √x ≥ r + ½).
    let rem = x.wrapping_sub(r.wrapping_mul(r));
    if rem > r {
        r.wrapping_add(1)
    } else {
        r
    }
}

/// Saturates an `i64` to `[-lim, lim]` and returns it as `i32` (`0 ≤ lim ≤ i32::MAX`).
#[inline(always)]
pub(crate) const fn clamp_to_i32(x: i64, lim: i32) -> i32 {
    let l = lim as i64;
    if x > l {
        lim
    } else if x < l.wrapping_neg() {
        lim.wrapping_neg()
    } else {
        x as i32
    }
}

/// A unit vector in Q2.30 (`I2F30`: 2^30 = 1.0, resolution 9.3·10⁻¹⁰) and the length of
/// the vector it was made from, in the input's own format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct UnitLen {
    /// x component, Q2.30.
    pub ux: i32,
    /// y component, Q2.30.
    pub uy: i32,
    /// |(dx, dy)| in the input's format, rounded, saturated to `i64::MAX`.
    pub len: i64,
}

/// Normalises `(dx, dy)` (any common fixed-point format, |components| < 2^63):
///
/// ```text
/// s so that max(|dx|,|dy|)·2^s ∈ [2^29, 2^30);  d' = d·2^s
/// ℓ' = ⌊√(d'x² + d'y²)⌉ ∈ [2^29, 2^30.5);  inv = ⌊2^61 / ℓ'⌋
/// u = d'·inv / 2^31  (Q2.30);  len = ℓ' / 2^s
/// ```
///
/// One integer square root and one 64-bit division. The relative error of `u` and `len`
/// is below 2^-28 (about 4·10⁻⁹). `None` for the zero vector.
pub(crate) fn normalize(dx: i64, dy: i64) -> Option<UnitLen> {
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
    // |n| < 2^30 ⇒ n² < 2^60, sum < 2^61.
    let l2 = (nx.wrapping_mul(nx) as u64).wrapping_add(ny.wrapping_mul(ny) as u64);
    let ln = sqrt_round_u64(l2);
    let inv = (1u64 << 61).checked_div(ln)? as i64;
    // |n|·inv < 2^30 · 2^32.
    let ux = shr_round_i64(nx.wrapping_mul(inv), 31);
    let uy = shr_round_i64(ny.wrapping_mul(inv), 31);
    let len = if s >= 0 {
        shr_round_i64(ln as i64, s as u32)
    } else {
        sat_i64((ln as i128).wrapping_shl(s.unsigned_abs()))
    };
    Some(UnitLen {
        ux: clamp_to_i32(ux, 1 << 30),
        uy: clamp_to_i32(uy, 1 << 30),
        len,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rounding_helpers() {
        assert_eq!(shr_round_i64(5, 1), 3);
        assert_eq!(shr_round_i64(-5, 1), -2);
        assert_eq!(shr_round_i64(7, 0), 7);
        assert_eq!(mul_shr_i64(3, 5, 1), 8);
        assert_eq!(mul_shr_i64(i64::MAX, i64::MAX, 0), i64::MAX);
        assert_eq!(sqrt_round_u64(8), 3);
        assert_eq!(sqrt_round_u64(6), 2);
        assert_eq!(sqrt_round_u64(u64::MAX), 1 << 32);
        assert_eq!(clamp_to_i32(1 << 40, 100), 100);
        assert_eq!(clamp_to_i32(-(1 << 40), 100), -100);
        assert_eq!(normalize(0, 0), None);
        let u = normalize(3 << 20, 4 << 20).unwrap();
        assert_eq!(u.len, 5 << 20);
        assert!((u.ux - (0.6 * (1u64 << 30) as f64) as i32).abs() <= 1);
    }

    proptest! {
        #[test]
        fn normalize_matches_f64(dx in -(1i64 << 62)..(1i64 << 62), dy in -(1i64 << 62)..(1i64 << 62)) {
            prop_assume!(dx != 0 || dy != 0);
            let u = normalize(dx, dy).unwrap();
            let (fx, fy) = (dx as f64, dy as f64);
            let l = (fx * fx + fy * fy).sqrt();
            let q30 = (1u64 << 30) as f64;
            prop_assert!((u.ux as f64 / q30 - fx / l).abs() < 4e-9);
            prop_assert!((u.uy as f64 / q30 - fy / l).abs() < 4e-9);
            prop_assert!((u.len as f64 - l).abs() <= l * 4e-9 + 1.0);
        }
    }
}
