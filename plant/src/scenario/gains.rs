//! A scenario's gains as the core's configurations: choosing the `[[tuning]]` set of a
//! run, and converting a gain set and an axis' calibration into `hydra_core`'s
//! `AxisConfig`, `PressConfig` and `FollowerConfig`.
//!
//! A scenario holds one `[[tuning]]` set per (controller, control period). A run at
//! period T uses the set of that controller whose period is the shortest at or above T
//! (gains tuned for a longer period are the conservative choice on a faster loop), or
//! the longest set if T is longer than every tuned period (then the run prints a note).
//! The procedure that produced the reference sets is in `docs/sim.md`
//! (`host_sim::autotune`).

use super::{
    AxisCfg, Controller, PositionGains, PredictorCfg, PressGains, Scenario, ScenarioError, Tuning,
};
use hydra_core::axis::{AxisConfig, PistonAreas, PressConfig};
use hydra_core::follower::FollowerConfig;
use hydra_core::master::{MasterFilterConfig, PredictorKind};

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

/// The core configuration of one follower axis.
pub fn axis_config(axis: &AxisCfg, g: &PositionGains, controller: Controller) -> AxisConfig {
    AxisConfig {
        mode: controller.mode(),
        gains: *g,
        valve: axis.calibration,
        areas: piston_areas(axis),
    }
}

/// The axis cylinder's piston areas (chamber A: the piston side, B: the rod side), mm².
pub fn piston_areas(axis: &AxisCfg) -> PistonAreas {
    let c = axis.cylinder_si();
    PistonAreas {
        area_a_mm2: (c.area_a_m2 * 1e6) as f32,
        area_b_mm2: (c.area_b_m2 * 1e6) as f32,
    }
}

/// The core configuration of one force axis.
pub fn press_config(axis: &AxisCfg, g: &PressGains) -> Option<PressConfig> {
    let p = axis.press.as_ref()?;
    let areas = piston_areas(axis);
    Some(PressConfig {
        area_a_mm2: areas.area_a_mm2,
        area_b_mm2: areas.area_b_mm2,
        approach_end_um: (p.approach_end_mm * 1e3) as f32,
        approach_speed_um_per_s: (p.approach_speed_mm_per_s * 1e3) as f32,
        contact_force_n: p.contact_force_n as f32,
        // The approach's own acceleration transient lasts a few tens of ms.
        contact_arm_ms: 100.0,
        force_set_n: p.force_set_n as f32,
        force_ramp_ms: (p.force_ramp_s * 1e3) as f32,
        gains: *g,
        valve: axis.calibration,
    })
}

/// The follower configuration (`S` axes, in scenario order) for a gain set used at
/// `period_us`. A force axis (which a set cannot name in `[tuning.axes]`) gets the
/// default position gains: the position law that jogs and moves it by hand, and a
/// following-error limit of 5 000 µm on its approach.
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
            bandwidth_hz: t.master_filter_hz.min(filter_limit_hz(period_us)) as f32,
        },
        predictor: match t.predictor {
            PredictorCfg::Eq4 => PredictorKind::Eq4,
            PredictorCfg::Quadratic => PredictorKind::Quadratic,
        },
        ..FollowerConfig::default()
    };
    for (slot, a) in cfg.axes.iter_mut().zip(&s.axes) {
        let g = t.axes.get(&a.name).cloned().unwrap_or_default();
        *slot = axis_config(a, &g, controller);
    }
    Ok(cfg)
}

/// The master filter's bandwidth limit `0.2/T`, rounded down to 2 significant digits, Hz.
pub fn filter_limit_hz(period_us: u32) -> f64 {
    let max = 0.2e6 / f64::from(period_us);
    let e = 10f64.powf(max.log10().floor() - 1.0);
    (max / e).floor() * e
}
