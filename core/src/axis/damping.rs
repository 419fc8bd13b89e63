//! Active damping of a position axis: feedback of the high-passed hydraulic force
//! (ΔP feedback).
//!
//! The oil column of a valve-controlled cylinder is a spring: with the moving mass it
//! makes the hydraulic mode (≈ 40–70 Hz on the reference machine) whose light damping
//! limits the position gain. The chamber pressures measure that spring's force directly;
//! subtracting its *changes* from the command damps the mode without a static effect (a
//! held load keeps its pressures and the term decays to zero):
//!
//! ```text
//! F(k)  = A_A·p_A(k) − A_B·p_B(k)                         hydraulic force, kN
//! y(k)  = α·(y(k−1) + F(k) − F(k−1)),  α = 1 / (1 + 2π·f_c·T)   first-order high-pass
//! u(k) −= k_dp · y(k)                                     LSB (then the valve clamp)
//! ```
//!
//! In fixed point the gain is folded into the areas once ([`DampingCoeffs`]): per chamber
//! g = k_dp·A, LSB per bar (`I16F16`, resolution 1.5e-5 LSB/bar, ≤ 32 767), so the
//! filter runs on the change k_dp·(F(k) − F(k−1)) = g_A·Δp_A − g_B·Δp_B in LSB
//! (`I16F16`; a large steady load cannot saturate it) and its output is the command
//! correction.
//! Pressures are [`PressureBar`] (`I16F16` bar). Two 32 × 32 → 64-bit products for the
//! force, one for the filter; every sum saturates.
//!
//! The sign convention is the position law's: a positive command extends the axis, which
//! raises p_A; chamber A is the board's pressure input 2n, B is 2n + 1 (slave n).

use crate::fixed_point::sat_i32;
use crate::units::{CmdLsb, PressureBar};

/// The cylinder's piston areas: what turns the two chamber pressures into a force.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PistonAreas {
    /// Area on the side of chamber A (pressure input 2n), mm² (0 … 1 000 000).
    pub area_a_mm2: f32,
    /// Area on the side of chamber B (pressure input 2n + 1), mm² (0 … 1 000 000).
    pub area_b_mm2: f32,
}

/// Why the damping cannot be built (reported as the axis' `AxisConfigError::Damping`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DampingError {
    /// The gain is not finite or outside 0 … 1000 LSB/kN.
    Gain,
    /// The high-pass corner is not finite or outside 0.1 … 1000 Hz.
    Corner,
    /// An area is not finite, negative or above 1 m², or both are zero with a gain set,
    /// or k_dp·A exceeds 32 767 LSB per bar.
    Area,
    /// A gain on an axis whose law is not `Feedforward`: the paper's law and the
    /// traditional one are the baselines and run as published.
    Law,
}

/// Validated coefficients. All zero (`OFF`): no damping, the law skips it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DampingCoeffs {
    /// k_dp·A_A, LSB per bar, `I16F16` raw.
    g_a: i32,
    /// k_dp·A_B, LSB per bar, `I16F16` raw.
    g_b: i32,
    /// α of the high-pass, Q31 (0 < α < 1).
    alpha_q31: i32,
    /// Whether the term runs (gain above zero).
    on: bool,
}

impl DampingCoeffs {
    /// No damping.
    pub const OFF: Self = Self {
        g_a: 0,
        g_b: 0,
        alpha_q31: 0,
        on: false,
    };

    /// Builds the coefficients for gain `gain_lsb_per_kn` (0 = off), the high-pass corner
    /// `corner_hz` and the piston areas at the control period `period_us` (checked by the
    /// caller to be 50 µs … 1 s).
    pub fn build(
        gain_lsb_per_kn: f32,
        corner_hz: f32,
        areas: &PistonAreas,
        period_us: u32,
    ) -> Result<Self, DampingError> {
        let ok = |x: f32, lo: f32, hi: f32| x.is_finite() && x >= lo && x <= hi;
        if !ok(gain_lsb_per_kn, 0.0, 1000.0) {
            return Err(DampingError::Gain);
        }
        if !ok(corner_hz, 0.1, 1000.0) {
            return Err(DampingError::Corner);
        }
        if !ok(areas.area_a_mm2, 0.0, 1e6) || !ok(areas.area_b_mm2, 0.0, 1e6) {
            return Err(DampingError::Area);
        }
        if gain_lsb_per_kn == 0.0 {
            return Ok(Self::OFF);
        }
        if areas.area_a_mm2 == 0.0 && areas.area_b_mm2 == 0.0 {
            return Err(DampingError::Area);
        }
        // 1 bar on 1 mm² is 0.1 N = 1e-4 kN.
        let g = |a: f32| {
            let lsb_per_bar = f64::from(gain_lsb_per_kn) * f64::from(a) * 1e-4;
            fixed::types::I16F16::checked_from_num(lsb_per_bar)
                .map(|v| v.to_bits())
                .ok_or(DampingError::Area)
        };
        let t = f64::from(period_us) * 1e-6;
        let alpha = 1.0 / (1.0 + 2.0 * core::f64::consts::PI * f64::from(corner_hz) * t);
        Ok(Self {
            g_a: g(areas.area_a_mm2)?,
            g_b: g(areas.area_b_mm2)?,
            // 0 < α < 1: in Q31 below 2^31.
            alpha_q31: (alpha * 2_147_483_648.0).min(2_147_483_647.0) as i32,
            on: true,
        })
    }

    /// Whether the term runs.
    #[inline(always)]
    pub fn is_on(&self) -> bool {
        self.on
    }
}

/// The high-pass filter's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DampingState {
    /// p_A(k−1), p_B(k−1), bar, `I16F16` raw, each stored XOR `i32::MIN` (the filter works
    /// on the force's change, so a large steady load cannot saturate it). A stored 0 —
    /// a reading of −32 768 bar, which no transducer gives — means no sample yet: the
    /// first tick after a reset outputs 0. (So the reset state is all-zero bytes and a
    /// static law buffer stays in `.bss`: a non-zero reset put 25 KiB of law buffers'
    /// initial image into flash.)
    p1: [i32; 2],
    /// y(k−1), LSB, `I16F16` raw.
    y: i32,
}

impl Default for DampingState {
    fn default() -> Self {
        Self::RESET
    }
}

impl DampingState {
    /// The reset state (`Default` as a `const`).
    pub const RESET: Self = Self { p1: [0; 2], y: 0 };
}

/// One tick: the command correction k_dp·y(k) in LSB (`I16F16` raw) to subtract from
/// the law's command, from chamber pressures `p` = [p_A, p_B] (bar). 0 when off.
#[inline(always)]
pub fn damping_bits(c: &DampingCoeffs, st: &mut DampingState, p: &[PressureBar; 2]) -> i32 {
    let p = [p[0].to_bits(), p[1].to_bits()];
    let p1 = if st.p1[0] == 0 {
        p
    } else {
        [st.p1[0] ^ i32::MIN, st.p1[1] ^ i32::MIN]
    };
    // k_dp·(F(k) − F(k−1)) = g_A·Δp_A − g_B·Δp_B: Q16 bar · Q16 LSB/bar = Q32 → Q16 LSB.
    // Δp saturated to i32 (±32 768 bar), |g| < 2^31: each product below 2^62, their
    // difference below 2^63 (32 × 32 → 64-bit multiplies, no overflow).
    let dp_a = i64::from(p[0].saturating_sub(p1[0]));
    let dp_b = i64::from(p[1].saturating_sub(p1[1]));
    let df = dp_a
        .wrapping_mul(i64::from(c.g_a))
        .wrapping_sub(dp_b.wrapping_mul(i64::from(c.g_b)))
        >> 16;
    let x = st.y.saturating_add(sat_i32(df));
    // Q16 · Q31 → Q47 >> 31: |α| < 1, so |y| ≤ |x| fits an i32.
    st.y = (i64::from(x).wrapping_mul(i64::from(c.alpha_q31)) >> 31) as i32;
    // A reading of exactly −32 768 bar stays "no sample" (never a real one).
    st.p1 = [p[0] ^ i32::MIN, p[1] ^ i32::MIN];
    st.y
}

/// `u` (the law's command, `I16F16` LSB) less the damping term, within ±`clamp`
/// (`I16F16` LSB). `u` unchanged when the damping is off (the state is not touched).
#[inline(always)]
pub fn damped(
    c: &DampingCoeffs,
    st: &mut DampingState,
    p: &[PressureBar; 2],
    u: i32,
    clamp: i32,
) -> i32 {
    if !c.on {
        return u;
    }
    let d = damping_bits(c, st, p);
    crate::fixed_point::clamp_sym(u.saturating_sub(d), clamp)
}

/// [`damped`] on [`CmdLsb`] values.
pub fn damped_cmd(
    c: &DampingCoeffs,
    st: &mut DampingState,
    p: &[PressureBar; 2],
    u: CmdLsb,
    clamp: CmdLsb,
) -> CmdLsb {
    CmdLsb::from_bits(damped(c, st, p, u.to_bits(), clamp.to_bits()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const AREAS: PistonAreas = PistonAreas {
        area_a_mm2: 5000.0,
        area_b_mm2: 2500.0,
    };

    fn bar(x: f64) -> PressureBar {
        PressureBar::from_num(x)
    }

    #[test]
    fn off_at_zero_gain_and_names_bad_values() {
        assert_eq!(
            DampingCoeffs::build(0.0, 5.0, &PistonAreas::default(), 1000),
            Ok(DampingCoeffs::OFF)
        );
        assert_eq!(
            DampingCoeffs::build(-1.0, 5.0, &AREAS, 1000),
            Err(DampingError::Gain)
        );
        assert_eq!(
            DampingCoeffs::build(f32::NAN, 5.0, &AREAS, 1000),
            Err(DampingError::Gain)
        );
        assert_eq!(
            DampingCoeffs::build(16.0, 0.0, &AREAS, 1000),
            Err(DampingError::Corner)
        );
        assert_eq!(
            DampingCoeffs::build(16.0, 5.0, &PistonAreas::default(), 1000),
            Err(DampingError::Area),
            "a gain with no area"
        );
        // 1000 LSB/kN · 1 m² = 1e5 LSB/bar: beyond I16F16.
        let huge = PistonAreas {
            area_a_mm2: 1e6,
            area_b_mm2: 0.0,
        };
        assert_eq!(
            DampingCoeffs::build(1000.0, 5.0, &huge, 1000),
            Err(DampingError::Area)
        );
        let mut st = DampingState::RESET;
        let u = damped(
            &DampingCoeffs::OFF,
            &mut st,
            &[bar(100.0), bar(0.0)],
            77,
            1000,
        );
        assert_eq!((u, st), (77, DampingState::RESET));
    }

    #[test]
    fn a_force_step_decays_with_the_corner_and_a_static_load_gives_nothing() {
        // 16 LSB/kN, A_A 5000 mm²: 8 LSB per bar on A; 5 Hz at 1 ms: α = 0.96954.
        let c = DampingCoeffs::build(16.0, 5.0, &AREAS, 1000).unwrap();
        let mut st = DampingState::RESET;
        // A held load: 80 bar on A, 40 on B (F = 30 kN) — the first tick outputs 0.
        let p0 = [bar(80.0), bar(40.0)];
        assert_eq!(damping_bits(&c, &mut st, &p0), 0);
        assert_eq!(damping_bits(&c, &mut st, &p0), 0);
        // +10 bar on A: ΔF = 5 kN → 80 LSB, then α^k decay.
        let p1 = [bar(90.0), bar(40.0)];
        let alpha = 1.0 / (1.0 + 2.0 * core::f64::consts::PI * 5.0 * 1e-3);
        for k in 1..=200 {
            let y = f64::from(damping_bits(&c, &mut st, &p1)) / 65536.0;
            let want = 80.0 * alpha.powi(k);
            assert!((y - want).abs() < 1e-3, "tick {k}: {y} vs {want}");
        }
        // The correction is subtracted and clamped.
        let mut st = DampingState::RESET;
        damped(&c, &mut st, &p0, 0, 100 << 16);
        let u = damped(&c, &mut st, &[bar(200.0), bar(40.0)], 50 << 16, 100 << 16);
        assert_eq!(u, -(100 << 16), "50 − 0.97·960 LSB clamps at −100");
        // B rising pushes the other way: the correction's sign flips.
        let mut st = DampingState::RESET;
        damping_bits(&c, &mut st, &p0);
        assert!(damping_bits(&c, &mut st, &[bar(80.0), bar(60.0)]) < 0);
    }

    /// The filter works on the force's change: at the largest gain on a large piston a
    /// steady 200 bar (k·F ≈ 100 000 LSB, beyond `I16F16`) still lets a 1 bar change
    /// through (an absolute-force input saturated there and lost the damping).
    #[test]
    fn a_large_steady_load_does_not_saturate_the_damping() {
        let big = PistonAreas {
            area_a_mm2: 5026.5,
            area_b_mm2: 0.0,
        };
        let c = DampingCoeffs::build(1000.0, 5.0, &big, 1000).unwrap();
        let mut st = DampingState::default();
        let p0 = [bar(200.0), bar(0.0)];
        for _ in 0..100 {
            assert_eq!(damping_bits(&c, &mut st, &p0), 0);
        }
        let y = f64::from(damping_bits(&c, &mut st, &[bar(201.0), bar(0.0)])) / 65536.0;
        // 1 bar · 1000 LSB/kN · 5026.5 mm² · 1e-4 = 502.65 LSB, times α on its first tick.
        let alpha = 1.0 / (1.0 + 2.0 * core::f64::consts::PI * 5.0 * 1e-3);
        assert!((y - 502.65 * alpha).abs() < 0.5, "{y}");
    }

    proptest! {
        #[test]
        fn never_panics_and_stays_within_the_clamp(
            seq in proptest::collection::vec((any::<i32>(), any::<i32>(), any::<i32>()), 1..100),
            gain in 0.0f32..1000.0, corner in 0.1f32..1000.0, period in 50u32..1_000_000,
            aa in 0.0f32..30_000.0, ab in 0.0f32..30_000.0, clamp in 0i32..(2047 << 16))
        {
            let areas = PistonAreas { area_a_mm2: aa, area_b_mm2: ab };
            let Ok(c) = DampingCoeffs::build(gain, corner, &areas, period) else {
                return Ok(());
            };
            let mut st = DampingState::RESET;
            for (pa, pb, u) in seq {
                let p = [PressureBar::from_bits(pa), PressureBar::from_bits(pb)];
                let out = damped(&c, &mut st, &p, u, clamp);
                if c.is_on() {
                    prop_assert!(out.abs() <= clamp);
                } else {
                    prop_assert_eq!(out, u);
                }
            }
        }
    }
}
