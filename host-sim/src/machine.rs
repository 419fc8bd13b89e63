//! The machine around a controller board, assembled in one place for every board the
//! host runs against the plant (the virtual board, `board-emu`'s emulated STM32F407):
//! the scenario's first axes as the board's slaves, in order (the reference machine's
//! tangent cylinder on slave 0, its side press on slave 1), the master profile, and the
//! sensors the board reads — the master and slave encoders, the chamber pressure
//! transducers.
//!
//! Units: SI inside the plant (m, m/s, Pa); encoder counts as the scenario's encoders
//! quantise them (master 0.001° per count, slaves 1 µm per count on the reference
//! machine); valve command u ∈ [−1, 1] (full opening), 0 while the valve power is off
//! (an unpowered servo valve's spool centres).

use crate::camfile::CamCsv;
use crate::plant::{Encoder, HydraulicAxis, MasterProfile, PressureAdc};
use crate::scenario::{Role, Scenario, ScenarioError};

/// Where a slave starts when neither the scenario (`x0_mm`) nor its table column says, mm.
pub const DEFAULT_X0_MM: f64 = 250.0;

/// One slave: its cylinder and valve, and its sensors.
#[derive(Clone, Debug)]
pub struct BoardSlave {
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

impl BoardSlave {
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
pub struct BoardPlant {
    /// The slaves (at most the board's count; fewer if the scenario has fewer axes — a
    /// board channel with no slave reads count 0 and drives nothing).
    pub slaves: Vec<BoardSlave>,
    /// The master's motion.
    pub master: MasterProfile,
    /// The master encoder.
    pub master_enc: Encoder,
    /// The plant's integration step, s.
    pub step_s: f64,
}

impl BoardPlant {
    /// The scenario's first `board_slaves` axes. A follower that has a column of `table`
    /// (matched by name, as `host-sim run` matches them) keeps it, and starts at its first
    /// value unless the scenario gives `x0_mm`.
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
                let x0_mm = a
                    .x0_mm
                    .or_else(|| column.as_ref().and_then(|c| c.first().copied()))
                    .unwrap_or(DEFAULT_X0_MM);
                BoardSlave {
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
        self.slaves.get(k).map_or(0, BoardSlave::count)
    }
}

/// The valve command of a signed DAC code (0 = mid-scale, ±2047 = full scale) with the
/// valve power on; 0 with it off.
pub fn valve_command(code: i16, enable: bool) -> f64 {
    if enable {
        (f64::from(code) / 2047.0).clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_machine_has_tangent_then_side_press() {
        let scn = Scenario::default();
        let p = BoardPlant::new(&scn, None, 2).expect("plant");
        let names: Vec<_> = p.slaves.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["tangent", "side_press"]);
        // Encoders at 1 µm: the tangent at its default start, the press at x0 = 10 mm.
        assert_eq!(p.slave_count(0), 250_000);
        assert_eq!(p.slave_count(1), 10_000);
        assert_eq!(p.slave_count(2), 0);
        let (pa, pb) = p.slaves[0].pressures_bar();
        assert!(pa > 0.0 && pb > 0.0, "{pa} {pb}");
    }

    #[test]
    fn valve_command_is_zero_unpowered_and_clamped() {
        assert_eq!(valve_command(2047, false), 0.0);
        assert_eq!(valve_command(-2047, true), -1.0);
        assert_eq!(valve_command(i16::MAX, true), 1.0);
        assert!((valve_command(1024, true) - 0.5002).abs() < 1e-3);
    }
}
