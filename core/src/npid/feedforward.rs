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
//! `K_ext`, `K_ret` (LSB/(µm/s)) are the inverse velocity gains of the axis when
//! extending and retracting: a single-rod cylinder on a symmetric valve moves at
//! different speeds per LSB in the two directions (area ratio), so one gain cannot
//! serve both. They are commissioning figures (an open-loop velocity test per axis and
//! direction). `T_lead` covers the half period of the backward difference, the one
//! period of computation delay and the valve's lag (≈ 2ζ/ω_v).
//!
//! Formats: reference and the last reference µm Q16, velocities µm/s Q16, gains
//! LSB/(µm/s) Q32 (resolution 2.3·10⁻¹⁰, range 0 … 1), `1/h` and `T_lead/h` Q16, output
//! [`CmdLsb`].

use super::fxmath::mul_shr;
use super::{cmd_from_q16, q16_from_pos};
use crate::units::{CmdLsb, PosUm};

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
}

#[cfg(feature = "std")]
impl std::error::Error for FfError {}

impl core::fmt::Display for FfError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "invalid feed-forward parameter: {self:?}")
    }
}

/// Validated feed-forward coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityFfCoeffs {
    /// K_ext, LSB/(µm/s) Q32.
    k_ext_q32: i64,
    /// K_ret, LSB/(µm/s) Q32.
    k_ret_q32: i64,
    /// 1/h, 1/s Q16.
    inv_h_q16: i64,
    /// T_lead/h, Q16.
    lead_over_h_q16: i64,
}

impl VelocityFfCoeffs {
    /// No feed-forward (both gains zero): `u_ff = 0`.
    pub const NONE: Self = Self {
        k_ext_q32: 0,
        k_ret_q32: 0,
        inv_h_q16: 0,
        lead_over_h_q16: 0,
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
        // LSB/(mm/s) → LSB/(µm/s): /1000.
        let q32 = |v: f64| (v * 1e-3 * 4_294_967_296.0 + 0.5) as i64;
        Ok(VelocityFfCoeffs {
            k_ext_q32: q32(self.extend_lsb_per_mm_s),
            k_ret_q32: q32(self.retract_lsb_per_mm_s),
            inv_h_q16: (65536.0 / h + 0.5) as i64,
            lead_over_h_q16: (self.lead_s / h * 65536.0 + 0.5) as i64,
        })
    }
}

/// Feed-forward state: the last reference and the last speed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityFf {
    /// r(k−1), µm Q16.
    last_ref_q16: i64,
    /// v(k−1), µm/s Q16.
    last_v_q16: i64,
}

/// |command| limit, LSB Q16.
const U_MAX_Q16: i64 = 2047 << 16;

impl VelocityFf {
    /// At rest at `position_um` (zero speed).
    pub fn at_rest(position_um: PosUm) -> Self {
        Self {
            last_ref_q16: q16_from_pos(position_um),
            last_v_q16: 0,
        }
    }

    /// One period: `u_ff` for the reference `reference_um` of this period.
    #[inline]
    pub fn step(&mut self, c: &VelocityFfCoeffs, reference_um: PosUm) -> CmdLsb {
        let r = q16_from_pos(reference_um);
        let v = mul_shr(r.saturating_sub(self.last_ref_q16), c.inv_h_q16, 16);
        let dv = v.saturating_sub(self.last_v_q16);
        let vff = v.saturating_add(mul_shr(dv, c.lead_over_h_q16, 16));
        self.last_ref_q16 = r;
        self.last_v_q16 = v;
        let k = if vff >= 0 { c.k_ext_q32 } else { c.k_ret_q32 };
        cmd_from_q16(mul_shr(vff, k, 32).clamp(-U_MAX_Q16, U_MAX_Q16))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> VelocityFfConfig {
        VelocityFfConfig {
            period_s: 1e-3,
            extend_lsb_per_mm_s: 20.0,
            retract_lsb_per_mm_s: 30.0,
            lead_s: 0.005,
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
    }
}
