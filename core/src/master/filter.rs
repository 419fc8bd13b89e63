//! A critically damped α-β-γ tracking filter for a quantised master.
//!
//! A 0.001° encoder at 3 °/s gives 3 counts per 1 ms period, so the raw second difference
//! of eq. 4 is mostly quantisation noise. The filter keeps position, velocity and
//! acceleration, predicts one tick ahead and corrects with the residual r:
//!
//! ```text
//! θp = θ + θ̇·T + ½θ̈·T²,  θ̇p = θ̇ + θ̈·T,  r = θ_meas − θp
//! θ = θp + g·r,  θ̇ = θ̇p + (h/T)·r,  θ̈ = θ̈ + (2k/T²)·r
//! g = 1 − ξ³,  h = 1.5·(1 − ξ)²·(1 + ξ),  2k = (1 − ξ)³,  ξ = exp(−2π·f_b·T)
//! ```
//!
//! (the fading-memory polynomial filter of degree 2: all three poles at ξ). It tracks a
//! constant acceleration with zero steady-state error, so it adds no lag to a smoothly
//! moving master, and its −3 dB bandwidth is about f_b.
//!
//! Formats: position `I48F16` master counts (`i64`, modulo 2^64 raw: the master is a
//! counter on a circle of 2^48 counts, followed through a wrap); velocity `I32F32`
//! counts/tick (`i64`, resolution 2.3e-10 counts/tick, clamped to ±2^14 counts/tick);
//! acceleration `I0F32` counts/tick² in an `i32`
//! (resolution 2.3e-10, range ±0.5 counts/tick² = ±5·10⁵ counts/s² at 1 kHz, saturated);
//! gains `g` and `2k` as Q1.31 and `h` (≤ 1.5) as Q2.30 in `i32`, so every gain product is
//! one 32×32→64-bit multiply of the residual (an `i32` after its clamp); speed and
//! acceleration handed to the loop in Q24.8 counts/s and counts/s² ([`MasterAhead`]). The
//! residual is saturated to ±2^15 counts (±2^31 raw, an `i32`) before the gain products,
//! so every product is below 2^62; a saturated residual is reported as a master jump.

use crate::fixed_point::{mul_shr_floor_sat, sat_i32};
use crate::units::{Master, MasterRate};

/// Filter configuration in engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterFilterConfig {
    /// Bandwidth f_b, Hz (0.1 … 0.2/T).
    pub bandwidth_hz: f32,
}

impl Default for MasterFilterConfig {
    fn default() -> Self {
        Self { bandwidth_hz: 8.0 }
    }
}

/// A filter parameter out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MasterFilterError {
    /// The period is not in 50 µs … 1 s.
    Period,
    /// The bandwidth is not in 0.1 Hz … 0.2/T.
    Bandwidth,
}

/// Validated filter coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterFilterCoeffs {
    /// g = 1 − ξ³, Q1.31 (0 < g < 1).
    g_q31: i32,
    /// h = 1.5·(1 − ξ)²·(1 + ξ), Q2.30 (0 < h < 1.5).
    h_q30: i32,
    /// 2k = (1 − ξ)³, Q1.31 (0 < 2k < 1).
    k2_q31: i32,
    /// Ticks per second, Q16 (1e6 / period_us · 2^16 < 2^31 for T ≥ 50 µs).
    tps_q16: i32,
}

impl MasterFilterCoeffs {
    /// Every coefficient zero (placeholder of an unconfigured law buffer, see
    /// `ValveCoeffs::UNSET`).
    pub(crate) const UNSET: Self = Self {
        g_q31: 0,
        h_q30: 0,
        k2_q31: 0,
        tps_q16: 0,
    };
}

/// Largest extrapolation lead of [`MasterFilter::ahead`], ticks Q16 (2^14 ticks).
pub const MAX_LEAD_Q16: i32 = 1 << 30;

/// Largest filtered speed, raw Q32 counts/tick (2^14 counts/tick).
const MAX_VEL: i64 = 1 << 46;

/// Clamps a speed to ±[`MAX_VEL`]: one test of the high word
/// (in range exactly when bits 46…63 are all equal).
#[inline(always)]
fn clamp_vel(v: i64) -> i64 {
    let hi = (v >> 32) as i32;
    if hi >> 14 == hi >> 31 {
        v
    } else {
        clamp_vel_out(v)
    }
}

/// [`clamp_vel`] for a speed out of range (cold: a master near 2^14 counts/tick).
#[cold]
#[inline(never)]
fn clamp_vel_out(v: i64) -> i64 {
    if v < 0 {
        MAX_VEL.wrapping_neg()
    } else {
        MAX_VEL
    }
}

impl MasterFilterCoeffs {
    /// Ticks per second, Q16 (the period's reciprocal).
    pub fn tps_q16(&self) -> i32 {
        self.tps_q16
    }
}

impl MasterFilterConfig {
    /// Validates the configuration for a control period in µs.
    pub fn build(&self, period_us: u32) -> Result<MasterFilterCoeffs, MasterFilterError> {
        if !(50..=1_000_000).contains(&period_us) {
            return Err(MasterFilterError::Period);
        }
        let t = f64::from(period_us) * 1e-6;
        let fb = f64::from(self.bandwidth_hz);
        if !fb.is_finite() || fb < 0.1 || fb > 0.2 / t {
            return Err(MasterFilterError::Bandwidth);
        }
        let xi = libm_exp(-2.0 * core::f64::consts::PI * fb * t);
        let one = 1.0 - xi;
        let q = |x: f64, frac_bits: u32| (x * (1u64 << frac_bits) as f64) as i32;
        Ok(MasterFilterCoeffs {
            g_q31: q(1.0 - xi * xi * xi, 31),
            h_q30: q(1.5 * one * one * (1.0 + xi), 30),
            k2_q31: q(one * one * one, 31),
            tps_q16: (65_536.0e6 / f64::from(period_us)) as i32,
        })
    }
}

/// `exp(x)` for x ≤ 0 without `std` (range reduction by halving and a Taylor series;
/// relative error below 1e-12 for x ∈ [−50, 0]). Configuration time only.
fn libm_exp(x: f64) -> f64 {
    let mut halvings = 0u32;
    let mut y = x;
    while y < -0.5 && halvings < 64 {
        y *= 0.5;
        halvings = halvings.saturating_add(1);
    }
    let mut term = 1.0;
    let mut sum = 1.0;
    for n in 1..20u32 {
        term *= y / f64::from(n);
        sum += term;
    }
    for _ in 0..halvings {
        sum *= sum;
    }
    sum
}

/// The filter's estimate of the master at some instant.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterEstimate {
    /// Position, master counts.
    pub pos: Master,
    /// Speed, master counts/s.
    pub rate_per_s: MasterRate,
    /// Acceleration, master counts/s² (`I48F16`).
    pub acc_per_s2: MasterRate,
}

/// Filter state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterFilter {
    pos: i64, // I48F16 counts
    vel: i64, // Q32 counts/tick
    acc: i32, // Q32 counts/tick² (±0.5, saturated)
    started: bool,
}

impl MasterFilter {
    /// Not started (the same as `Default`, as a `const`).
    pub(crate) const START: Self = Self {
        pos: 0,
        vel: 0,
        acc: 0,
        started: false,
    };
}

/// The master `n` ticks ahead in the loop's working formats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterAhead {
    /// Position, master counts (`I48F16`).
    pub pos: Master,
    /// Speed, master counts/s, Q24.8 (±8.4e6 counts/s, saturated).
    pub rate_q8: i32,
    /// Acceleration, master counts/s², Q24.8 (saturated).
    pub acc_q8: i32,
}

impl MasterFilter {
    /// Feeds one measurement. Returns `true` if the residual had to be clamped (the
    /// measurement jumped by 2^15 counts or more from the prediction).
    ///
    /// Positions are computed modulo 2^64 raw (`wrapping_*`): the master is a counter on
    /// the `I48F16` circle of 2^48 counts, so a counter that wraps is followed through the
    /// wrap, and no position sum needs a 64-bit saturation. The speed is clamped to
    /// ±2^46 raw (Q32: ±16 384 counts/tick, 1.6·10⁷ counts/s at 1 kHz), which keeps
    /// every later conversion of it to 32 bits exact.
    #[inline]
    pub fn update(&mut self, c: &MasterFilterCoeffs, meas: Master) -> bool {
        let m = meas.to_bits();
        if !self.started {
            *self = Self {
                pos: m,
                vel: 0,
                acc: 0,
                started: true,
            };
            return false;
        }
        // Predict one tick: step = (θ̇ + ½θ̈) >> 16 (Q32 → Q16 counts): |θ̇| ≤ 2^46 and
        // |½θ̈| < 2^30, so the sum cannot wrap and |step| < 2^31.
        let step = self.vel.wrapping_add(i64::from(self.acc >> 1)) >> 16;
        // The residual modulo 2^64; a jump when it does not fit an i32 (|r| ≥ 2^15
        // counts), then saturated to ±2^31 raw. One test of the high word.
        let r_raw = m.wrapping_sub(self.pos).wrapping_sub(step);
        let jump = (r_raw >> 32) as i32 != (r_raw as i32) >> 31;
        let r = sat_i32(r_raw);
        // |r| ≤ 2^31 and gains < 2^31: every product is below 2^62.
        // r (Q16) · g (Q31) >> 31 = Q16;  r (Q16) · h (Q30) >> 14 = Q32;
        // r (Q16) · 2k (Q31) >> 15 = Q32.
        let r64 = i64::from(r);
        // θ = θ + step + g·r (mod 2^64).
        let dpos = step.wrapping_add(r64.wrapping_mul(i64::from(c.g_q31)) >> 31);
        self.pos = self.pos.wrapping_add(dpos);
        // θ̇ = θ̇ + θ̈ + h·r: |θ̇| ≤ 2^46, |θ̈| < 2^31, |h·r| < 1.5·2^47: the sum is below
        // 2^49, then clamped to ±2^46.
        let vel = self
            .vel
            .wrapping_add(i64::from(self.acc))
            .wrapping_add(r64.wrapping_mul(i64::from(c.h_q30)) >> 14);
        self.vel = clamp_vel(vel);
        self.acc = self.acc.saturating_add(mul_shr_floor_sat(r, c.k2_q31, 15));
        jump
    }

    /// The estimate `lead_q16 / 2^16` ticks after the last measurement, in the loop's
    /// working formats (see [`MasterAhead`]):
    ///
    /// ```text
    /// θ(n) = θ + θ̇·n + ½θ̈·n²,   θ̇(n) = θ̇ + θ̈·n   (n in ticks)
    /// ```
    ///
    /// Every product is 32×32→64 bits: the velocity enters as Q16 counts/tick (|θ̇| ≤
    /// 2^14 counts/tick, kept so by [`MasterFilter::update`]), the acceleration as Q32
    /// counts/tick² (±0.5), the lead as Q16 ticks (clamped to 0 … 2^14 ticks; a validated
    /// axis lead is below 2^14), ticks/s as Q16 (≤ 20 kHz). The position is modulo 2^64
    /// raw like the filter's.
    #[inline]
    pub fn ahead(&self, c: &MasterFilterCoeffs, lead_q16: i32) -> MasterAhead {
        let (delta, v_q16) = self.ahead_delta(lead_q16);
        MasterAhead {
            pos: Master::from_bits(self.pos.wrapping_add(delta)),
            rate_q8: self.rate_q8(c, v_q16),
            acc_q8: self.acc_q8(c),
        }
    }

    /// [`MasterFilter::ahead`] as the distance from the filtered position (raw `I48F16`,
    /// |·| < 2^45) and the speed there in counts/tick, Q16 (|·| < 2^31): the follower's
    /// working formats.
    #[inline(always)]
    pub(crate) fn ahead_delta(&self, lead_q16: i32) -> (i64, i32) {
        let n = lead_q16.clamp(0, MAX_LEAD_Q16);
        // θ̇ in Q16 counts/tick: |θ̇| ≤ 2^46 (Q32), so θ̇ >> 16 fits 31 bits exactly.
        let v16 = (self.vel >> 16) as i32;
        // θ̈·n: Q32·Q16 >> 32 = Q16 counts/tick (|·| ≤ 2^31·2^30 >> 32 = 2^29).
        let acc_n = (i64::from(self.acc).wrapping_mul(i64::from(n)) >> 32) as i32;
        // θ̇·n + ½θ̈·n²: Q16·Q16 = Q32 (|θ̇·n| ≤ 2^60, |θ̈·n·n/2| ≤ 2^58), then Q16
        // (|·| < 2^45).
        let delta = i64::from(v16)
            .wrapping_mul(i64::from(n))
            .wrapping_add(i64::from(acc_n).wrapping_mul(i64::from(n)) >> 1)
            >> 16;
        // θ̇ + θ̈·n, Q16 counts/tick: |·| ≤ 2^30 + 2^29 < 2^31.
        (delta, v16.wrapping_add(acc_n))
    }

    /// The acceleration, counts/tick², Q32 (±0.5, the filter's own format).
    #[inline(always)]
    pub(crate) fn acc_q32(&self) -> i32 {
        self.acc
    }

    /// A speed in counts/tick (Q16) in counts/s, Q24.8 (saturated):
    /// counts/tick (Q16) · ticks/s (Q16) = Q32 → >> 24 = Q8.
    #[inline(always)]
    fn rate_q8(&self, c: &MasterFilterCoeffs, v_q16: i32) -> i32 {
        mul_shr_floor_sat(v_q16, c.tps_q16, 24)
    }

    /// The acceleration in counts/s², Q24.8 (saturated): counts/tick² (Q32) · ticks/s (Q16)
    /// >> 32 = Q16 (|·| < 2^30); · ticks/s (Q16) >> 24 = Q8.
    #[inline(always)]
    fn acc_q8(&self, c: &MasterFilterCoeffs) -> i32 {
        let a1 = ((i64::from(self.acc).wrapping_mul(i64::from(c.tps_q16))) >> 32) as i32;
        mul_shr_floor_sat(a1, c.tps_q16, 24)
    }

    /// The same estimate in the public formats (`I48F16` for all three quantities).
    pub fn estimate(&self, c: &MasterFilterCoeffs, lead_q16: i32) -> MasterEstimate {
        let a = self.ahead(c, lead_q16);
        MasterEstimate {
            pos: a.pos,
            rate_per_s: MasterRate::from_bits(i64::from(a.rate_q8) << 8),
            acc_per_s2: MasterRate::from_bits(i64::from(a.acc_q8) << 8),
        }
    }

    /// [`MasterFilter::estimate`] at a lead of 0 (the estimate now), without the
    /// extrapolation's products.
    #[inline]
    pub fn estimate_now(&self, c: &MasterFilterCoeffs) -> MasterEstimate {
        // |θ̇| ≤ 2^46: θ̇ >> 16 fits an i32 exactly.
        let rate_q8 = self.rate_q8(c, (self.vel >> 16) as i32);
        MasterEstimate {
            pos: Master::from_bits(self.pos),
            rate_per_s: MasterRate::from_bits(i64::from(rate_q8) << 8),
            acc_per_s2: MasterRate::from_bits(i64::from(self.acc_q8(c)) << 8),
        }
    }

    /// The filtered master position now.
    #[inline]
    pub fn pos(&self) -> Master {
        Master::from_bits(self.pos)
    }

    /// The sign of the filtered master speed: 1 moving up, −1 moving down, 0 at rest.
    #[inline]
    pub fn direction(&self) -> i8 {
        // From the high word (and the low word only when the high word is 0).
        let hi = (self.vel >> 32) as i32;
        if hi < 0 {
            -1
        } else if hi > 0 || self.vel as u32 != 0 {
            1
        } else {
            0
        }
    }

    /// Forgets the state (the next measurement re-initialises it at rest).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn exp_is_accurate() {
        for x in [-0.001f64, -0.5, -1.0, -3.0, -10.0] {
            let e = libm_exp(x);
            assert!((e / std::primitive::f64::exp(x) - 1.0).abs() < 1e-12, "{x}");
        }
    }

    #[test]
    fn rejects_bad_config() {
        let c = MasterFilterConfig { bandwidth_hz: 0.0 };
        assert_eq!(c.build(1000), Err(MasterFilterError::Bandwidth));
        let c = MasterFilterConfig {
            bandwidth_hz: 500.0,
        };
        assert_eq!(c.build(1000), Err(MasterFilterError::Bandwidth));
        assert_eq!(
            MasterFilterConfig::default().build(10),
            Err(MasterFilterError::Period)
        );
    }

    /// After settling on exact (unquantised) constant-acceleration motion, position,
    /// speed and acceleration match the motion closely.
    #[test]
    fn tracks_constant_acceleration_without_lag() {
        let c = MasterFilterConfig { bandwidth_hz: 10.0 }
            .build(1000)
            .unwrap();
        let mut f = MasterFilter::default();
        // θ = 100 + 3000·t + 200·t² counts (t in s)
        let th = |t: f64| 100.0 + 3000.0 * t + 200.0 * t * t;
        for k in 0..3000 {
            f.update(&c, Master::from_num(th(k as f64 * 1e-3)));
        }
        let t = 2.999;
        let e = f.estimate(&c, 0);
        assert!((e.pos.to_num::<f64>() - th(t)).abs() < 1e-3, "{}", e.pos);
        assert!((e.rate_per_s.to_num::<f64>() - (3000.0 + 400.0 * t)).abs() < 0.05);
        assert!((e.acc_per_s2.to_num::<f64>() - 400.0).abs() < 1.0);
        // 5 ticks ahead
        let e5 = f.estimate(&c, 5 << 16);
        assert!((e5.pos.to_num::<f64>() - th(t + 0.005)).abs() < 1e-3);
    }

    /// On a quantised ramp (3 counts per tick plus a third), the speed estimate is
    /// far smoother than the raw difference.
    #[test]
    fn smooths_quantisation() {
        let c = MasterFilterConfig { bandwidth_hz: 8.0 }
            .build(1000)
            .unwrap();
        let mut f = MasterFilter::default();
        let mut worst: f64 = 0.0;
        for k in 0..4000 {
            let th = (k as f64 * 3.3333).floor();
            f.update(&c, Master::from_num(th));
            if k > 2000 {
                let r = f.estimate(&c, 0).rate_per_s.to_num::<f64>();
                worst = worst.max((r - 3333.3).abs());
            }
        }
        // raw differences jump between 3000 and 4000 counts/s
        assert!(worst < 60.0, "speed ripple {worst}");
    }

    /// A master counter that wraps at the end of the `I48F16` range is followed through
    /// the wrap: no jump, the same speed, the position wrapped with it.
    #[test]
    fn follows_a_counter_through_its_wrap() {
        let c = MasterFilterConfig::default().build(1000).unwrap();
        let mut f = MasterFilter::default();
        let step = 3i64 << 16; // 3 counts/tick
        let start = i64::MAX - 1000 * step;
        let mut m = start;
        for _ in 0..2000 {
            assert!(!f.update(&c, Master::from_bits(m)));
            m = m.wrapping_add(step);
        }
        assert!(m < 0, "the counter wrapped");
        let e = f.estimate_now(&c);
        assert!(
            (e.rate_per_s.to_num::<f64>() - 3000.0).abs() < 1.0,
            "{}",
            e.rate_per_s
        );
        let last = m.wrapping_sub(step);
        assert!(
            e.pos.to_bits().wrapping_sub(last).abs() < 1 << 16,
            "{}",
            e.pos
        );
        assert_eq!(f.direction(), 1);
    }

    #[test]
    fn reports_jumps() {
        let c = MasterFilterConfig::default().build(1000).unwrap();
        let mut f = MasterFilter::default();
        assert!(!f.update(&c, Master::from_num(0)));
        assert!(!f.update(&c, Master::from_num(3)));
        assert!(f.update(&c, Master::from_num(100_000)));
    }

    proptest! {
        #[test]
        fn never_panics(xs in proptest::collection::vec(any::<i64>(), 1..50), fb in 0.1f32..100.0,
                        lead in any::<i32>()) {
            let c = MasterFilterConfig { bandwidth_hz: fb }.build(1000).unwrap();
            let mut f = MasterFilter::default();
            for x in xs {
                f.update(&c, Master::from_bits(x));
                let _ = f.estimate(&c, lead);
                prop_assert_eq!(f.estimate_now(&c), f.estimate(&c, 0));
            }
        }
    }
}
