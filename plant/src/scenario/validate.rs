//! Validation of a scenario: every value a real machine could have, and every gain set
//! as the core's configuration builders accept it. Errors name the key, e.g.
//! `axis.tangent.cylinder.rod_mm` or `tuning[paper@72000us].axes.tangent.kp_lsb_per_um`.

use super::gains::{axis_config, press_config};
use super::{invalid, AxisCfg, Role, Scenario, ScenarioError, Tuning};
use hydra_core::axis::{AxisConfigError, BandError, DampingError, FfTrimError, PressConfigError};
use hydra_core::master::MasterFilterConfig;
use hydra_core::valve::ValveCalError;
use std::f64::consts::PI;

/// Checks `lo < x` (or `lo ≤ x`) and `x ≤ hi`, finite.
fn check(key: &str, x: f64, lo: f64, lo_inclusive: bool, hi: f64) -> Result<(), ScenarioError> {
    if !x.is_finite() {
        return Err(invalid(key, x, "must be a finite number"));
    }
    let above = if lo_inclusive { x >= lo } else { x > lo };
    if !above || x > hi {
        let l = if lo_inclusive { "[" } else { "(" };
        return Err(invalid(key, x, format!("must be in {l}{lo}, {hi}]")));
    }
    Ok(())
}

impl Scenario {
    /// Checks the RK4 step and the control period (a whole number of steps).
    pub fn validate_timing(&self) -> Result<(), ScenarioError> {
        let sim = &self.sim;
        check("sim.step_us", sim.step_us, 0.0, false, 1000.0)?;
        if sim.period_us == 0 {
            return Err(invalid("sim.period_us", 0, "must be at least 1 µs"));
        }
        let ratio = f64::from(sim.period_us) / sim.step_us;
        if (ratio - ratio.round()).abs() > 1e-9 * ratio || ratio.round() < 1.0 {
            return Err(invalid(
                "sim.period_us",
                sim.period_us,
                format!(
                    "must be a whole number of RK4 steps (sim.step_us = {})",
                    sim.step_us
                ),
            ));
        }
        Ok(())
    }

    /// Checks every value; the error names the first impossible key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.validate_timing()?;
        let sim = &self.sim;
        check("sim.error_skip_s", sim.error_skip_s, 0.0, true, 1e6)?;
        if let Some(d) = sim.duration_s {
            check("sim.duration_s", d, 0.0, false, 1e6)?;
        }
        let s = &self.supply;
        check("supply.supply_bar", s.supply_bar, 0.0, false, 1000.0)?;
        check("supply.tank_bar", s.tank_bar, 0.0, true, s.supply_bar)?;
        if s.tank_bar >= s.supply_bar {
            return Err(invalid(
                "supply.tank_bar",
                s.tank_bar,
                "must be below supply.supply_bar",
            ));
        }
        check("supply.clamp_factor", s.clamp_factor, 1.0, true, 10.0)?;
        if let Some(d) = &s.drift {
            d.validate(s.tank_bar)?;
        }
        let m = &self.master;
        check("master.start_deg", m.start_deg, -1e6, true, 1e6)?;
        check("master.end_deg", m.end_deg, -1e6, true, 1e6)?;
        if m.end_deg == m.start_deg {
            return Err(invalid(
                "master.end_deg",
                m.end_deg,
                "must differ from master.start_deg",
            ));
        }
        check("master.speed_deg_per_s", m.speed_deg_per_s, 0.0, false, 1e5)?;
        check("master.ramp_s", m.ramp_s, 0.0, false, 1e4)?;
        check("master.ripple", m.ripple, 0.0, true, 0.99)?;
        check("master.ripple_hz", m.ripple_hz, 0.0, true, 1e4)?;
        check(
            "master.ripple_phase_deg",
            m.ripple_phase_deg,
            -1e6,
            true,
            1e6,
        )?;
        check("master.start_s", m.start_s, 0.0, true, 1e5)?;
        check("master.hold_s", m.hold_s, 0.0, true, 1e5)?;
        check("master.resolution_deg", m.resolution_deg, 0.0, false, 10.0)?;
        if m.edge_timer_hz != 0.0 {
            check("master.edge_timer_hz", m.edge_timer_hz, 1e3, true, 1e9)?;
        }
        self.master_profile()?;
        if self.axes.is_empty() {
            return Err(invalid("axis", "[]", "at least one [[axis]] is needed"));
        }
        for (i, a) in self.axes.iter().enumerate() {
            if a.name.is_empty()
                || !a
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(invalid(
                    format!("axis[{i}].name"),
                    format!("{:?}", a.name),
                    "must be a non-empty name of letters, digits, `_` or `-`",
                ));
            }
            if self.axes[..i].iter().any(|b| b.name == a.name) {
                return Err(invalid(
                    format!("axis[{i}].name"),
                    &a.name,
                    "two axes have this name",
                ));
            }
            a.validate(self.step_s())?;
            if let Some(l) = &a.load {
                l.validate(&format!("axis.{}.load", a.name))?;
            }
            if let Some(d) = &a.drift {
                d.validate(&format!("axis.{}.drift", a.name))?;
            }
        }
        let axes: Vec<&str> = self.axes.iter().map(|a| a.name.as_str()).collect();
        self.events.validate(&axes)?;
        validate_tuning(self)
    }
}

impl AxisCfg {
    fn validate(&self, step_s: f64) -> Result<(), ScenarioError> {
        let k = |s: &str| format!("axis.{}.{s}", self.name);
        let v = &self.valve;
        check(&k("valve.bandwidth_hz"), v.bandwidth_hz, 0.0, false, 1e4)?;
        check(&k("valve.damping"), v.damping, 0.0, false, 10.0)?;
        check(
            &k("valve.rated_flow_l_per_min"),
            v.rated_flow_l_per_min,
            0.0,
            false,
            1e5,
        )?;
        check(&k("valve.rated_dp_bar"), v.rated_dp_bar, 0.0, false, 1000.0)?;
        check(
            &k("valve.leakage_m3_per_s_pa"),
            v.leakage_m3_per_s_pa,
            0.0,
            true,
            1e-9,
        )?;
        check(
            &k("valve.transition_bar"),
            v.transition_bar,
            0.0,
            false,
            10.0,
        )?;
        let c = &self.cylinder;
        check(&k("cylinder.bore_mm"), c.bore_mm, 0.0, false, 2000.0)?;
        check(&k("cylinder.rod_mm"), c.rod_mm, 0.0, true, 2000.0)?;
        if c.rod_mm >= c.bore_mm {
            return Err(invalid(
                k("cylinder.rod_mm"),
                c.rod_mm,
                format!("must be smaller than cylinder.bore_mm ({})", c.bore_mm),
            ));
        }
        check(&k("cylinder.stroke_mm"), c.stroke_mm, 0.0, false, 8000.0)?;
        check(
            &k("cylinder.dead_volume_a_l"),
            c.dead_volume_a_l,
            0.0,
            false,
            1e4,
        )?;
        check(
            &k("cylinder.dead_volume_b_l"),
            c.dead_volume_b_l,
            0.0,
            false,
            1e4,
        )?;
        check(
            &k("cylinder.bulk_modulus_pa"),
            c.bulk_modulus_pa,
            0.0,
            false,
            1e11,
        )?;
        check(&k("cylinder.mass_kg"), c.mass_kg, 0.0, false, 1e7)?;
        check(
            &k("cylinder.viscous_n_s_per_m"),
            c.viscous_n_s_per_m,
            0.0,
            true,
            1e9,
        )?;
        check(&k("cylinder.coulomb_n"), c.coulomb_n, 0.0, true, 1e8)?;
        check(
            &k("cylinder.coulomb_smoothing_mm_per_s"),
            c.coulomb_smoothing_mm_per_s,
            0.0,
            false,
            1e4,
        )?;
        check(&k("cylinder.load_n"), c.load_n, -1e9, true, 1e9)?;
        check(
            &k("cylinder.stop_stiffness_n_per_m"),
            c.stop_stiffness_n_per_m,
            0.0,
            false,
            1e14,
        )?;
        check(
            &k("cylinder.stop_damping_ratio"),
            c.stop_damping_ratio,
            0.0,
            true,
            100.0,
        )?;
        if let Some(ct) = &self.contact {
            check(
                &k("contact.position_mm"),
                ct.position_mm,
                0.0,
                true,
                c.stroke_mm,
            )?;
            check(
                &k("contact.stiffness_n_per_m"),
                ct.stiffness_n_per_m,
                0.0,
                false,
                1e12,
            )?;
        }
        let s = &self.sensors;
        check(&k("sensors.encoder_um"), s.encoder_um, 0.0, false, 1e4)?;
        check(
            &k("sensors.pressure_full_scale_bar"),
            s.pressure_full_scale_bar,
            0.0,
            false,
            5000.0,
        )?;
        if !(8..=24).contains(&s.pressure_adc_bits) {
            return Err(invalid(
                k("sensors.pressure_adc_bits"),
                s.pressure_adc_bits,
                "must be in [8, 24]",
            ));
        }
        if let Some(x0) = self.x0_mm {
            check(&k("x0_mm"), x0, 0.0, true, c.stroke_mm)?;
        }
        match (&self.press, self.role) {
            (None, Role::Force) => {
                return Err(invalid(
                    k("press"),
                    "missing",
                    "a force axis needs an [axis.press] section",
                ));
            }
            (Some(_), Role::Follower) => {
                return Err(invalid(
                    k("press"),
                    "given",
                    "only a `role = \"force\"` axis has a press process",
                ));
            }
            (Some(p), Role::Force) => {
                check(
                    &k("press.approach_end_mm"),
                    p.approach_end_mm,
                    0.0,
                    true,
                    c.stroke_mm,
                )?;
                check(
                    &k("press.approach_speed_mm_per_s"),
                    p.approach_speed_mm_per_s,
                    0.0,
                    false,
                    1000.0,
                )?;
                check(
                    &k("press.contact_force_n"),
                    p.contact_force_n,
                    0.0,
                    false,
                    1e6,
                )?;
                check(&k("press.force_set_n"), p.force_set_n, 0.0, false, 1e6)?;
                check(&k("press.force_ramp_s"), p.force_ramp_s, 1e-3, true, 60.0)?;
            }
            (None, Role::Follower) => {}
        }
        let cal = &self.calibration;
        if let Err(e) = cal.build() {
            return Err(invalid(
                k("calibration"),
                format!("{e:?}"),
                "out of its range (see hydra_core::valve::ValveCal)",
            ));
        }
        // Fixed-step RK4 is stable for h·|λ| below about 2.8; ask for a margin of 2 on the
        // fastest modes (spool, oil column at the stiffer end of the stroke, end stops).
        let cyl = self.cylinder_si();
        let w_valve = 2.0 * PI * v.bandwidth_hz;
        let w_oil = 2.0
            * PI
            * cyl
                .natural_frequency_hz(0.0)
                .max(cyl.natural_frequency_hz(cyl.stroke_m));
        let w_stop = (cyl.stop_stiffness_n_per_m / cyl.mass_kg).sqrt();
        let w_contact = self
            .contact
            .as_ref()
            .map_or(0.0, |ct| (ct.stiffness_n_per_m / cyl.mass_kg).sqrt());
        // A chamber behind an open land below the transition pressure: ṗ = −E/V·K_v/√p_tr·Δp.
        let valve = self.valve_si();
        let w_land = cyl.bulk_modulus_pa / cyl.dead_volume_a_m3.min(cyl.dead_volume_b_m3)
            * valve.kv
            / valve.dp_transition_pa.sqrt();
        for (what, w) in [
            ("valve.bandwidth_hz", w_valve),
            ("valve.transition_bar", w_land),
            ("the oil-column frequency", w_oil),
            ("cylinder.stop_stiffness_n_per_m", w_stop),
            ("contact.stiffness_n_per_m", w_contact),
        ] {
            if w * step_s > 1.4 {
                return Err(invalid(
                    "sim.step_us",
                    step_s * 1e6,
                    format!(
                        "too long for axis `{}`: {what} gives a mode of {:.0} rad/s, RK4 needs step < {:.2} µs",
                        self.name,
                        w,
                        1.4 / w * 1e6
                    ),
                ));
            }
        }
        Ok(())
    }
}

fn tkey(t: &Tuning) -> String {
    format!("tuning[{}@{}us]", t.controller.name(), t.period_us)
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
        AxisConfigError::OscBand(BandError::Range) => "osc_band_um",
        AxisConfigError::OscBand(BandError::Setting(f)) => f.key(),
        AxisConfigError::OscBand(BandError::Law) => {
            "osc_band_um (gain backoff: controller feedforward only)"
        }
        AxisConfigError::FfTrim(FfTrimError::Range) => {
            "ff_trim_tau_s (0, or 0.01 … 1000 s and at least 16 periods)"
        }
        AxisConfigError::FfTrim(FfTrimError::Law) => {
            "ff_trim_tau_s (feed-forward trim: controller feedforward only)"
        }
        AxisConfigError::Valve(v) => valve_error_key(v),
        AxisConfigError::Damping(DampingError::Gain) => "dp_gain_lsb_per_kn",
        AxisConfigError::Damping(DampingError::Corner) => "dp_corner_hz",
        AxisConfigError::Damping(DampingError::Law) => {
            "dp_gain_lsb_per_kn (active damping: controller feedforward only)"
        }
        AxisConfigError::Damping(DampingError::Area) => {
            "dp_gain_lsb_per_kn (× cylinder.bore_mm / rod_mm areas)"
        }
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
fn validate_tuning(s: &Scenario) -> Result<(), ScenarioError> {
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
