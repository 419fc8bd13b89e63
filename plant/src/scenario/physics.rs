//! The plant and sensors a scenario describes, in SI units (`crate::hydraulics`'s models):
//! valves, cylinders, encoders, pressure transducers, the supply and the master motion.

use super::{invalid, AxisCfg, Scenario, ScenarioError};
use crate::hydraulics::{
    Contact, Cylinder, Encoder, HydraulicAxis, MasterMotion, MasterProfile, PressureAdc, Supply,
    Valve,
};
use std::f64::consts::PI;

impl Scenario {
    /// The master motion.
    pub fn master_motion(&self) -> MasterMotion {
        let m = &self.master;
        MasterMotion {
            start_deg: m.start_deg,
            end_deg: m.end_deg,
            speed_deg_per_s: m.speed_deg_per_s,
            ramp_s: m.ramp_s,
            ripple: m.ripple,
            ripple_hz: m.ripple_hz,
            ripple_phase_rad: m.ripple_phase_deg.to_radians(),
            start_s: m.start_s,
            hold_s: m.hold_s,
        }
    }

    /// The master profile (validated).
    pub fn master_profile(&self) -> Result<MasterProfile, ScenarioError> {
        MasterProfile::new(self.master_motion())
            .map_err(|e| invalid("master.end_deg", self.master.end_deg, e.to_string()))
    }

    /// The master encoder.
    pub fn master_encoder(&self) -> Encoder {
        Encoder {
            resolution: self.master.resolution_deg,
        }
    }

    /// The board's master edge timer, if the scenario has one (`master.edge_timer_hz`).
    pub fn master_edge_timer(&self) -> Option<crate::hydraulics::EdgeTimer> {
        (self.master.edge_timer_hz > 0.0).then_some(crate::hydraulics::EdgeTimer {
            hz: self.master.edge_timer_hz,
        })
    }

    /// The supply in SI units.
    pub fn supply(&self) -> Supply {
        let s = &self.supply;
        Supply {
            supply_pa: s.supply_bar * 1e5,
            tank_pa: s.tank_bar * 1e5,
            max_pa: s.clamp_factor * s.supply_bar * 1e5,
        }
    }
}

impl AxisCfg {
    /// The valve in SI units.
    pub fn valve_si(&self) -> Valve {
        let v = &self.valve;
        Valve {
            omega_rad_s: 2.0 * PI * v.bandwidth_hz,
            zeta: v.damping,
            kv: Valve::kv_from_rating(v.rated_flow_l_per_min * 1e-3 / 60.0, v.rated_dp_bar * 1e5),
            leak_m3_per_s_pa: v.leakage_m3_per_s_pa,
            dp_transition_pa: v.transition_bar * 1e5,
        }
    }

    /// The cylinder in SI units.
    pub fn cylinder_si(&self) -> Cylinder {
        let c = &self.cylinder;
        let area_a = PI / 4.0 * (c.bore_mm * 1e-3).powi(2);
        let area_rod = PI / 4.0 * (c.rod_mm * 1e-3).powi(2);
        Cylinder {
            area_a_m2: area_a,
            area_b_m2: area_a - area_rod,
            stroke_m: c.stroke_mm * 1e-3,
            dead_volume_a_m3: c.dead_volume_a_l * 1e-3,
            dead_volume_b_m3: c.dead_volume_b_l * 1e-3,
            bulk_modulus_pa: c.bulk_modulus_pa,
            mass_kg: c.mass_kg,
            viscous_n_s_per_m: c.viscous_n_s_per_m,
            coulomb_n: c.coulomb_n,
            coulomb_smoothing_m_per_s: c.coulomb_smoothing_mm_per_s * 1e-3,
            load_n: c.load_n,
            stop_stiffness_n_per_m: c.stop_stiffness_n_per_m,
            stop_damping_n_s_per_m: 2.0
                * c.stop_damping_ratio
                * (c.stop_stiffness_n_per_m * c.mass_kg).sqrt(),
            contact: self.contact.as_ref().map(|ct| Contact {
                position_m: ct.position_mm * 1e-3,
                stiffness_n_per_m: ct.stiffness_n_per_m,
            }),
        }
    }

    /// The position encoder (resolution in m).
    pub fn encoder(&self) -> Encoder {
        Encoder {
            resolution: self.sensors.encoder_um * 1e-6,
        }
    }

    /// The pressure transducers.
    pub fn pressure_adc(&self) -> PressureAdc {
        PressureAdc {
            full_scale_pa: self.sensors.pressure_full_scale_bar * 1e5,
            bits: self.sensors.pressure_adc_bits,
        }
    }

    /// The plant of this axis at rest at `x0_m`.
    pub fn plant(&self, supply: Supply, x0_m: f64) -> HydraulicAxis {
        HydraulicAxis::at_rest(self.valve_si(), self.cylinder_si(), supply, x0_m)
    }
}
