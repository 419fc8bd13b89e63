//! Configuration of one position-controlled slave axis, and its validated coefficients.
//!
//! The user gives gains in engineering units ([`AxisConfig`], `f32`); [`AxisConfig::build`]
//! checks every value and converts it once to the fixed-point formats of
//! [`crate::units`] for a given control period T. The per-tick law
//! ([`super::position`]) then never fails.

use super::backoff::{BackoffCoeffs, BackoffSettings, BandError};
use super::damping::{DampingCoeffs, DampingError, PistonAreas};
use super::ff_trim::{FfTrimCoeffs, FfTrimError};
use crate::valve::{ValveCal, ValveCalError, ValveCoeffs};
use fixed::types::{I0F32, I16F16, I24F8, I8F24};

/// Which control law drives the axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControlMode {
    /// Feedback on the error at the sampling instant, P + separated I (+ D), velocity and
    /// acceleration feed-forward aimed at the interval in which the command acts.
    #[default]
    Feedforward,
    /// SPEC §A eq. 6–9 exactly: incremental integral-separation PID on
    /// e(k) = x*(k+1) − x(k), x* at the eq. 4 prediction of the master.
    Paper,
    /// The traditional law: positional PID toward the table node at the far end of the
    /// current segment (in the direction of master motion); no prediction, no
    /// feed-forward.
    NextNode,
}

/// The position loop's gains and its following-error limit, in engineering units: what a
/// tuning produces for one axis at one control period. With the `serde` feature it is
/// what a scenario's `[tuning.axes.<name>]` table holds (every field optional, defaults
/// as below; unknown keys refused).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields, default)
)]
pub struct PositionGains {
    /// Proportional gain Kp, DAC LSB per µm (0 … 1000).
    pub kp_lsb_per_um: f32,
    /// Integral gain Ki, DAC LSB per (µm·s) (0 … 1e5).
    pub ki_lsb_per_um_s: f32,
    /// Derivative gain Kd, DAC LSB per (µm/s) (0 … 10).
    pub kd_lsb_s_per_um: f32,
    /// Integral separation m: integrate only while |e| ≤ m, µm (> 0).
    pub i_zone_um: f32,
    /// Integrator clamp, DAC LSB (0 … 2047).
    pub i_limit_lsb: f32,
    /// Velocity feed-forward for positive (extending) target speed, LSB per (µm/s) (0 … 100).
    pub kv_pos_lsb_per_um_s: f32,
    /// Velocity feed-forward for negative (retracting) target speed, LSB per (µm/s) (0 … 100).
    pub kv_neg_lsb_per_um_s: f32,
    /// Acceleration feed-forward, LSB per (µm/s²) (0 … 0.4).
    pub ka_lsb_per_um_s2: f32,
    /// Valve response delay to aim the feed-forward at, µs (0 … 100 000). For a 2nd-order
    /// spool of ω_v, ζ_v it is about 2ζ_v/ω_v (4.2 ms for 60 Hz, ζ 0.8).
    pub valve_lag_us: f32,
    /// Following-error fault limit, µm (> 0).
    pub following_error_um: f32,
    /// Active damping (ΔP feedback, [`super::damping`]): the command falls by this many
    /// LSB per kN of high-passed hydraulic force A_A·p_A − A_B·p_B (0 … 1000; 0 = off,
    /// the default). Needs the axis' piston areas.
    pub dp_gain_lsb_per_kn: f32,
    /// Active damping's high-pass corner, Hz (0.1 … 1000; default 5): below it the
    /// force is a load, not the oil column's oscillation, and is not fed back.
    pub dp_corner_hz: f32,
    /// Gain backoff ([`super::backoff`]): the band, µm, the high-passed following error
    /// must cross back and forth four times within 150 ms for the axis to take its
    /// proportional gain down (to 0.36×, then 0.75× per further oscillation; from the
    /// second level the integral gain too, to min(1, s/0.36); 0 … 10 000; 0 = off, the
    /// default). Feedforward axes only — a band on a Paper or NextNode axis is refused
    /// (`AxisConfigError::OscBand(BandError::Law)`: the baselines run as published); it
    /// acts while following (jog and test moves keep the set gain).
    pub osc_band_um: f32,
    /// Feed-forward trim ([`super::ff_trim`]): the time constant, s, with which the
    /// integrator's content moves into a ratio of the feed-forward kv±·v + ka·a, one per
    /// sign of the feed-forward, while the axis moves (the valve's real flow gain,
    /// learned; a constant the integrator holds while moving one way — an uncalibrated
    /// null, a steady load — is taken for a ratio too; 0.01 …
    /// 1 000 and at least 16 control periods; 0 = off, the default). Feedforward axes
    /// only — on a Paper or NextNode axis it is refused
    /// (`AxisConfigError::FfTrim(FfTrimError::Law)`).
    pub ff_trim_tau_s: f32,
    /// The gain backoff's thresholds ([`super::backoff::BackoffSettings`]; the
    /// defaults unless set; they act while `osc_band_um` is not 0).
    pub backoff: BackoffSettings,
}

impl Default for PositionGains {
    fn default() -> Self {
        Self {
            kp_lsb_per_um: 0.2,
            ki_lsb_per_um_s: 0.0,
            kd_lsb_s_per_um: 0.0,
            i_zone_um: 1000.0,
            i_limit_lsb: 200.0,
            kv_pos_lsb_per_um_s: 0.0,
            kv_neg_lsb_per_um_s: 0.0,
            ka_lsb_per_um_s2: 0.0,
            valve_lag_us: 4200.0,
            following_error_um: 5000.0,
            dp_gain_lsb_per_kn: 0.0,
            dp_corner_hz: 5.0,
            osc_band_um: 0.0,
            ff_trim_tau_s: 0.0,
            backoff: BackoffSettings::DEFAULT,
        }
    }
}

/// One position axis in engineering units: its control law, its gains and its valve.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisConfig {
    /// Control law.
    pub mode: ControlMode,
    /// Gains and the following-error limit.
    pub gains: PositionGains,
    /// Valve output calibration.
    pub valve: ValveCal,
    /// The cylinder's piston areas (used by the active damping only).
    pub areas: PistonAreas,
}

/// An axis parameter out of range (the field it names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AxisConfigError {
    /// `kp_lsb_per_um`.
    Kp,
    /// `ki_lsb_per_um_s` (or Ki·T too large for its format, or the largest integrator
    /// step Ki·T·m above 32 768 LSB per tick).
    Ki,
    /// `kd_lsb_s_per_um` (or Kd/T too large for its format).
    Kd,
    /// `i_zone_um`.
    IZone,
    /// `i_limit_lsb`.
    ILimit,
    /// `kv_pos_lsb_per_um_s` or `kv_neg_lsb_per_um_s`.
    Kv,
    /// `ka_lsb_per_um_s2`.
    Ka,
    /// `valve_lag_us`.
    ValveLag,
    /// `following_error_um`.
    FollowingError,
    /// The control period (50 µs … 1 s).
    Period,
    /// The valve calibration.
    Valve(ValveCalError),
    /// The active damping's gain, corner or piston areas.
    Damping(DampingError),
    /// `osc_band_um` (the gain backoff's band): out of range, or on a baseline law.
    OscBand(BandError),
    /// `ff_trim_tau_s` (the feed-forward trim): out of range, or on a baseline law.
    FfTrim(FfTrimError),
}

/// Validated fixed-point coefficients of one axis (see the format table in
/// [`crate::units`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisCoeffs {
    /// Control law.
    pub mode: ControlMode,
    /// Kp, LSB/µm, `I16F16` raw.
    pub kp: i32,
    /// Ki·T, LSB/(µm·tick), `I8F24` raw.
    pub ki_tick: i32,
    /// Kd/T, LSB/(µm/tick), `I16F16` raw.
    pub kd_tick: i32,
    /// m, µm, `I24F8` raw.
    pub i_zone: i32,
    /// Integrator clamp, LSB, `I16F16` raw.
    pub i_limit: i32,
    /// kv⁺, LSB/(µm/s), `I8F24` raw.
    pub kv_pos: i32,
    /// kv⁻, LSB/(µm/s), `I8F24` raw.
    pub kv_neg: i32,
    /// ka, LSB/(µm/s²), `I0F32` raw.
    pub ka: i32,
    /// Feed-forward aim after the sampling instant, ticks, Q16 (1.5·T + valve lag;
    /// below 16 384 ticks, the master filter's extrapolation limit).
    pub lead_q16: i32,
    /// Following-error limit, µm, `I24F8` raw.
    pub fe_limit: i32,
    /// Valve output stage.
    pub valve: ValveCoeffs,
    /// Active damping (ΔP feedback).
    pub damping: DampingCoeffs,
    /// Gain backoff on a detected oscillation.
    pub backoff: BackoffCoeffs,
    /// Feed-forward trim learned from the integrator.
    pub ff_trim: FfTrimCoeffs,
    /// Whether any of the active damping, the gain backoff or the trim is on (set by
    /// [`AxisConfig::build`]; the Feedforward law tests only this for an axis without
    /// them, then takes the backoff's and trim's out-of-line path or the damped one).
    pub(crate) extras: bool,
}

fn check(x: f32, lo: f32, hi: f32, e: AxisConfigError) -> Result<f32, AxisConfigError> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(x)
    } else {
        Err(e)
    }
}

fn fit<F: fixed::traits::Fixed>(x: f64, e: AxisConfigError) -> Result<F, AxisConfigError> {
    F::checked_from_num(x).ok_or(e)
}

impl AxisConfig {
    /// Validates the configuration for a control period `period_us` and converts it.
    pub fn build(&self, period_us: u32) -> Result<AxisCoeffs, AxisConfigError> {
        use AxisConfigError as E;
        let g = &self.gains;
        if !(50..=1_000_000).contains(&period_us) {
            return Err(E::Period);
        }
        let t = f64::from(period_us) * 1e-6;
        let kp = f64::from(check(g.kp_lsb_per_um, 0.0, 1000.0, E::Kp)?);
        let ki = f64::from(check(g.ki_lsb_per_um_s, 0.0, 1e5, E::Ki)?);
        let kd = f64::from(check(g.kd_lsb_s_per_um, 0.0, 10.0, E::Kd)?);
        let zone = f64::from(check(g.i_zone_um, 1e-3, 1e6, E::IZone)?);
        let ilim = f64::from(check(g.i_limit_lsb, 0.0, 2047.0, E::ILimit)?);
        let kvp = f64::from(check(g.kv_pos_lsb_per_um_s, 0.0, 100.0, E::Kv)?);
        let kvn = f64::from(check(g.kv_neg_lsb_per_um_s, 0.0, 100.0, E::Kv)?);
        let ka = f64::from(check(g.ka_lsb_per_um_s2, 0.0, 0.4, E::Ka)?);
        let lag = f64::from(check(g.valve_lag_us, 0.0, 100_000.0, E::ValveLag)?);
        let fe = f64::from(check(g.following_error_um, 1e-3, 1e6, E::FollowingError)?);
        let valve = self.valve.build().map_err(E::Valve)?;
        let damping =
            DampingCoeffs::build(g.dp_gain_lsb_per_kn, g.dp_corner_hz, &self.areas, period_us)
                .map_err(E::Damping)?;
        if damping.is_on() && self.mode != ControlMode::Feedforward {
            return Err(E::Damping(DampingError::Law));
        }
        let backoff =
            BackoffCoeffs::build(g.osc_band_um, &g.backoff, period_us).map_err(E::OscBand)?;
        if backoff.is_on() && self.mode != ControlMode::Feedforward {
            return Err(E::OscBand(BandError::Law));
        }
        let ff_trim = FfTrimCoeffs::build(g.ff_trim_tau_s, period_us, self.valve.clamp_lsb)
            .map_err(E::FfTrim)?;
        if ff_trim.is_on() && self.mode != ControlMode::Feedforward {
            return Err(E::FfTrim(FfTrimError::Law));
        }
        let lead_ticks = 1.5 + lag / f64::from(period_us);
        // Below the master filter's extrapolation limit (2^14 ticks).
        if lead_ticks >= 16_384.0 {
            return Err(E::ValveLag);
        }
        let ki_tick = fit::<I8F24>(ki * t, E::Ki)?.to_bits();
        let i_zone = fit::<I24F8>(zone, E::IZone)?.to_bits();
        // The largest integrator step, Ki·T·m, must stay below 2^15 LSB per tick
        // (e·Ki·T < 2^47 in Q32), so the laws form it without a saturation. 32 768 LSB
        // per tick is 16 times the whole valve range: no working tuning comes near it.
        if i64::from(i_zone).saturating_mul(i64::from(ki_tick)) >= 1 << 47 {
            return Err(E::Ki);
        }
        Ok(AxisCoeffs {
            mode: self.mode,
            kp: fit::<I16F16>(kp, E::Kp)?.to_bits(),
            ki_tick,
            kd_tick: fit::<I16F16>(kd / t, E::Kd)?.to_bits(),
            i_zone,
            i_limit: fit::<fixed::types::I16F16>(ilim, E::ILimit)?.to_bits(),
            kv_pos: fit::<I8F24>(kvp, E::Kv)?.to_bits(),
            kv_neg: fit::<I8F24>(kvn, E::Kv)?.to_bits(),
            ka: fit::<I0F32>(ka, E::Ka)?.to_bits(),
            lead_q16: (lead_ticks * 65536.0) as i32,
            fe_limit: fit::<I24F8>(fe, E::FollowingError)?.to_bits(),
            valve,
            extras: damping.is_on() || backoff.is_on() || ff_trim.is_on(),
            damping,
            backoff,
            ff_trim,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converts_units() {
        let c = AxisConfig {
            gains: PositionGains {
                kp_lsb_per_um: 0.5,
                ki_lsb_per_um_s: 10.0,
                kd_lsb_s_per_um: 0.001,
                kv_pos_lsb_per_um_s: 0.017,
                ..PositionGains::default()
            },
            ..AxisConfig::default()
        }
        .build(1000)
        .unwrap();
        assert_eq!(c.kp, 1 << 15);
        assert_eq!(c.ki_tick, (0.01f64 * 16_777_216.0).round() as i32);
        assert_eq!(c.kd_tick, 1 << 16);
        assert_eq!(c.lead_q16, (5.7 * 65536.0) as i32);
    }

    #[test]
    fn names_the_bad_field() {
        let bad = |f: fn(&mut AxisConfig)| {
            let mut c = AxisConfig::default();
            f(&mut c);
            c.build(1000)
        };
        assert_eq!(
            bad(|c| c.gains.kp_lsb_per_um = -1.0),
            Err(AxisConfigError::Kp)
        );
        assert_eq!(
            bad(|c| c.gains.ki_lsb_per_um_s = f32::NAN),
            Err(AxisConfigError::Ki)
        );
        assert_eq!(
            bad(|c| c.gains.kd_lsb_s_per_um = 20.0),
            Err(AxisConfigError::Kd)
        );
        // Ki·T·m = 1e5·1e-3·1e6 = 1e8 LSB per tick
        assert_eq!(
            bad(|c| {
                c.gains.ki_lsb_per_um_s = 1e5;
                c.gains.i_zone_um = 1e6;
            }),
            Err(AxisConfigError::Ki)
        );
        assert_eq!(
            bad(|c| c.gains.i_zone_um = 0.0),
            Err(AxisConfigError::IZone)
        );
        assert_eq!(
            bad(|c| c.gains.i_limit_lsb = 3000.0),
            Err(AxisConfigError::ILimit)
        );
        assert_eq!(
            bad(|c| c.gains.kv_neg_lsb_per_um_s = -0.1),
            Err(AxisConfigError::Kv)
        );
        assert_eq!(
            bad(|c| c.gains.ka_lsb_per_um_s2 = 1.0),
            Err(AxisConfigError::Ka)
        );
        assert_eq!(
            bad(|c| c.gains.valve_lag_us = f32::INFINITY),
            Err(AxisConfigError::ValveLag)
        );
        assert_eq!(
            bad(|c| c.gains.following_error_um = 0.0),
            Err(AxisConfigError::FollowingError)
        );
        assert_eq!(
            bad(|c| c.valve.gain_pos = 0.0),
            Err(AxisConfigError::Valve(ValveCalError::Gain))
        );
        assert_eq!(
            AxisConfig::default().build(20),
            Err(AxisConfigError::Period)
        );
        // Active damping: areas needed, Feedforward only.
        assert_eq!(
            bad(|c| c.gains.dp_gain_lsb_per_kn = 16.0),
            Err(AxisConfigError::Damping(DampingError::Area))
        );
        let damped = |mode| AxisConfig {
            mode,
            gains: PositionGains {
                dp_gain_lsb_per_kn: 16.0,
                ..PositionGains::default()
            },
            areas: crate::profile::piston_areas(),
            ..AxisConfig::default()
        };
        assert!(damped(ControlMode::Feedforward).build(1000).is_ok());
        assert_eq!(
            damped(ControlMode::Paper).build(1000),
            Err(AxisConfigError::Damping(DampingError::Law))
        );
        // The gain backoff: a band in range, Feedforward only (the baselines as published).
        let banded = |mode, band| AxisConfig {
            mode,
            gains: PositionGains {
                osc_band_um: band,
                ..PositionGains::default()
            },
            ..AxisConfig::default()
        };
        assert!(banded(ControlMode::Feedforward, 4.0).build(1000).is_ok());
        assert!(banded(ControlMode::Paper, 0.0).build(1000).is_ok());
        for mode in [ControlMode::Paper, ControlMode::NextNode] {
            assert_eq!(
                banded(mode, 4.0).build(1000),
                Err(AxisConfigError::OscBand(BandError::Law))
            );
        }
        assert_eq!(
            banded(ControlMode::Feedforward, -1.0).build(1000),
            Err(AxisConfigError::OscBand(BandError::Range))
        );
        // Kd/T out of I16F16 at 50 µs: 10 / 5e-5 = 2e5
        let mut c = AxisConfig::default();
        c.gains.kd_lsb_s_per_um = 10.0;
        assert_eq!(c.build(50), Err(AxisConfigError::Kd));
    }
}
