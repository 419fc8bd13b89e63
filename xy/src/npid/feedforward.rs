//! Velocity feed-forward of one hydraulic axis from the interpolated reference.
//!
//! ```text
//! v(k)   = (r(k) − r(k−1)) / h                        [µm/s]  (the interpolator's speed)
//! a(k)   = (v(k) − v(k−1)) / h                        [µm/s²]
//! v_ff   = v(k) + T_lead·a(k)                         [µm/s]  (aims at the interval in
//!                                                             which the command acts)
//! u_ff   = K_ext·v_ff  if v_ff ≥ 0,   K_ret·v_ff  if v_ff < 0      [DAC LSB, ±2047]
//! ```
//!
//! **Friction (quadrant) compensation.** A valve-controlled cylinder is a flow source
//! behind an oil spring of stiffness `k_h = E·(A_A²/V_A + A_B²/V_B)` (PLANT.md: 3.7·10⁷
//! N/m at mid-stroke). Coulomb friction `F_c·sgn(v)` compresses that spring by
//! `D_c = F_c/k_h` (400 N ⇒ 10.8 µm): moving, the oil column "leads" the piston by
//! `D_c`; at a velocity reversal the deflection swings by `2·D_c` and the piston
//! overshoots, then lags (the quadrant glitch of a circle). The compensation adds the
//! flow that re-deflects the spring as the reference reverses:
//!
//! ```text
//! d(k)   = D_c · sat(v_ff(k) / v_s)                   [µm]    (sat: clamp to ±1)
//! u_fc   = K_ext|K_ret · (d(k) − d(k−1)) / h          [LSB]   (gain by the sign of Δd)
//! ```
//!
//! `D_c` (µm) and the reversal speed band `v_s` (mm/s) are commissioning figures
//! (friction force from the pressure transducers at constant speed in both directions,
//! `k_h` from the cylinder data; or tuned, see `host-sim xy --tune`). `D_c = 0` switches
//! it off.
//!
//! `K_ext`, `K_ret` (LSB/(µm/s)) are the inverse velocity gains of the axis when
//! extending and retracting: a single-rod cylinder on a symmetric valve moves at
//! different speeds per LSB in the two directions (area ratio), so one gain cannot
//! serve both. They are commissioning figures (an open-loop velocity test per axis and
//! direction). `T_lead` covers the half period of the backward difference, the one
//! period of computation delay and the valve's lag (≈ 2ζ/ω_v).
//!
//! Formats (every product 32 × 32 → 64 bits, one `smull`; ranges from the validated
//! parameters): reference and the last reference µm Q8 (the [`PosUm`] bits); velocities
//! µm/s Q8 in an `i32` (±8.4 m/s, saturated; resolution 0.004 µm/s); gains LSB/(µm/s) Q24
//! (0 … 1, resolution 6·10⁻⁸); `1/h` 1/s Q8 (100 … 10⁵; rounding ≤ 2·10⁻⁵ relative, exact
//! for 1 ms, 500 µs, 250 µs, 100 µs); `T_lead/h` Q18 (0 … 5000); `D_c` and `d` µm Q16 (0 … 1000 µm);
//! `D_c/v_s` µm/(µm/s) Q24 (0 … 100: D_c ≤ 1000 µm, v_s ≥ 0.01 mm/s); output [`CmdLsb`].
//! Against the f64 equations: within 0.2 LSB (proptest; worst seen 0.106 LSB with D_c
//! 48 µm over a 0.6 mm/s band, ≈ 0.05 otherwise: the friction term differentiates d and
//! so amplifies v_ff's resolution by D_c/(v_s·h)).

use hydra_core::fixed_point::mul_shr_floor_sat;
use hydra_core::units::{CmdLsb, PosUm};

/// Feed-forward parameters in engineering units (validated by [`VelocityFfConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityFfConfig {
    /// Control period h, s (10 µs … 10 ms).
    pub period_s: f64,
    /// Command per speed when extending, LSB/(mm/s) (0 … 1000).
    pub extend_lsb_per_mm_s: f64,
    /// Command per speed when retracting, LSB/(mm/s) (0 … 1000).
    pub retract_lsb_per_mm_s: f64,
    /// Lead time T_lead, s (0 … 0.05).
    pub lead_s: f64,
    /// Friction deflection D_c = F_c/k_h, µm (0 … 1000; 0 = no friction compensation).
    pub friction_deflection_um: f64,
    /// Reversal speed band v_s of the friction compensation, mm/s (0.01 … 100).
    pub friction_speed_mm_s: f64,
}

/// Why a feed-forward configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FfError {
    /// Period outside 10 µs … 10 ms or not finite.
    Period,
    /// Extension gain outside 0 … 1000 LSB/(mm/s) or not finite.
    ExtendGain,
    /// Retraction gain outside 0 … 1000 LSB/(mm/s) or not finite.
    RetractGain,
    /// Lead outside 0 … 50 ms or not finite.
    Lead,
    /// Friction deflection outside 0 … 1000 µm or not finite.
    FrictionDeflection,
    /// Friction reversal speed outside 0.01 … 100 mm/s or not finite.
    FrictionSpeed,
}

impl core::error::Error for FfError {}

impl core::fmt::Display for FfError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "invalid feed-forward parameter: {self:?}")
    }
}

/// Validated feed-forward coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityFfCoeffs {
    /// K_ext, LSB/(µm/s) Q24 (0 … 2²⁴).
    k_ext_q24: i32,
    /// K_ret, LSB/(µm/s) Q24 (0 … 2²⁴).
    k_ret_q24: i32,
    /// 1/h, 1/s Q8 (100·2⁸ … 10⁵·2⁸).
    inv_h_q8: i32,
    /// T_lead/h, Q18 (0 … 5000·2¹⁸ < 2³¹; resolution 3.8·10⁻⁶ periods).
    lead_over_h_q18: i32,
    /// D_c, µm Q16 (0 … 1000·2¹⁶).
    friction_um_q16: i32,
    /// D_c/v_s, µm/(µm/s) Q24 (0 … 100 · 2²⁴ < 2³¹).
    friction_gain_q24: i32,
}

impl VelocityFfCoeffs {
    /// No feed-forward (both gains zero): `u_ff = 0`.
    pub const NONE: Self = Self {
        k_ext_q24: 0,
        k_ret_q24: 0,
        inv_h_q8: 0,
        lead_over_h_q18: 0,
        friction_um_q16: 0,
        friction_gain_q24: 0,
    };
}

impl VelocityFfConfig {
    /// Validates every parameter; the error names the first bad one.
    pub fn build(&self) -> Result<VelocityFfCoeffs, FfError> {
        let h = self.period_s;
        if !(h.is_finite() && (1e-5..=0.01).contains(&h)) {
            return Err(FfError::Period);
        }
        let ok = |v: f64, hi: f64| v.is_finite() && (0.0..=hi).contains(&v);
        if !ok(self.extend_lsb_per_mm_s, 1000.0) {
            return Err(FfError::ExtendGain);
        }
        if !ok(self.retract_lsb_per_mm_s, 1000.0) {
            return Err(FfError::RetractGain);
        }
        if !ok(self.lead_s, 0.05) {
            return Err(FfError::Lead);
        }
        if !ok(self.friction_deflection_um, 1000.0) {
            return Err(FfError::FrictionDeflection);
        }
        let vs = self.friction_speed_mm_s;
        if !(vs.is_finite() && (0.01..=100.0).contains(&vs)) {
            return Err(FfError::FrictionSpeed);
        }
        // LSB/(mm/s) → LSB/(µm/s): /1000. Every value below is within its i32 range
        // (see the field docs) for the validated parameters.
        let q24 = |v: f64| (v * 1e-3 * 16_777_216.0 + 0.5) as i32;
        Ok(VelocityFfCoeffs {
            k_ext_q24: q24(self.extend_lsb_per_mm_s),
            k_ret_q24: q24(self.retract_lsb_per_mm_s),
            inv_h_q8: (256.0 / h + 0.5) as i32,
            lead_over_h_q18: (self.lead_s / h * 262_144.0 + 0.5) as i32,
            friction_um_q16: (self.friction_deflection_um * 65536.0 + 0.5) as i32,
            // mm/s → µm/s: ×1000.
            friction_gain_q24: (self.friction_deflection_um / (vs * 1e3) * 16_777_216.0 + 0.5)
                as i32,
        })
    }
}

/// Feed-forward state: the last reference, the last speed and the last friction
/// deflection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityFf {
    /// r(k−1), µm Q8 (raw [`PosUm`]).
    last_ref_q8: i32,
    /// v(k−1), µm/s Q8.
    last_v_q8: i32,
    /// d(k−1), µm Q16.
    last_d_q16: i32,
}

/// |command| limit, LSB Q16.
const U_MAX_Q16: i32 = 2047 << 16;

impl VelocityFf {
    /// At rest at `position_um` (zero speed).
    pub fn at_rest(position_um: PosUm) -> Self {
        Self {
            last_ref_q8: position_um.to_bits(),
            last_v_q8: 0,
            last_d_q16: 0,
        }
    }

    /// One period: `u_ff` for the reference `reference_um` of this period.
    #[inline]
    pub fn step(&mut self, c: &VelocityFfCoeffs, reference_um: PosUm) -> CmdLsb {
        let r = reference_um.to_bits();
        // µm Q8 · 1/s Q8 >> 8 = µm/s Q8.
        let v = mul_shr_floor_sat(r.saturating_sub(self.last_ref_q8), c.inv_h_q8, 8);
        let dv = v.saturating_sub(self.last_v_q8);
        // µm/s Q8 · Q18 >> 18 = µm/s Q8.
        let vff = v.saturating_add(mul_shr_floor_sat(dv, c.lead_over_h_q18, 18));
        self.last_ref_q8 = r;
        self.last_v_q8 = v;
        let k = if vff >= 0 { c.k_ext_q24 } else { c.k_ret_q24 };
        // µm/s Q8 · LSB/(µm/s) Q24 >> 16 = LSB Q16.
        let u_v = mul_shr_floor_sat(vff, k, 16);
        // Friction: d = D_c·sat(v_ff/v_s) = clamp(v_ff·D_c/v_s, ±D_c), u_fc = K·Δd/h.
        // µm/s Q8 · µm/(µm/s) Q24 >> 16 = µm Q16 (one rounding: d is differentiated).
        let d = mul_shr_floor_sat(vff, c.friction_gain_q24, 16)
            .clamp(c.friction_um_q16.wrapping_neg(), c.friction_um_q16);
        let dd = d.saturating_sub(self.last_d_q16);
        self.last_d_q16 = d;
        let kd = if dd >= 0 { c.k_ext_q24 } else { c.k_ret_q24 };
        // µm Q16 · 1/s Q8 >> 16 = µm/s Q8 (|Δd|/h ≤ 2000 µm · 10⁵/s: fits); · Q24 >> 16.
        let u_fc = mul_shr_floor_sat(mul_shr_floor_sat(dd, c.inv_h_q8, 16), kd, 16);
        CmdLsb::from_bits(u_v.saturating_add(u_fc).clamp(-U_MAX_Q16, U_MAX_Q16))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cfg() -> VelocityFfConfig {
        VelocityFfConfig {
            period_s: 1e-3,
            extend_lsb_per_mm_s: 20.0,
            retract_lsb_per_mm_s: 30.0,
            lead_s: 0.005,
            friction_deflection_um: 0.0,
            friction_speed_mm_s: 1.0,
        }
    }

    #[test]
    fn constant_speed_gives_gain_times_speed_per_direction() {
        let c = cfg().build().unwrap();
        let mut f = VelocityFf::at_rest(PosUm::ZERO);
        let mut u = CmdLsb::ZERO;
        // 50 mm/s = 50 µm per period.
        for k in 1..=20 {
            u = f.step(&c, PosUm::from_num(50 * k));
        }
        assert!((u.to_num::<f64>() - 1000.0).abs() < 0.01, "{u}");
        let mut f = VelocityFf::at_rest(PosUm::ZERO);
        for k in 1..=20 {
            u = f.step(&c, PosUm::from_num(-10 * k));
        }
        assert!((u.to_num::<f64>() + 300.0).abs() < 0.01, "{u}");
    }

    #[test]
    fn lead_adds_acceleration_times_lead() {
        let c = cfg().build().unwrap();
        let mut f = VelocityFf::at_rest(PosUm::ZERO);
        // v steps 0 → 10 mm/s: a = 10⁷ µm/s², T_lead·a = 50 mm/s → 60 mm/s · 20.
        let u = f.step(&c, PosUm::from_num(10));
        assert!((u.to_num::<f64>() - 1200.0).abs() < 0.01, "{u}");
        let u = f.step(&c, PosUm::from_num(20));
        assert!((u.to_num::<f64>() - 200.0).abs() < 0.01, "{u}");
    }

    #[test]
    fn output_clamped_and_none_is_zero() {
        let c = cfg().build().unwrap();
        let mut f = VelocityFf::at_rest(PosUm::ZERO);
        assert_eq!(f.step(&c, PosUm::from_num(1e6)), CmdLsb::from_num(2047));
        let mut f = VelocityFf::at_rest(PosUm::ZERO);
        assert_eq!(
            f.step(&VelocityFfCoeffs::NONE, PosUm::from_num(1000)),
            CmdLsb::ZERO
        );
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut c = cfg();
        c.period_s = 0.0;
        assert_eq!(c.build(), Err(FfError::Period));
        let mut c = cfg();
        c.extend_lsb_per_mm_s = -1.0;
        assert_eq!(c.build(), Err(FfError::ExtendGain));
        let mut c = cfg();
        c.retract_lsb_per_mm_s = f64::NAN;
        assert_eq!(c.build(), Err(FfError::RetractGain));
        let mut c = cfg();
        c.lead_s = 1.0;
        assert_eq!(c.build(), Err(FfError::Lead));
        let mut c = cfg();
        c.friction_deflection_um = -0.1;
        assert_eq!(c.build(), Err(FfError::FrictionDeflection));
        let mut c = cfg();
        c.friction_speed_mm_s = 0.0;
        assert_eq!(c.build(), Err(FfError::FrictionSpeed));
    }

    /// A reference that reverses at constant deceleration: the friction term is a
    /// pulse whose integral is 2·D_c of equivalent position (K·2·D_c LSB·s), signed
    /// like the new direction, and zero at constant speed.
    #[test]
    fn friction_term_redeflects_the_oil_column_at_a_reversal() {
        let mut with = cfg();
        with.lead_s = 0.0;
        with.friction_deflection_um = 10.0;
        with.friction_speed_mm_s = 1.0;
        let cw = with.build().unwrap();
        let mut without = with;
        without.friction_deflection_um = 0.0;
        let c0 = without.build().unwrap();
        // 5 mm/s for t < 0, then v(t) = 5 mm/s − 50 mm/s²·t over 0.2 s: +5 → −5 mm/s,
        // reversal at 0.1 s. The filters start moving 20 ms before t = 0.
        let h = 1e-3;
        let x_um = |t: f64| {
            if t < 0.0 {
                5000.0 * t
            } else {
                5000.0 * t - 25_000.0 * t * t
            }
        };
        let start = PosUm::from_num(x_um(-0.021));
        let (mut fw, mut f0) = (VelocityFf::at_rest(start), VelocityFf::at_rest(start));
        let mut sum_lsb_s = 0.0;
        let mut last = 0.0;
        for k in -20..=200 {
            let t = k as f64 * h;
            let r = PosUm::from_num(x_um(t));
            let du = fw.step(&cw, r).to_num::<f64>() - f0.step(&c0, r).to_num::<f64>();
            if k < 1 {
                continue;
            }
            sum_lsb_s += du * h;
            last = du;
            // Outside the band (|v| > 1 mm/s + one step) the term is zero.
            let v = 5.0 - 50.0 * t;
            if v.abs() > 1.2 {
                assert!(du.abs() < 0.01, "t {t}: {du}");
            } else {
                // Reversing from + to −: retracting flow, K_ret = 30 LSB/(mm/s).
                assert!(du <= 0.01, "t {t}: {du}");
            }
        }
        // ∫u dt = K_ret · (−2·D_c) = 30e-3 LSB/(µm/s) · −20 µm = −0.6 LSB·s.
        assert!((sum_lsb_s + 0.6).abs() < 0.02, "{sum_lsb_s}");
        assert!(last.abs() < 0.01);
    }

    /// The f64 form of [`VelocityFf::step`] (the equations of the module doc).
    struct RefFf {
        r: f64,
        v: f64,
        d: f64,
    }

    impl RefFf {
        fn step(&mut self, c: &VelocityFfConfig, r: f64) -> f64 {
            let h = c.period_s;
            let k = |x: f64| {
                1e-3 * if x >= 0.0 {
                    c.extend_lsb_per_mm_s
                } else {
                    c.retract_lsb_per_mm_s
                }
            };
            let v = (r - self.r) / h;
            let vff = v + c.lead_s * (v - self.v) / h;
            let s = (vff / (c.friction_speed_mm_s * 1e3)).clamp(-1.0, 1.0);
            let d = c.friction_deflection_um * s;
            let dd = d - self.d;
            (self.r, self.v, self.d) = (r, v, d);
            (k(vff) * vff + k(dd) * dd / h).clamp(-2047.0, 2047.0)
        }
    }

    proptest! {
        /// Random commissioning figures and references (speeds up to ±500 mm/s with
        /// reversals): the fixed-point step stays within 0.2 LSB (a fifth of the DAC's
        /// step) of the f64 equations. The largest part is the friction term at a narrow
        /// band: it differentiates D_c·v_ff/v_s, so the 0.004 µm/s resolution of v_ff is
        /// amplified by D_c/(v_s·h) (≤ 100 here); worst seen 0.106 LSB (D_c 48 µm over a
        /// 0.6 mm/s band), ≈ 0.05 for ordinary settings.
        #[test]
        fn matches_the_f64_equations(
            ext in 0.0f64..100.0,
            ret in 0.0f64..100.0,
            lead_ms in 0.0f64..10.0,
            dc in 0.0f64..50.0,
            vs in 0.5f64..10.0,
            speeds in proptest::collection::vec(-500.0f64..500.0, 1..8),
        ) {
            let c = VelocityFfConfig {
                period_s: 1e-3,
                extend_lsb_per_mm_s: ext,
                retract_lsb_per_mm_s: ret,
                lead_s: lead_ms * 1e-3,
                friction_deflection_um: dc,
                friction_speed_mm_s: vs,
            };
            let q = c.build().unwrap();
            let mut f = VelocityFf::at_rest(PosUm::ZERO);
            let mut rf = RefFf { r: 0.0, v: 0.0, d: 0.0 };
            let mut x = 0.0f64;
            let mut worst = 0.0f64;
            for (i, mm_s) in speeds.iter().enumerate() {
                // 40 periods per speed segment, the speed ramping from the last one.
                let v0 = if i == 0 { 0.0 } else { speeds[i - 1] };
                for k in 0..40 {
                    let v = v0 + (mm_s - v0) * f64::from(k) / 40.0;
                    // Positions on the PosUm grid (1/256 µm), as the interpolator gives.
                    x = ((x + v) * 256.0).round() / 256.0;
                    let u = f.step(&q, PosUm::from_num(x)).to_num::<f64>();
                    worst = worst.max((u - rf.step(&c, x)).abs());
                }
            }
            prop_assert!(worst < 0.2, "worst |Δu| {} LSB", worst);
        }
    }
}
