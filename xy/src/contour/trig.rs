//! Sine and cosine in fixed point (the `fixed` crate has no trigonometry).
//!
//! Angle: `u32` in turns, Q0.32 (2^32 = one full turn, resolution 2^-32 turn =
//! 1.46·10⁻⁹ rad, wrapping). Result: `i64` in Q2.62 (2^62 = 1.0).
//!
//! Method: octant reduction (exact, by symmetry) to θ ∈ [0, π/4]; θ = a + b with
//! a = i/1024 turn (i = 0 … 128) from a table and 0 ≤ b < 2π/1024 = 0.0061 rad;
//!
//! ```text
//! sin b = b − b³/6 (+ b⁵/120),   cos b = 1 − b²/2 + b⁴/24
//! sin θ = sin a·cos b + cos a·sin b,   cos θ = cos a·cos b − sin a·sin b
//! ```
//!
//! in Q62 with `i128` products (10 of them). The table is computed at compile time from
//! the Taylor polynomials to degree 15/16 (error at π/4 below 5·10⁻¹⁷). Truncation of
//! the short polynomials at b < 0.0061: b⁷/5040 = 6·10⁻²⁰ (sin, with the b⁵ term),
//! b⁶/720 = 7·10⁻¹⁷ (cos); each product rounds by 2^-63. The maximum error against
//! `f64` is below 10⁻¹⁵ (tests below): on a circle of radius 4 m that is 4·10⁻⁹ µm.
//! Cost on a Cortex-M4: about 350 instructions (measured, `docs/contour.md`).

use hydra_core::fixed_point::{mul64_shr_round_sat, sat_i64, shr_round_i128};

/// 1.0 in Q62.
pub const ONE_Q62: i64 = 1 << 62;
/// 2π in Q61 (does not fit an `i64`).
const TWO_PI_Q61: i128 = 14_488_038_916_154_245_685;
/// Odd Taylor coefficients 1/3!, 1/5!, …, 1/15! in Q62 (signs applied in the code).
const SIN_C: [i64; 7] = [
    768_614_336_404_564_651,
    38_430_716_820_228_233,
    915_017_067_148_291,
    12_708_570_377_060,
    115_532_457_973,
    740_592_679,
    3_526_632,
];
/// Even Taylor coefficients 1/2!, 1/4!, …, 1/16! in Q62.
const COS_C: [i64; 8] = [
    2_305_843_009_213_693_952,
    192_153_584_101_141_163,
    6_405_119_470_038_039,
    114_377_133_393_536,
    1_270_857_037_706,
    9_627_704_831,
    52_899_477,
    220_414,
];

/// Horner evaluation of `1 − c0·z + c1·z² − …` (alternating signs), all Q62.
/// Compile time only (it builds [`TABLE`]): an index out of range would fail the build,
/// it cannot panic at run time.
#[allow(clippy::indexing_slicing)]
const fn alternating_series(z: i64, c: &[i64]) -> i64 {
    // Innermost first: p = ±c_last, then p = ±c_k + z·p … finally p = 1 + z·p.
    let mut p: i64 = 0;
    let mut k = c.len();
    let mut neg = k % 2 == 1; // sign of the innermost coefficient
    while k > 0 {
        k = k.wrapping_sub(1);
        let ck = c[k];
        let term = if neg { ck.wrapping_neg() } else { ck };
        p = term.saturating_add(mul64_shr_round_sat(z, p, 62));
        neg = !neg;
    }
    ONE_Q62.saturating_add(mul64_shr_round_sat(z, p, 62))
}

/// An angle in Q32 turns within [0, 1/8] turn as radians, Q62.
const fn radians_q62(x: u32) -> i64 {
    // x·2π: Q32·Q61 = Q93 → Q62 (≤ π/4).
    sat_i64(shr_round_i128((x as i128).wrapping_mul(TWO_PI_Q61), 31))
}

/// (sin θ, cos θ), Q62, for θ ∈ [0, π/4] by the degree-15/16 Taylor polynomials.
const fn sin_cos_poly(theta: i64) -> (i64, i64) {
    let z = mul64_shr_round_sat(theta, theta, 62);
    (
        mul64_shr_round_sat(theta, alternating_series(z, &SIN_C), 62),
        alternating_series(z, &COS_C),
    )
}

/// Table steps per 1/8 turn.
const STEPS: usize = 128;
/// log₂ of the Q32 turns per table step (2^29 / 128).
const STEP_SHIFT: u32 = 22;

/// sin and cos of i/1024 turn, i = 0 … 128, Q62 (computed at compile time; the
/// indexing below runs in the compiler, never on the target).
#[allow(clippy::indexing_slicing)]
const TABLE: [(i64, i64); STEPS + 1] = {
    let mut t = [(0i64, 0i64); STEPS + 1];
    let mut i = 0;
    while i <= STEPS {
        t[i] = sin_cos_poly(radians_q62((i as u32) << STEP_SHIFT));
        i += 1;
    }
    t
};

/// (sin θ, cos θ), Q62, for θ ∈ [0, 1/8 turn] given in Q32 turns (x ≤ 2^29).
fn sin_cos_octant(x: u32) -> (i64, i64) {
    let (sa, ca) = TABLE
        .get((x >> STEP_SHIFT) as usize)
        .copied()
        .unwrap_or((0, ONE_Q62));
    let b = radians_q62(x & ((1 << STEP_SHIFT) - 1));
    let z = mul64_shr_round_sat(b, b, 62);
    // sin b = b·(1 − z/6 + z²/120); cos b = 1 − z/2 + z²/24.
    let sb = b.saturating_sub(mul64_shr_round_sat(
        b,
        mul64_shr_round_sat(
            z,
            SIN_C[0].saturating_sub(mul64_shr_round_sat(z, SIN_C[1], 62)),
            62,
        ),
        62,
    ));
    let cb = ONE_Q62.saturating_sub(mul64_shr_round_sat(
        z,
        COS_C[0].saturating_sub(mul64_shr_round_sat(z, COS_C[1], 62)),
        62,
    ));
    (
        mul64_shr_round_sat(sa, cb, 62).saturating_add(mul64_shr_round_sat(ca, sb, 62)),
        mul64_shr_round_sat(ca, cb, 62).saturating_sub(mul64_shr_round_sat(sa, sb, 62)),
    )
}

/// `(sin, cos)` of an angle in turns (Q0.32), both in Q2.62.
pub fn sin_cos_q62(turns: u32) -> (i64, i64) {
    let octant = turns >> 29;
    let r = turns & ((1 << 29) - 1);
    // Odd octants are mirrored so θ always runs over [0, π/4].
    let x = if octant & 1 == 1 {
        (1u32 << 29).wrapping_sub(r)
    } else {
        r
    };
    let (s, c) = sin_cos_octant(x);
    match octant {
        0 => (s, c),
        1 => (c, s),
        2 => (c, s.wrapping_neg()),
        3 => (s, c.wrapping_neg()),
        4 => (s.wrapping_neg(), c.wrapping_neg()),
        5 => (c.wrapping_neg(), s.wrapping_neg()),
        6 => (c.wrapping_neg(), s),
        _ => (s.wrapping_neg(), c),
    }
}

/// An angle in degrees as turns Q0.32, rounded, wrapped to one turn (builders only).
/// `deg` must be finite and |deg| < 10⁹.
pub fn turns_from_deg(deg: f64) -> u32 {
    let t = deg / 360.0 * 4_294_967_296.0;
    // Round to nearest without `f64::round` (not in `core`).
    let i = t as i64;
    let frac = t - i as f64;
    let i = if frac >= 0.5 {
        i.saturating_add(1)
    } else if frac <= -0.5 {
        i.saturating_sub(1)
    } else {
        i
    };
    // Wrapping to one turn is the intent.
    i as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check(turns: u32) -> f64 {
        let (s, c) = sin_cos_q62(turns);
        let a = turns as f64 / 4_294_967_296.0 * core::f64::consts::TAU;
        let q = ONE_Q62 as f64;
        let es = (s as f64 / q - a.sin()).abs();
        let ec = (c as f64 / q - a.cos()).abs();
        es.max(ec)
    }

    #[test]
    fn exact_at_axes_and_octants() {
        assert_eq!(sin_cos_q62(0), (0, ONE_Q62));
        let (s, c) = sin_cos_q62(1 << 30); // 90°
        assert_eq!((s, c), (ONE_Q62, 0));
        let (s, c) = sin_cos_q62(1 << 31); // 180°
        assert_eq!((s, c), (0, -ONE_Q62));
        for k in 0..8u32 {
            for off in [0u32, 1, 12345, (1 << 29) - 1] {
                assert!(check(k.wrapping_mul(1 << 29).wrapping_add(off)) < 1e-15);
            }
        }
        assert_eq!(turns_from_deg(90.0), 1 << 30);
        assert_eq!(turns_from_deg(-90.0), 3 << 30);
        assert_eq!(turns_from_deg(450.0), 1 << 30);
    }

    proptest! {
        #[test]
        fn matches_f64(turns: u32) {
            prop_assert!(check(turns) < 1e-15);
        }

        #[test]
        fn unit_amplitude(turns: u32) {
            let (s, c) = sin_cos_q62(turns);
            let q = ONE_Q62 as f64;
            let r = ((s as f64 / q).powi(2) + (c as f64 / q).powi(2)).sqrt();
            prop_assert!((r - 1.0).abs() < 1e-15);
        }
    }
}
