//! The machine a controller runs against, assembled in one place: the simulator
//! (`host-sim run`), the virtual board, `board-emu`'s emulated STM32F407 and the X–Y
//! table all build their plant and sensors here. [`MachinePlant`]: a scenario's axes in
//! order (the reference machine's tangent cylinder first, its side press second — a
//! board's slaves 0 and 1), the master profile, and the sensors the controller reads —
//! the master and slave encoders, the chamber pressure transducers. [`xy_axes`]: the
//! X–Y table's two axes.
//!
//! Units: SI inside the plant (m, m/s, Pa); encoder counts as the scenario's encoders
//! quantise them (master 0.001° per count, slaves 1 µm per count on the reference
//! machine); valve command u ∈ [−1, 1] (full opening), 0 while the valve power is off
//! (an unpowered servo valve's spool centres).

use crate::camfile::{interpolate, CamCsv};
use crate::hydraulics::{Encoder, HydraulicAxis, MasterProfile, PressureAdc, Supply};
use crate::scenario::{AxisCfg, Role, Scenario, ScenarioError};

/// Where a slave starts when neither the scenario (`x0_mm`) nor its table column says, mm.
pub const DEFAULT_X0_MM: f64 = 250.0;

/// One slave: its cylinder and valve, and its sensors.
#[derive(Clone, Debug)]
pub struct MachineAxis {
    /// Name (the scenario's).
    pub name: String,
    /// The hydraulic axis.
    pub plant: HydraulicAxis,
    /// Its position encoder.
    pub enc: Encoder,
    /// Its chamber pressure transducers.
    pub adc: PressureAdc,
    /// Its table column (mm), if it follows the table given at assembly.
    pub column: Option<Vec<f64>>,
}

impl MachineAxis {
    /// The encoder count of the slave's true position.
    pub fn count(&self) -> i64 {
        self.enc.count(self.plant.x_m())
    }

    /// Chamber pressures A, B as the transducers read them, bar.
    pub fn pressures_bar(&self) -> (f64, f64) {
        let (pa, pb) = self.plant.pressures_pa();
        (self.adc.read_pa(pa) * 1e-5, self.adc.read_pa(pb) * 1e-5)
    }
}

/// The plant a board is wired to.
#[derive(Clone, Debug)]
pub struct MachinePlant {
    /// The slaves (at most the board's count; fewer if the scenario has fewer axes — a
    /// board channel with no slave reads count 0 and drives nothing).
    pub slaves: Vec<MachineAxis>,
    /// The master's motion.
    pub master: MasterProfile,
    /// The master encoder.
    pub master_enc: Encoder,
    /// The plant's integration step, s.
    pub step_s: f64,
}

impl MachinePlant {
    /// The scenario's first `board_slaves` axes. A follower that has a column of `table`
    /// (matched by name) keeps it. Each axis starts at the scenario's `x0_mm`, else a
    /// follower at its column's value at the master's start angle, else a force axis at
    /// 0 mm and a follower without a column at [`DEFAULT_X0_MM`].
    pub fn new(
        scn: &Scenario,
        table: Option<&CamCsv>,
        board_slaves: usize,
    ) -> Result<Self, ScenarioError> {
        let slaves = scn
            .axes
            .iter()
            .take(board_slaves)
            .map(|a| {
                let column = (a.role == Role::Follower)
                    .then(|| table.and_then(|t| t.column(&a.name)).map(<[f64]>::to_vec))
                    .flatten();
                let at_start = |c: &Vec<f64>| {
                    table.map(|t| interpolate(&t.master, c, scn.master.start_deg, &mut 0))
                };
                let x0_mm = a
                    .x0_mm
                    .or_else(|| column.as_ref().and_then(at_start))
                    .unwrap_or(match a.role {
                        Role::Force => 0.0,
                        Role::Follower => DEFAULT_X0_MM,
                    });
                MachineAxis {
                    name: a.name.clone(),
                    plant: a.plant(scn.supply(), x0_mm * 1e-3),
                    enc: a.encoder(),
                    adc: a.pressure_adc(),
                    column,
                }
            })
            .collect();
        Ok(Self {
            slaves,
            master: scn.master_profile()?,
            master_enc: scn.master_encoder(),
            step_s: scn.step_s(),
        })
    }

    /// One integration step with valve commands `u` (one per slave; missing = 0).
    pub fn step(&mut self, u: &[f64]) {
        for (k, s) in self.slaves.iter_mut().enumerate() {
            s.plant.step(u.get(k).copied().unwrap_or(0.0), self.step_s);
        }
    }

    /// The master encoder's count at master time `t_s` (s since the master started).
    pub fn master_count(&self, t_s: f64) -> i64 {
        self.master_enc.count(self.master.angle_deg(t_s))
    }

    /// Slave `k`'s encoder count (0 for a channel with no slave).
    pub fn slave_count(&self, k: usize) -> i64 {
        self.slaves.get(k).map_or(0, MachineAxis::count)
    }
}

/// The X–Y table's two axes at rest at `start_um` from the path origin (mid-stroke,
/// `origin_m`): X per PLANT.md, Y with 1.5× the moving mass and 30 % less valve flow.
pub fn xy_axes(origin_m: f64, start_um: [f64; 2]) -> (HydraulicAxis, HydraulicAxis, Supply) {
    let supply = Scenario::default().supply();
    let x = AxisCfg::default();
    let mut y = AxisCfg::default();
    y.cylinder.mass_kg *= 1.5;
    y.valve.rated_flow_l_per_min *= 0.7;
    let ax = x.plant(supply, origin_m + start_um[0] * 1e-6);
    let ay = y.plant(supply, origin_m + start_um[1] * 1e-6);
    (ax, ay, supply)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_machine_has_tangent_then_side_press() {
        let scn = Scenario::default();
        let p = MachinePlant::new(&scn, None, 2).expect("plant");
        let names: Vec<_> = p.slaves.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["tangent", "side_press"]);
        // Encoders at 1 µm: the tangent at its default start, the press at x0 = 10 mm.
        assert_eq!(p.slave_count(0), 250_000);
        assert_eq!(p.slave_count(1), 10_000);
        assert_eq!(p.slave_count(2), 0);
        let (pa, pb) = p.slaves[0].pressures_bar();
        assert!(pa > 0.0 && pb > 0.0, "{pa} {pb}");
    }
}
