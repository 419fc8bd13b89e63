//! The machine around the emulated board: host-sim's hydraulic plant (the scenario's
//! axes, its RK4 step), its master profile and sensors, wired as the board is
//! (`firmware/src/board.rs`): TIM5 ← master encoder (its rising A edges timestamped by
//! TIM8 at 1 MHz whatever the scenario's `master.edge_timer_hz`: the board's hardware),
//! TIM2/TIM3 ← slave encoders,
//! DAC1 ch1/ch2 → the slaves' valves (u = (code − 2048)/2047, zero while PE7 is low: an
//! unpowered valve centres), IN11/IN12 ← slave 0's chamber pressures A/B, IN8/IN9 ←
//! slave 1's, PE8 ← the E-stop chain.
//!
//! The plant advances on its own step grid to whatever time the board looks at
//! (lazily, at every peripheral access and every scheduler stop). The following error is
//! measured as `host-sim run` measures it: the table at the true master angle minus the
//! true position, every millisecond of master time after `sim.error_skip_s`.

use crate::bus::{Environment, Inputs, Outputs, SYSCLK_HZ};
use hydra_plant::camfile::{interpolate, CamCsv};
use hydra_plant::hydraulics::edges::newest_rising_a;
use hydra_plant::hydraulics::valve_command;
use hydra_plant::machine::{MachineAxis, MachinePlant};
use hydra_plant::scenario::Scenario;
use hydra_plant::stats::ErrorStat;
use std::cell::RefCell;
use std::rc::Rc;

/// What the test or the CLI reads and drives while the board runs.
#[derive(Debug, Clone)]
pub struct Shared {
    /// The E-stop chain closed.
    pub estop_closed: bool,
    /// Core cycle at which the master starts moving (set when the host sends Start).
    pub master_start: Option<u64>,
    /// Per-slave error statistics (followers only).
    pub errors: Vec<ErrorStat>,
    /// Trace rows every millisecond: t_s, master_deg, then per slave target_mm, x_mm,
    /// u, enable.
    pub trace: Vec<Vec<f64>>,
    /// Record the trace.
    pub record: bool,
    /// The latest outputs.
    pub outputs: Outputs,
    /// The slaves' true positions, µm.
    pub positions_um: Vec<f64>,
}

/// The plant environment.
pub struct PlantEnv {
    plant: MachinePlant,
    table_master: Vec<f64>,
    step_cycles: u64,
    error_skip_s: f64,
    /// Cycles at the plant's time.
    t: u64,
    steps: u64,
    metric_every: u64,
    hints: Vec<usize>,
    /// Core cycle up to which the master's edges have been looked for, and the newest
    /// rising edge of channel A found (its cycle, the count after it).
    edge_scan: u64,
    newest_edge: Option<(u64, i64)>,
    /// Shared state.
    pub shared: Rc<RefCell<Shared>>,
}

impl PlantEnv {
    /// The scenario's axes (at most two: the board's slaves) following `table`.
    pub fn new(scn: &Scenario, table: &CamCsv) -> anyhow::Result<Self> {
        let step_s = scn.step_s();
        // The machine as host-sim assembles it for a board (slave k = scenario axis k).
        let plant = MachinePlant::new(scn, Some(table), 2)?;
        let n = plant.slaves.len();
        let step_cycles = (step_s * SYSCLK_HZ as f64).round() as u64;
        Ok(Self {
            plant,
            table_master: table.master.clone(),
            step_cycles: step_cycles.max(1),
            error_skip_s: scn.sim.error_skip_s,
            t: 0,
            steps: 0,
            metric_every: ((1e-3 / step_s).round() as u64).max(1),
            hints: vec![0; n],
            edge_scan: 0,
            newest_edge: None,
            shared: Rc::new(RefCell::new(Shared {
                estop_closed: true,
                master_start: None,
                errors: vec![ErrorStat::default(); n],
                trace: Vec::new(),
                record: false,
                outputs: Outputs::default(),
                positions_um: vec![0.0; n],
            })),
        })
    }

    /// The slaves.
    pub fn slaves(&self) -> &[MachineAxis] {
        &self.plant.slaves
    }

    /// Slave `k`'s table column (mm), if it follows the table.
    pub fn column(&self, k: usize) -> Option<&[f64]> {
        self.plant.slaves.get(k).and_then(|s| s.column.as_deref())
    }

    /// Slave `k`'s true position, µm.
    pub fn position_um(&self, k: usize) -> Option<f64> {
        self.plant.slaves.get(k).map(|s| s.plant.x_m() * 1e6)
    }

    /// The newest rising edge of the master encoder's channel A up to core cycle `now`
    /// (host-sim's sensor model, `hydra_plant::hydraulics::edges`).
    fn scan_edges(&mut self, now: u64) {
        let Some(start) = self.shared.borrow().master_start else {
            self.edge_scan = now;
            return;
        };
        let from = self.edge_scan.max(start);
        self.edge_scan = now;
        if now <= from {
            return;
        }
        let (profile, res) = (&self.plant.master, self.plant.master_enc.resolution);
        let pos = |cyc: f64| profile.angle_deg((cyc - start as f64) / SYSCLK_HZ as f64) / res;
        if let Some((t, c)) = newest_rising_a(pos, from as f64, now as f64) {
            self.newest_edge = Some(((t.ceil() as u64).min(now), c));
        }
    }

    fn master_s(&self, at: u64) -> f64 {
        let start = self.shared.borrow().master_start;
        start.map_or(0.0, |s| at.saturating_sub(s) as f64 / SYSCLK_HZ as f64)
    }
}

impl Environment for PlantEnv {
    fn advance(&mut self, now: u64, out: &Outputs) -> Inputs {
        // The DAC's unipolar register value → signed code (2048 = null).
        let u: Vec<f64> = (0..self.plant.slaves.len())
            .map(|k| match out.dac.get(k).copied().flatten() {
                Some(code) => valve_command((i32::from(code) - 2048) as i16, out.enable),
                None => 0.0,
            })
            .collect();
        while self.t + self.step_cycles <= now {
            self.plant.step(&u);
            self.t += self.step_cycles;
            self.steps += 1;
            if self.steps.is_multiple_of(self.metric_every) {
                let tm = self.master_s(self.t);
                let started = self.shared.borrow().master_start.is_some();
                let theta = self.plant.master.angle_deg(tm);
                let mut sh = self.shared.borrow_mut();
                let mut row = vec![self.t as f64 / SYSCLK_HZ as f64, theta];
                for (k, s) in self.plant.slaves.iter().enumerate() {
                    let x_mm = s.plant.x_m() * 1e3;
                    let target = s
                        .column
                        .as_ref()
                        .map(|c| interpolate(&self.table_master, c, theta, &mut self.hints[k]));
                    if let (Some(tg), true) = (target, started && tm >= self.error_skip_s) {
                        sh.errors[k].add((tg - x_mm) * 1e3);
                    }
                    row.extend_from_slice(&[
                        target.unwrap_or(f64::NAN),
                        x_mm,
                        u[k],
                        f64::from(u8::from(out.enable)),
                    ]);
                }
                if sh.record {
                    sh.trace.push(row);
                }
            }
        }
        let tm = self.master_s(now);
        self.scan_edges(now);
        let mut sh = self.shared.borrow_mut();
        sh.outputs = *out;
        let mut inp = Inputs {
            master: self.plant.master_count(tm),
            master_edge: self.newest_edge,
            estop_closed: sh.estop_closed,
            ..Inputs::default()
        };
        for (k, s) in self.plant.slaves.iter().enumerate() {
            sh.positions_um[k] = s.plant.x_m() * 1e6;
            inp.slaves[k] = s.count();
            let (pa, pb) = s.plant.pressures_pa();
            inp.pressures[2 * k] = s.adc.code(pa) as u16;
            inp.pressures[2 * k + 1] = s.adc.code(pb) as u16;
        }
        inp
    }
}
