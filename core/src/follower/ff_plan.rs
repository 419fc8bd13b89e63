//! The velocity and acceleration feed-forward of one `Feedforward` axis inside one table
//! segment, folded into two constants (SPEC §A, loop step 5).
//!
//! Inside segment j the table's slope is constant, so the feed-forward of the axis law,
//!
//! ```text
//! u_ff = kv±·v_ff + ka·a_ff,   v_ff = (Δx_j/len_j)·θ̇,   a_ff = (Δx_j/len_j)·θ̈
//! ```
//!
//! (θ̇, θ̈ of the master at the look-ahead, in counts/s and counts/s²), is linear in the
//! master filter's own speed and acceleration per tick:
//!
//! ```text
//! u_ff [LSB, Q16] = (θ̇_tick·M_v± + θ̈_tick·M_a) >> s
//! M_v± = kv±·(Δx_j/len_j)·f_s·2^s          θ̇_tick: counts/tick, Q16 (i32)
//! M_a  = ka·(Δx_j/len_j)·f_s²·2^(s − 16)    θ̈_tick: counts/tick², Q32 (i32)
//! ```
//!
//! (f_s = 1/T ticks/s). kv⁺ applies while the slave moves up (Δx_j·θ̇ > 0), kv⁻ while it
//! moves down, so M_v± carries the slope's sign: M_v+ (for θ̇ ≥ 0) is +kv⁺·|slope| on a
//! rising segment and −kv⁻·|slope| on a falling one, M_v− the other way round.
//!
//! The constants are worked out when the axis' feed-forward enters a segment (every ≈ 160
//! ticks on the reference machine; out of line, ≈ 160 instructions on a Cortex-M4), the
//! gains with f_s folded in once when the follower is built, so a tick pays two
//! multiply-accumulates and one shift per axis instead of converting the master's rates to
//! counts/s, to segments/s and to µm/s first. Formats: M_v±, M_a `i32` with the common
//! shift s ∈ [1, 31] chosen so the largest |M| is in [2^30, 2^31) (relative resolution
//! 2^-30; a smaller constant keeps its absolute resolution 2^-31 of the largest). Each is
//! the product of the validated gains, the segment's rise, its floating reciprocal and
//! f_s, each step normalised to 32 significant bits (relative error < 2^-29 in all).
//! |θ̇_tick| < 2^31, |θ̈_tick| ≤ 2^31 and |M| < 2^31, so the sum of the two products is
//! below 2^63; the shifted result is saturated to `i32` (Q16 LSB, ±32 768 LSB).

use crate::axis::AxisCoeffs;
use crate::fixed_point::sat_i32_words;

/// The feed-forward of one axis: its gains for the follower's period, and its constants
/// for one segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FfPlan {
    /// kv⁺·f_s, kv⁻·f_s and ka·f_s²·2^-16 with the formats' exponents (kv `I8F24`, ka
    /// `I0F32`, f_s Q16): worked out once, at [`FfPlan::new`].
    gains: [MantExp; 3],
    /// The segment the constants below are for ([`FfPlan::NONE`]: none yet).
    seg: usize,
    /// M_v for θ̇ ≥ 0 and for θ̇ < 0, LSB per (count/tick) · 2^s.
    m_v: [i32; 2],
    /// M_a, LSB per (count/tick²) · 2^(s − 16).
    m_a: i32,
    /// 2^(32 − s), s = 1 … 31 (the final shift as a multiply).
    k_shl: u32,
}

impl Default for FfPlan {
    /// Zero gains, no segment.
    fn default() -> Self {
        Self::UNSET
    }
}

impl FfPlan {
    /// Zero gains, no segment (`Default` as a `const`).
    pub(crate) const UNSET: Self = Self {
        gains: [MantExp::ZERO; 3],
        seg: Self::NONE,
        m_v: [0; 2],
        m_a: 0,
        k_shl: 1 << 31,
    };

    /// Every byte zero: the plan of an unconfigured law buffer (all-zero, so the buffer
    /// is a `.bss` static, not 14 KiB of `.data`). Never used: `Follower::configure`
    /// replaces it before a law runs.
    pub(crate) const ZEROED: Self = Self {
        gains: [MantExp::ZERO; 3],
        seg: 0,
        m_v: [0; 2],
        m_a: 0,
        k_shl: 0,
    };
}

/// A positive number m·2^e with m < 2^32 (normalised: m ≥ 2^31, or m = 0): integer
/// mantissa and exponent, for working out the constants (no floating point).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct MantExp {
    m: u32,
    e: i32,
}

impl MantExp {
    /// Zero.
    const ZERO: Self = Self { m: 0, e: 0 };

    /// `x`·2^e, normalised.
    fn new(x: u32, e: i32) -> Self {
        if x == 0 {
            return Self::ZERO;
        }
        let lz = x.leading_zeros();
        Self {
            m: x.wrapping_shl(lz),
            e: e.wrapping_sub(lz as i32),
        }
    }

    /// The product of two normalised numbers, truncated to 32 significant bits (relative
    /// error < 2^-31). Both mantissas in [2^31, 2^32): the product is in [2^62, 2^64), so
    /// its normalisation is a shift by 0 or 1 (the cheap form of [`MantExp::mul`], for the
    /// constants of every segment entered).
    fn times(self, x: Self) -> Self {
        let p = u64::from(self.m).wrapping_mul(u64::from(x.m));
        if self.m == 0 || x.m == 0 {
            return Self::ZERO;
        }
        let e = self.e.wrapping_add(x.e).wrapping_add(32);
        if p >> 63 == 0 {
            Self {
                m: (p >> 31) as u32,
                e: e.wrapping_sub(1),
            }
        } else {
            Self {
                m: (p >> 32) as u32,
                e,
            }
        }
    }

    /// The product, truncated to 32 significant bits (relative error < 2^-31).
    fn mul(self, x: u32) -> Self {
        let p = u64::from(self.m).wrapping_mul(u64::from(x));
        if p == 0 {
            return Self { m: 0, e: 0 };
        }
        let lz = p.leading_zeros();
        // p·2^lz has its top bit at 63: keep the high word.
        let m = (p.wrapping_shl(lz) >> 32) as u32;
        Self {
            m,
            // p = m·2^(32 − lz) (truncated), so the value is m·2^(e + 32 − lz).
            e: self.e.wrapping_add(32).wrapping_sub(lz as i32),
        }
    }

    /// The largest shift s with m·2^(e + s) < 2^31 (`i32::MAX` for zero).
    fn max_shift(self) -> i32 {
        if self.m == 0 {
            i32::MAX
        } else {
            // m ≥ 2^31: m·2^(e+s) < 2^31 ⟺ e + s ≤ −1.
            self.e.wrapping_neg().wrapping_sub(1)
        }
    }

    /// m·2^(e + s) as an `i32`, truncated (saturated if it does not fit).
    fn scaled(self, s: i32) -> i32 {
        let right = self.e.wrapping_add(s).wrapping_neg();
        if self.m == 0 || right >= 32 {
            0
        } else if right <= 0 {
            i32::MAX
        } else {
            self.m.wrapping_shr(right as u32) as i32
        }
    }
}

impl FfPlan {
    /// No segment.
    pub(crate) const NONE: usize = usize::MAX;

    /// Whether these constants are for segment `seg`.
    #[inline(always)]
    pub(crate) fn is_for(&self, seg: usize) -> bool {
        self.seg == seg
    }

    /// Axis `c`'s feed-forward at ticks per second `tps_q16` (Q16), no segment yet.
    pub(crate) fn new(c: &AxisCoeffs, tps_q16: i32) -> Self {
        let tps = tps_q16.unsigned_abs();
        // Validated gains are ≥ 0.
        let kv = |g: i32| MantExp::new(g.unsigned_abs(), -56).mul(tps);
        Self {
            gains: [
                kv(c.kv_pos),
                kv(c.kv_neg),
                MantExp::new(c.ka.unsigned_abs(), -96).mul(tps).mul(tps),
            ],
            ..Self::default()
        }
    }

    /// Forgets the segment (a new table).
    pub(crate) fn invalidate(&mut self) {
        self.seg = Self::NONE;
    }

    /// Works out the constants of segment `seg`: rise `dx` (raw `I24F8` µm), floating
    /// reciprocal 2^24/len_j ≈ `recip_m`·2^-`recip_s` (len_j raw `I48F16` counts; see
    /// [`crate::table::CamTable`]).
    ///
    /// With kv in `I8F24`, ka in `I0F32`, Δx in `I24F8`, 1/len_raw = recip_m·2^-(24 +
    /// recip_s) and f_s in Q16, the real constants are
    /// kv·Δx·recip_m·f_s·2^-(56 + recip_s) LSB per (count/tick) and
    /// ka·Δx·recip_m·f_s²·2^-(80 + recip_s) LSB per (count/tick²), M_a a further 2^-16.
    pub(crate) fn enter(&mut self, seg: usize, dx: i32, recip_m: u32, recip_s: u32) {
        // |Δx|·recip_m·2^-recip_s: the slope without the formats' exponents (recip_m is
        // normalised, see `CamTable`).
        let slope = MantExp::new(dx.unsigned_abs(), (recip_s as i32).wrapping_neg())
            .times(MantExp::new(recip_m, 0));
        let [kv_pos, kv_neg, ka] = self.gains.map(|g| g.times(slope));
        let s = kv_pos
            .max_shift()
            .min(kv_neg.max_shift())
            .min(ka.max_shift())
            .clamp(1, 31);
        let (p, n, a) = (kv_pos.scaled(s), kv_neg.scaled(s), ka.scaled(s));
        let (m_up, m_dn, m_a) = if dx >= 0 {
            (p, n, a)
        } else {
            (n.wrapping_neg(), p.wrapping_neg(), a.wrapping_neg())
        };
        self.seg = seg;
        self.m_v = [m_up, m_dn];
        self.m_a = m_a;
        self.k_shl = 1u32.wrapping_shl(32u32.wrapping_sub(s as u32));
    }

    /// u_ff, Q16 LSB (saturated), for the master speed `v_q16` (counts/tick, Q16) and
    /// acceleration `acc_q32` (counts/tick², Q32) at the look-ahead.
    #[inline(always)]
    pub(crate) fn ff_q16(&self, v_q16: i32, acc_q32: i32) -> i32 {
        // M_v+ or M_v− by the sign bit of θ̇.
        let m = self
            .m_v
            .get((v_q16 as u32 >> 31) as usize)
            .copied()
            .unwrap_or(0);
        // Each product below 2^62, the sum below 2^63 (see the module).
        let p = i64::from(v_q16)
            .wrapping_mul(i64::from(m))
            .wrapping_add(i64::from(acc_q32).wrapping_mul(i64::from(self.m_a)));
        // p >> s = (p·2^(32−s)) >> 32 for 1 ≤ s ≤ 31, on the two words: hi·2^(32−s) plus
        // the high word of lo·2^(32−s) (|·| < 2^62, no overflow), saturated to i32.
        let k = self.k_shl;
        let hi = i64::from((p >> 32) as i32).wrapping_mul(i64::from(k));
        let lo = (u64::from(p as u32).wrapping_mul(u64::from(k)) >> 32) as u32;
        // The 64-bit sum in words (the carry by hand), saturated on the words.
        let r_lo = (hi as u32).wrapping_add(lo);
        let r_hi = ((hi >> 32) as i32).wrapping_add(i32::from(r_lo < lo));
        sat_i32_words(r_hi, r_lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::{AxisConfig, PositionGains};
    use proptest::prelude::*;

    /// (recip_m, recip_s) of a segment of `len` raw bits, as the table builds them.
    fn recip(len: u64) -> (u32, u32) {
        crate::table::float_recip(len)
    }

    /// Axis `c`'s constants in a segment.
    fn plan(c: &AxisCoeffs, seg: usize, dx: i32, rm: u32, rs: u32, tps: i32) -> FfPlan {
        let mut p = FfPlan::new(c, tps);
        assert!(!p.is_for(seg));
        p.enter(seg, dx, rm, rs);
        p
    }

    fn coeffs(kvp: f32, kvn: f32, ka: f32) -> AxisCoeffs {
        AxisConfig {
            gains: PositionGains {
                kv_pos_lsb_per_um_s: kvp,
                kv_neg_lsb_per_um_s: kvn,
                ka_lsb_per_um_s2: ka,
                ..PositionGains::default()
            },
            ..AxisConfig::default()
        }
        .build(1000)
        .unwrap()
    }

    /// The feed-forward in f64 from the same raw inputs, LSB.
    fn reference(c: &AxisCoeffs, dx: i32, len: u64, tps_q16: i32, v_q16: i32, acc: i32) -> f64 {
        let slope = f64::from(dx) / 256.0 / (len as f64 / 65_536.0); // µm/count
        let tps = f64::from(tps_q16) / 65_536.0;
        let v = f64::from(v_q16) / 65_536.0 * tps * slope; // µm/s
        let a = f64::from(acc) / 4_294_967_296.0 * tps * tps * slope; // µm/s²
        let kv = if v >= 0.0 { c.kv_pos } else { c.kv_neg };
        f64::from(kv) / 16_777_216.0 * v + f64::from(c.ka) / 4_294_967_296.0 * a
    }

    #[test]
    fn reference_axis_segment() {
        // 0.5° segment (500 counts) rising 2 mm, 1 kHz, 3.07 counts/tick.
        let c = coeffs(0.017, 0.025, 0.0001);
        let len = 500u64 << 16;
        let (rm, rs) = recip(len);
        let tps = 1000 << 16;
        let p = plan(&c, 7, 2000 << 8, rm, rs, tps);
        assert!(p.is_for(7) && !p.is_for(8));
        for (v, acc) in [(201_195, 0), (-201_195, 0), (201_195, 40_000), (0, -40_000)] {
            let got = f64::from(p.ff_q16(v, acc)) / 65_536.0;
            let want = reference(&c, 2000 << 8, len, tps, v, acc);
            assert!((got - want).abs() < 1e-4, "{v} {acc}: {got} vs {want}");
        }
        // Rising at +θ̇: kv⁺ (0.017 · 4 µm/count · 3070 counts/s = 208.8 LSB).
        let up = f64::from(p.ff_q16(3 << 16, 0)) / 65_536.0;
        assert!((up - 0.017 * 4.0 * 3000.0).abs() < 1e-3, "{up}");
        // Falling segment, θ̇ > 0: the slave moves down, kv⁻.
        let q = plan(&c, 7, -(2000 << 8), rm, rs, tps);
        let down = f64::from(q.ff_q16(3 << 16, 0)) / 65_536.0;
        assert!((down + 0.025 * 4.0 * 3000.0).abs() < 1e-3, "{down}");
    }

    #[test]
    fn zero_gains_or_flat_segment_give_zero() {
        let (rm, rs) = recip(1 << 20);
        let p = plan(&coeffs(0.0, 0.0, 0.0), 0, 5000, rm, rs, 1000 << 16);
        assert_eq!(p.ff_q16(i32::MAX, i32::MIN), 0);
        let q = plan(&coeffs(1.0, 1.0, 0.1), 0, 0, rm, rs, 1000 << 16);
        assert_eq!(q.ff_q16(i32::MIN, i32::MAX), 0);
    }

    proptest! {
        /// Within the constants' resolution of the f64 value: one unit of each M (2^-s of
        /// each input), a relative 2^-28 for the constants' products, one Q16 LSB for
        /// the final shift; or saturated where the f64 value is beyond ±32 768 LSB.
        #[test]
        fn matches_f64(kvp in 0.0f32..100.0, kvn in 0.0f32..100.0, ka in 0.0f32..0.4,
                       dx in -(1i32 << 30)..(1i32 << 30), len in 2u64..(1u64 << 32) - (1 << 16),
                       period_us in 50u32..1_000_000, v in any::<i32>(), acc in any::<i32>()) {
            let c = coeffs(kvp, kvn, ka);
            let tps = (65_536.0e6 / f64::from(period_us)) as i32;
            let (rm, rs) = recip(len);
            let p = plan(&c, 0, dx, rm, rs, tps);
            let shr = 32 - p.k_shl.trailing_zeros();
            prop_assert!((1..=31).contains(&shr) && p.k_shl.is_power_of_two());
            let got = f64::from(p.ff_q16(v, acc));
            let want = reference(&c, dx, len, tps, v, acc) * 65_536.0;
            let limit = f64::from(i32::MAX);
            if want.abs() > limit * (1.0 + 1e-6) {
                prop_assert_eq!(got, if want < 0.0 { f64::from(i32::MIN) } else { limit });
            } else if want.abs() < limit * (1.0 - 1e-6) {
                let unit = (f64::from(v).abs() + f64::from(acc).abs()) * 2f64.powi(-(shr as i32));
                let bound = unit + want.abs() * 2f64.powi(-28) + 1.0;
                prop_assert!((got - want).abs() <= bound, "got {} want {} bound {}", got, want, bound);
            }
        }
    }
}
