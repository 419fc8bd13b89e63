//! Controller gains: the reference tuning, choosing a gain set for a run, and the
//! conversion of a scenario's gains into the core's configurations.
//!
//! A scenario holds one `[[tuning]]` set per (controller, control period). A run at
//! period T uses the set of that controller whose period is the shortest at or above T
//! (gains tuned for a longer period are the conservative choice on a faster loop), or
//! the longest set if T is longer than every tuned period (then the run prints a note).
//! The procedure that produced the reference sets is in `docs/sim.md`.

use crate::scenario::{
    AxisCfg, Controller, PositionGains, PredictorCfg, PressGains, Role, Scenario, ScenarioError,
    Tuning,
};
use hydra_core::axis::{AxisConfig, AxisConfigError, PressConfig, PressConfigError};
use hydra_core::follower::FollowerConfig;
use hydra_core::master::{MasterFilterConfig, PredictorKind};
use hydra_core::valve::ValveCalError;

fn invalid(key: String, value: impl ToString, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        key,
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// The reference machine's tuned gain sets: the `[[tuning]]` sets of
/// `host-sim/scenarios/tangent.toml` (compiled in, so the defaults and the shipped file
/// cannot differ; see `docs/sim.md` and [`crate::autotune`] for the procedure).
pub fn reference_tuning() -> Vec<Tuning> {
    /// Only the gain sets of the file (the other keys are ignored here).
    #[derive(serde::Deserialize)]
    struct TuningFile {
        #[serde(default)]
        tuning: Vec<Tuning>,
    }
    toml::from_str::<TuningFile>(include_str!("../scenarios/tangent.toml"))
        .map(|f| f.tuning)
        .unwrap_or_default()
}

/// The gain set a run of `controller` at `period_us` uses, and whether it was tuned at
/// exactly that period.
pub fn select(s: &Scenario, controller: Controller, period_us: u32) -> Option<(&Tuning, bool)> {
    let sets = s.tuning.iter().filter(|t| t.controller == controller);
    let at_or_above = sets
        .clone()
        .filter(|t| t.period_us >= period_us)
        .min_by_key(|t| t.period_us);
    let t = at_or_above.or_else(|| sets.max_by_key(|t| t.period_us))?;
    Some((t, t.period_us == period_us))
}

fn tkey(t: &Tuning) -> String {
    format!("tuning[{}@{}us]", t.controller.name(), t.period_us)
}

/// The core configuration of one follower axis.
pub fn axis_config(axis: &AxisCfg, g: &PositionGains, controller: Controller) -> AxisConfig {
    AxisConfig {
        mode: controller.mode(),
        kp_lsb_per_um: g.kp_lsb_per_um as f32,
        ki_lsb_per_um_s: g.ki_lsb_per_um_s as f32,
        kd_lsb_s_per_um: g.kd_lsb_s_per_um as f32,
        i_zone_um: g.i_zone_um as f32,
        i_limit_lsb: g.i_limit_lsb as f32,
        kv_pos_lsb_per_um_s: g.kv_pos_lsb_per_um_s as f32,
        kv_neg_lsb_per_um_s: g.kv_neg_lsb_per_um_s as f32,
        ka_lsb_per_um_s2: g.ka_lsb_per_um_s2 as f32,
        valve_lag_us: g.valve_lag_us as f32,
        following_error_um: g.following_error_um as f32,
        valve: axis.calibration,
    }
}

/// The core configuration of one force axis.
pub fn press_config(axis: &AxisCfg, g: &PressGains) -> Option<PressConfig> {
    let p = axis.press.as_ref()?;
    let c = axis.cylinder_si();
    Some(PressConfig {
        area_a_mm2: (c.area_a_m2 * 1e6) as f32,
        area_b_mm2: (c.area_b_m2 * 1e6) as f32,
        approach_end_um: (p.approach_end_mm * 1e3) as f32,
        approach_speed_um_per_s: (p.approach_speed_mm_per_s * 1e3) as f32,
        kp_lsb_per_um: g.kp_lsb_per_um as f32,
        kv_lsb_per_um_s: g.kv_lsb_per_um_s as f32,
        contact_force_n: p.contact_force_n as f32,
        // The approach's own acceleration transient lasts a few tens of ms.
        contact_arm_ms: 100.0,
        force_set_n: p.force_set_n as f32,
        force_ramp_ms: (p.force_ramp_s * 1e3) as f32,
        kp_lsb_per_n: g.kp_lsb_per_n as f32,
        ki_lsb_per_n_s: g.ki_lsb_per_n_s as f32,
        valve: axis.calibration,
    })
}

/// The follower configuration (`S` follower axes, in scenario order) for a gain set
/// used at `period_us`.
pub fn follower_config<const S: usize>(
    s: &Scenario,
    t: &Tuning,
    controller: Controller,
    period_us: u32,
) -> Result<FollowerConfig<S>, ScenarioError> {
    let mut cfg = FollowerConfig::<S> {
        period_us,
        // A set used at a longer period than it was tuned at may ask for more bandwidth
        // than the filter allows there (0.2/T): it gets the most the filter allows.
        master_filter: MasterFilterConfig {
            bandwidth_hz: t
                .master_filter_hz
                .min(crate::autotune::filter_limit_hz(period_us)) as f32,
        },
        predictor: match t.predictor {
            PredictorCfg::Eq4 => PredictorKind::Eq4,
            PredictorCfg::Quadratic => PredictorKind::Quadratic,
        },
        ..FollowerConfig::default()
    };
    let followers = s.axes.iter().filter(|a| a.role == Role::Follower);
    for (slot, a) in cfg.axes.iter_mut().zip(followers) {
        let g = t.axes.get(&a.name).cloned().unwrap_or_default();
        *slot = axis_config(a, &g, controller);
    }
    Ok(cfg)
}

fn axis_error_key(e: AxisConfigError) -> &'static str {
    match e {
        AxisConfigError::Kp => "kp_lsb_per_um",
        AxisConfigError::Ki => "ki_lsb_per_um_s",
        AxisConfigError::Kd => "kd_lsb_s_per_um",
        AxisConfigError::IZone => "i_zone_um",
        AxisConfigError::ILimit => "i_limit_lsb",
        AxisConfigError::Kv => "kv_pos_lsb_per_um_s / kv_neg_lsb_per_um_s",
        AxisConfigError::Ka => "ka_lsb_per_um_s2",
        AxisConfigError::ValveLag => "valve_lag_us",
        AxisConfigError::FollowingError => "following_error_um",
        AxisConfigError::Period => "period_us",
        AxisConfigError::Valve(v) => valve_error_key(v),
    }
}

fn valve_error_key(e: ValveCalError) -> &'static str {
    match e {
        ValveCalError::Null => "calibration.null_lsb",
        ValveCalError::Overlap => "calibration.overlap_pos_lsb / overlap_neg_lsb",
        ValveCalError::OverlapZone => "calibration.overlap_zone_lsb",
        ValveCalError::Gain => "calibration.gain_pos / gain_neg",
        ValveCalError::Clamp => "calibration.clamp_lsb",
    }
}

fn press_error_key(e: PressConfigError) -> &'static str {
    match e {
        PressConfigError::Area => "cylinder.bore_mm / rod_mm",
        PressConfigError::ApproachEnd => "press.approach_end_mm",
        PressConfigError::ApproachSpeed => "press.approach_speed_mm_per_s",
        PressConfigError::PositionGain => "kp_lsb_per_um / kv_lsb_per_um_s",
        PressConfigError::ContactForce => "press.contact_force_n",
        PressConfigError::ForceSet => "press.force_set_n",
        PressConfigError::ForceRamp => "press.force_ramp_s",
        PressConfigError::ForceGain => "kp_lsb_per_n / ki_lsb_per_n_s",
        PressConfigError::Period => "period_us",
        PressConfigError::Valve(v) => valve_error_key(v),
    }
}

/// Checks every gain set by building the core's configurations from it; the error
/// names the key, e.g. `tuning[paper@72000us].axes.tangent.kp_lsb_per_um`.
pub fn validate(s: &Scenario) -> Result<(), ScenarioError> {
    for (i, t) in s.tuning.iter().enumerate() {
        let k = tkey(t);
        if s.tuning[..i]
            .iter()
            .any(|u| u.controller == t.controller && u.period_us == t.period_us)
        {
            return Err(invalid(
                format!("{k}.period_us"),
                t.period_us,
                "two gain sets for the same controller and period",
            ));
        }
        if !(50..=1_000_000).contains(&t.period_us) {
            return Err(invalid(
                format!("{k}.period_us"),
                t.period_us,
                "must be in [50, 1000000] µs",
            ));
        }
        MasterFilterConfig {
            bandwidth_hz: t.master_filter_hz as f32,
        }
        .build(t.period_us)
        .map_err(|_| {
            invalid(
                format!("{k}.master_filter_hz"),
                t.master_filter_hz,
                format!(
                    "must be in [0.1, 0.2/T = {:.3}] Hz",
                    0.2e6 / f64::from(t.period_us)
                ),
            )
        })?;
        for (name, g) in &t.axes {
            let a = s
                .axes
                .iter()
                .find(|a| &a.name == name && a.role == Role::Follower)
                .ok_or_else(|| {
                    invalid(
                        format!("{k}.axes.{name}"),
                        name,
                        "no follower axis has this name",
                    )
                })?;
            axis_config(a, g, t.controller)
                .build(t.period_us)
                .map_err(|e| {
                    let field = axis_error_key(e);
                    invalid(
                        format!("{k}.axes.{name}.{field}"),
                        format!("{e:?}"),
                        "out of its range (see hydra_core::axis::AxisConfig)",
                    )
                })?;
        }
        for (name, g) in &t.press {
            let a = s
                .axes
                .iter()
                .find(|a| &a.name == name && a.role == Role::Force)
                .ok_or_else(|| {
                    invalid(
                        format!("{k}.press.{name}"),
                        name,
                        "no force axis has this name",
                    )
                })?;
            if let Some(pc) = press_config(a, g) {
                pc.build(t.period_us).map_err(|e| {
                    invalid(
                        format!("{k}.press.{name}.{}", press_error_key(e)),
                        format!("{e:?}"),
                        "out of its range (see hydra_core::axis::PressConfig)",
                    )
                })?;
            }
        }
    }
    Ok(())
}
