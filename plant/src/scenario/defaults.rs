//! The defaults of every scenario key: the reference machine of `shared/PLANT.md`, and
//! its tuned gain sets (the `[[tuning]]` sets of `host-sim/scenarios/tangent.toml`).

use super::*;

impl Default for PressCfg {
    fn default() -> Self {
        Self {
            approach_end_mm: 60.0,
            approach_speed_mm_per_s: 20.0,
            contact_force_n: 2000.0,
            force_set_n: 20_000.0,
            force_ramp_s: 1.0,
        }
    }
}

impl Default for SimCfg {
    fn default() -> Self {
        Self {
            step_us: 10.0,
            period_us: 1000,
            error_skip_s: 1.5,
            duration_s: None,
            controller: Controller::Feedforward,
        }
    }
}

impl Default for SupplyCfg {
    fn default() -> Self {
        Self {
            supply_bar: 160.0,
            tank_bar: 0.0,
            clamp_factor: 1.1,
            drift: None,
        }
    }
}

impl Default for MasterCfg {
    fn default() -> Self {
        Self {
            start_deg: 0.0,
            end_deg: 90.0,
            speed_deg_per_s: 3.0,
            ramp_s: 1.0,
            ripple: 0.03,
            ripple_hz: 0.4,
            ripple_phase_deg: 0.0,
            start_s: 0.0,
            hold_s: 1.0,
            resolution_deg: 0.001,
            edge_timer_hz: 1e6,
        }
    }
}

impl Default for ValveCfg {
    fn default() -> Self {
        Self {
            bandwidth_hz: 60.0,
            damping: 0.8,
            rated_flow_l_per_min: 24.0,
            rated_dp_bar: 35.0,
            leakage_m3_per_s_pa: 1e-13,
            transition_bar: 0.01,
        }
    }
}

impl Default for CylinderCfg {
    fn default() -> Self {
        Self {
            bore_mm: 80.0,
            rod_mm: 45.0,
            stroke_mm: 500.0,
            dead_volume_a_l: 0.3,
            dead_volume_b_l: 0.3,
            bulk_modulus_pa: 1.4e9,
            mass_kg: 300.0,
            viscous_n_s_per_m: 3000.0,
            coulomb_n: 400.0,
            coulomb_smoothing_mm_per_s: 1.0,
            load_n: 0.0,
            stop_stiffness_n_per_m: 1e10,
            stop_damping_ratio: 1.0,
        }
    }
}

impl Default for ContactCfg {
    fn default() -> Self {
        Self {
            position_mm: 50.0,
            stiffness_n_per_m: 5e6,
        }
    }
}

impl Default for SensorCfg {
    fn default() -> Self {
        Self {
            encoder_um: 1.0,
            pressure_full_scale_bar: 250.0,
            pressure_adc_bits: 12,
        }
    }
}

impl Default for AxisCfg {
    fn default() -> Self {
        Self {
            name: String::new(),
            role: Role::Follower,
            x0_mm: None,
            valve: ValveCfg::default(),
            cylinder: CylinderCfg::default(),
            contact: None,
            sensors: SensorCfg::default(),
            calibration: hydra_core::valve::ValveCal::default(),
            press: None,
            load: None,
            drift: None,
        }
    }
}

impl AxisCfg {
    /// PLANT.md's tangent cylinder.
    pub fn reference_tangent() -> Self {
        Self {
            name: "tangent".into(),
            ..Self::default()
        }
    }

    /// PLANT.md's side press: same valve and bore, 100 mm stroke, a 5e6 N/m workpiece
    /// beyond 50 mm.
    pub fn reference_side_press() -> Self {
        Self {
            name: "side_press".into(),
            role: Role::Force,
            cylinder: CylinderCfg {
                stroke_mm: 100.0,
                ..CylinderCfg::default()
            },
            contact: Some(ContactCfg::default()),
            x0_mm: Some(10.0),
            press: Some(PressCfg::default()),
            ..Self::default()
        }
    }
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: String::new(),
            sim: SimCfg::default(),
            supply: SupplyCfg::default(),
            master: MasterCfg::default(),
            table: TableCfg::default(),
            axes: vec![
                AxisCfg::reference_tangent(),
                AxisCfg::reference_side_press(),
            ],
            tuning: reference_tuning(),
            events: super::events::EventsCfg::default(),
            base_dir: PathBuf::from("."),
        }
    }
}

/// The reference machine's tuned gain sets: the `[[tuning]]` sets of
/// `host-sim/scenarios/tangent.toml` (compiled in, so the defaults and the shipped file
/// cannot differ; see `docs/sim.md` and `host_sim::autotune` for the procedure).
pub fn reference_tuning() -> Vec<Tuning> {
    /// Only the gain sets of the file (the other keys are ignored here).
    #[derive(serde::Deserialize)]
    struct TuningFile {
        #[serde(default)]
        tuning: Vec<Tuning>,
    }
    toml::from_str::<TuningFile>(include_str!("../../../host-sim/scenarios/tangent.toml"))
        .map(|f| f.tuning)
        .unwrap_or_default()
}
