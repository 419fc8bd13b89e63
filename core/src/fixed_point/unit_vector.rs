//! The reciprocal square root and the normalisation of a vector to a unit vector and a
//! length (the contour geometry's directions and distances).
//!
//! | quantity | format | range |
//! |---|---|---|
//! | 1/√x (`rsqrt_q30`) | `u32` Q2.30 | x ∈ [0.25, 2), result ∈ (0.707, 2], < 4·10⁻⁹ relative |
//! | unit vector (`normalize`) | `i32` Q2.30 | ±2^30, < 8·10⁻⁹ |
//! | 1/|d| (`UnitLen::rsq`, `exp`) | `u32` Q2.30 × 2^exp | (2^29.5, 2^31] |
//!
//! Every helper saturates instead of overflowing and never panics; no division.

use super::round::shr_round_i64;
use super::saturate::sat_i64;

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
    use crate::fixed_point::clamp_to_i32;
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
    fn normalize_a_3_4_5_vector() {
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
