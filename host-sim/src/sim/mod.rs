//! The closed loop: the core's controllers against the plant, period by period.
//!
//! Timing of one control period k (`t_k = k·T`):
//!
//! 1. **Sample** at `t_k`: the master angle through its encoder (`round(θ/0.001°)`
//!    counts) and, with the board's edge timer (`master.edge_timer_hz`, default 1 MHz),
//!    the newest rising A edge since `t_{k−1}` with its time (`crate::plant::edges`: the
//!    runtime then feeds the law the master below one count), every axis' position
//!    through its linear encoder and its two chamber pressures through the 12-bit ADC.
//! 2. **Compute**: one [`hydra_core::runtime::TickLoop::run`] per period, the firmware's
//!    tick ([`board`]: Start at the first period; the scenario's `[events]` drive the
//!    E-stop, encoder and pressure inputs; the fault rules live: a latched fault
//!    unpowers every valve, `u` = 0 from the next period, and is reported in
//!    [`RunReport::faults`]). Its law is the follower for the table axes and the press
//!    law for the force axes (`hydra_core::runtime::PressAxes`): valve codes out.
//! 3. **Apply** one period later: the codes computed at `t_k` drive the valves from
//!    `t_{k+1}` to `t_{k+2}` (one period of computation delay); during period 0 the valves
//!    are at null. The DAC holds each code: `u = n/2047`.
//! 4. **Integrate** the plant over the period by RK4 steps of `h` (`T/h` steps).
//!
//! **Metrics** are taken every 100 µs of simulated time (every step if `h` > 100 µs):
//!
//! * follower axis: `e(t) = X(θ(t)) − x(t)`, the table (linear interpolation of its nodes)
//!   at the *true* master angle minus the true position, after `sim.error_skip_s`; max |e|
//!   and RMS in µm;
//! * force axis: `e_F(t) = F_ref − F(t)` while force control is active and the runtime powers the valves, `F_ref` the press
//!   law's (ramped) reference from its last tick and `F = A_A·p_A − A_B·p_B` from the true
//!   pressures; max |e_F| and RMS in N, the time of the switch and the jump of the command
//!   across it;
//! * every axis: the peak |u| of the applied valve command over the whole run (1 = full
//!   opening).
//!
//! Trace columns (`--csv`): `t_s`, `master_deg` (true), `master_estimate_deg` (the
//! follower's filtered estimate at its last sample), per follower `<axis>_target_mm`
//! (table at the true master), `_x_mm`, `_error_um`, `_u` (applied valve command),
//! `_controller_target_mm` (the follower's X(θ_f(k))), `_backoff_level` (the gain
//! backoff's level, core `axis::backoff`; 0 = the set gain); per force axis `_x_mm`, `_force_n`,
//! `_force_ref_n`, `_u`.

pub use hydra_plant::board;
pub use hydra_plant::stats::ErrorStat;
pub mod control;
pub mod probe;

use crate::camfile::{interpolate, CamCsv};
use crate::plant::{valve_command, HydraulicAxis, MasterProfile, PressureAdc};
use crate::scenario::{Controller, Role, Scenario, ScenarioError};
use control::{build_follower, Reading};
use hydra_core::axis::PressPhase;
use hydra_core::units::{DacCode, PosUm, PressureBar};
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSpec {
    /// The follower law.
    pub controller: Controller,
    /// Control period, µs.
    pub period_us: u32,
    /// Record a trace every this many seconds (rounded to whole RK4 steps); `None`: no trace.
    pub trace_every_s: Option<f64>,
}

/// Results of one axis.
#[derive(Clone, Debug, PartialEq)]
pub enum AxisResult {
    /// A table-following axis.
    Follower {
        /// Largest |X(θ) − x| after the skip time, µm.
        max_error_um: f64,
        /// RMS of X(θ) − x after the skip time, µm.
        rms_error_um: f64,
    },
    /// A force axis.
    Force {
        /// Largest |F_ref − F| under force control, N.
        max_force_error_n: f64,
        /// RMS of F_ref − F under force control, N.
        rms_force_error_n: f64,
        /// When force control took over, s (None: never).
        switch_s: Option<f64>,
        /// |u(k) − u(k−1)| of the command before the output stage at the switch, DAC LSB.
        switch_jump_lsb: f64,
        /// Force at the end of the run, N.
        final_force_n: f64,
    },
}

/// One axis' report.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisReport {
    /// Axis name.
    pub name: String,
    /// Largest |u| applied over the run (1 = full opening).
    pub peak_command: f64,
    /// The axis' metrics.
    pub result: AxisResult,
}

/// A recorded trace: column names and rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Column names (`t_s`, `master_deg`, then per axis).
    pub columns: Vec<String>,
    /// Row-major values.
    pub data: Vec<f64>,
}

impl Trace {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.data.len() / self.columns.len().max(1)
    }

    /// The values of a column.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let n = self.columns.len();
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.data.chunks_exact(n).map(|r| r[i]).collect())
    }

    /// The CSV text.
    pub fn to_csv(&self) -> String {
        let Ok(mut o) = crate::csvout::CsvOut::new(Vec::new(), &self.columns) else {
            return String::new();
        };
        for r in self.data.chunks_exact(self.columns.len().max(1)) {
            if o.row(r.iter().map(|v| format!("{v:.6}"))).is_err() {
                return String::new();
            }
        }
        o.text()
    }
}

/// The report of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// Scenario name.
    pub scenario: String,
    /// The follower law.
    pub controller: Controller,
    /// Control period, µs.
    pub period_us: u32,
    /// The gain set's period, µs (≠ `period_us` when no set was tuned at this period).
    pub tuned_period_us: u32,
    /// Faults the runtime latched, in order (a run without faults: empty).
    pub faults: Vec<FaultEvent>,
    /// After the first fault: the start of the first period in which every valve's
    /// applied command is 0, s (the fault's tick unpowers the valves; its code acts one
    /// period of computation delay later at most).
    pub valves_null_s: Option<f64>,
    /// Per follower axis: velocity reversals against the table's own.
    pub oscillation: Vec<Oscillation>,
    /// Per follower axis: the gain backoff's level at the end of the run (core
    /// `axis::backoff`; 0 = the set gain throughout).
    pub backoff_levels: Vec<u8>,
    /// Simulated time, s.
    pub sim_seconds: f64,
    /// Wall-clock time of the simulation, s.
    pub wall_seconds: f64,
    /// RK4 steps taken (per axis).
    pub steps: u64,
    /// Per-axis results, in scenario order.
    pub axes: Vec<AxisReport>,
    /// The trace, if asked for.
    pub trace: Option<Trace>,
    /// Errors are measured from this time on, s (`sim.error_skip_s`).
    pub error_skip_s: f64,
    /// With a valve probe ([`run_probed`]): the loop's response L at its frequency.
    pub loop_response: Option<nalgebra::Complex<f64>>,
}

impl RunReport {
    /// The worst of the follower axes: the largest max |error| (µm), the largest RMS
    /// error (µm) and the largest valve command (1 = full opening); zeros without one.
    pub fn followers_worst(&self) -> (f64, f64, f64) {
        let (mut max_um, mut rms_um, mut peak) = (0.0f64, 0.0f64, 0.0f64);
        for a in &self.axes {
            if let AxisResult::Follower {
                max_error_um,
                rms_error_um,
            } = a.result
            {
                max_um = max_um.max(max_error_um);
                rms_um = rms_um.max(rms_error_um);
                peak = peak.max(a.peak_command);
            }
        }
        (max_um, rms_um, peak)
    }

    /// The report of an axis by name.
    pub fn axis(&self, name: &str) -> Option<&AxisReport> {
        self.axes.iter().find(|a| a.name == name)
    }
}

/// Per force axis bookkeeping (its law runs inside the runtime).
#[derive(Clone, Debug)]
struct PressRt {
    f_ref_n: f64,
    phase: PressPhase,
    switch_s: Option<f64>,
    jump_lsb: f64,
    last_cmd: f64,
    stat: ErrorStat,
}

/// Runs one scenario with one controller and period. `progress` is called with the
/// simulated time about every 1 % of the run.
pub fn run(
    s: &Scenario,
    table: &CamCsv,
    spec: &RunSpec,
    progress: &mut dyn FnMut(f64),
) -> Result<RunReport, ScenarioError> {
    run_probed(s, table, spec, None, progress)
}

/// [`run`] with a sinusoidal probe added to one follower's valve command
/// ([`probe`]); the report's `loop_response` is the loop's L at the probe's frequency.
pub fn run_probed(
    s: &Scenario,
    table: &CamCsv,
    spec: &RunSpec,
    probe: Option<&probe::Probe>,
    progress: &mut dyn FnMut(f64),
) -> Result<RunReport, ScenarioError> {
    let wall = Instant::now();
    let (tuning, _) = crate::scenario::gains::select(s, spec.controller, spec.period_us)
        .ok_or_else(|| ScenarioError::Invalid {
            key: "tuning".into(),
            value: spec.controller.name().into(),
            reason: "the scenario has no [[tuning]] set for this controller".into(),
        })?;
    let mut sc = s.clone();
    sc.sim.period_us = spec.period_us;
    sc.validate_timing()?;
    let master: MasterProfile = sc.master_profile()?;
    let menc = sc.master_encoder();
    let edge_timer = sc.master_edge_timer();
    let h = sc.step_s();
    let steps_per_period = u64::from(sc.steps_per_period());
    let period_s = sc.period_s();
    let duration = sc.duration_s()?;
    let n_periods = (duration / period_s).ceil() as u64;
    let metric_steps = ((100e-6 / h).round() as u64).max(1);
    let trace_steps = spec.trace_every_s.map(|d| ((d / h).round() as u64).max(1));

    let follower_cfgs = control::followers(&sc);
    let columns: Vec<&[f64]> = follower_cfgs
        .iter()
        .map(|a| table.column(&a.name).unwrap_or(&[]))
        .collect();
    let mut follower = build_follower(&sc, table, tuning, spec.controller, spec.period_us)?;

    // Plants and sensors, in scenario order (crate::machine: followers start on the table
    // at the master's start).
    let machine = crate::machine::MachinePlant::new(&sc, Some(table), sc.axes.len())?;
    let mut plants: Vec<HydraulicAxis> = machine.slaves.iter().map(|m| m.plant.clone()).collect();
    let encoders: Vec<_> = machine.slaves.iter().map(|m| m.enc).collect();
    let adcs: Vec<_> = machine.slaves.iter().map(|m| m.adc).collect();
    let mut follower_idx = Vec::new();
    let mut press_idx = Vec::new();
    let mut presses: Vec<PressRt> = Vec::new();
    for (i, a) in sc.axes.iter().enumerate() {
        match a.role {
            Role::Follower => follower_idx.push(i),
            Role::Force => {
                press_idx.push(i);
                presses.push(PressRt {
                    f_ref_n: 0.0,
                    phase: PressPhase::Approach,
                    switch_s: None,
                    jump_lsb: 0.0,
                    last_cmd: 0.0,
                    stat: ErrorStat::default(),
                });
            }
        }
    }
    let n_axes = plants.len();
    let nf = follower_idx.len();

    let mut trace = trace_steps.map(|_| {
        let mut cols = vec![
            "t_s".to_string(),
            "master_deg".to_string(),
            "master_estimate_deg".to_string(),
        ];
        for a in &sc.axes {
            match a.role {
                Role::Follower => {
                    for c in [
                        "target_mm",
                        "x_mm",
                        "error_um",
                        "u",
                        "controller_target_mm",
                        "backoff_level",
                        "ff_trim_neg",
                        "ff_trim_pos",
                    ] {
                        cols.push(format!("{}_{c}", a.name));
                    }
                }
                Role::Force => {
                    for c in ["x_mm", "force_n", "force_ref_n", "u"] {
                        cols.push(format!("{}_{c}", a.name));
                    }
                }
            }
        }
        Trace {
            columns: cols,
            data: Vec::new(),
        }
    });

    let mut u_now = vec![0.0f64; n_axes]; // applied this period
    let mut u_next = vec![0.0f64; n_axes]; // computed at this period's sample
                                           // Per runtime slave (scenario axis).
    let mut enc = vec![0i64; n_axes];
    let mut chambers = vec![[PressureBar::ZERO; 2]; n_axes];
    let mut dac = vec![DacCode::NULL; n_axes];
    let mut ctrl_target = vec![PosUm::ZERO; n_axes];
    let mut faults: Vec<FaultEvent> = Vec::new();
    let mut valves_null_s = None;
    let mut start_refused = None;
    let mut osc: Vec<Reversals> = vec![Reversals::default(); n_axes];
    let mut master_est_deg = 0.0;
    // The runtime powers the valves this period (a force axis' error counts only then).
    let mut controlling = false;
    let mut err_stats = vec![ErrorStat::default(); nf];
    let mut peak = vec![0.0f64; n_axes];
    let mut cursors = vec![0usize; nf];
    let mut step: u64 = 0;
    let mut bins = probe::ProbeBins::default();
    let progress_every = (n_periods / 100).max(1);

    let varying = Varying::new(&sc, &plants);
    for k in 0..n_periods {
        let t_k = k as f64 * period_s;
        varying.apply(t_k, &mut plants);
        // 1–2. sample and compute
        if let Some(f) = follower.as_mut() {
            let m = menc.count(master.angle_deg(t_k));
            let edges = edge_timer.map(|tm| {
                let counts = |t: f64| master.angle_deg(t) / menc.resolution;
                tm.reading(counts, t_k - period_s, t_k)
            });
            for (i, a) in sc.axes.iter().enumerate() {
                let true_count = encoders[i].count(plants[i].x_m());
                enc[i] = sc.events.encoder_count(&a.name, t_k, true_count, enc[i]);
                osc[i].add(plants[i].v_m_per_s());
                chambers[i] = adc_bar(&adcs[i], plants[i].pressures_pa());
            }
            let reading = Reading {
                master: m,
                master_edges: edges,
                slaves: &enc,
                pressures: &chambers,
                estop: sc.events.estop(t_k),
                pressure_live: sc.events.pressure_live(t_k),
            };
            let o = f.tick(&reading, &mut dac, &mut ctrl_target);
            master_est_deg = o.master_estimate.to_num::<f64>() * sc.master.resolution_deg;
            controlling = o.enable;
            for (u, d) in u_next.iter_mut().zip(&dac) {
                // Not controlling: the valves are unpowered and their spools centre.
                *u = valve_command(d.get(), o.enable);
            }
            for (p, &i) in presses.iter_mut().zip(&press_idx) {
                let Some(o) = f.press(i) else { continue };
                let c = o.cmd_lsb.to_num::<f64>();
                if o.phase == PressPhase::Force && p.phase == PressPhase::Approach {
                    p.switch_s = Some(t_k);
                    p.jump_lsb = (c - p.last_cmd).abs();
                }
                p.phase = o.phase;
                p.f_ref_n = o.force_ref_n.to_num::<f64>();
                p.last_cmd = c;
            }
            if let Some(p) = probe.filter(|_| o.enable) {
                if let Some(&i) = follower_idx.get(p.follower) {
                    let u_ctrl = u_next[i];
                    u_next[i] = (u_ctrl + p.disturbance(t_k)).clamp(-1.0, 1.0);
                    bins.add(p, t_k, u_ctrl, u_next[i]);
                }
            }
            if start_refused.is_none() {
                start_refused = o.start_refused;
            }
            if let Some(r) = o.fault {
                if faults.last().map(|l| (l.code, l.tick)) != Some((r.fault.code(), r.tick)) {
                    let axis = r.fault.slave();
                    faults.push(FaultEvent {
                        code: r.fault.code(),
                        name: r.fault.name(),
                        axis: axis
                            .and_then(|a| sc.axes.get(usize::from(a)))
                            .map(|a| a.name.clone()),
                        tick: r.tick,
                        t_s: t_k,
                        value: match r.fault {
                            hydra_core::runtime::Fault::FollowingError { axis } => {
                                Some(f.error_um(usize::from(axis)))
                            }
                            _ => None,
                        },
                    });
                }
            }
        }
        // 3–4. integrate the period with the codes computed one period ago
        if valves_null_s.is_none() && !faults.is_empty() && u_now.iter().all(|&u| u == 0.0) {
            valves_null_s = Some(t_k);
        }
        for (pk, u) in peak.iter_mut().zip(&u_now) {
            *pk = pk.max(u.abs());
        }
        for _ in 0..steps_per_period {
            for (p, &u) in plants.iter_mut().zip(&u_now) {
                p.step(u, h);
            }
            step += 1;
            let metric = step.is_multiple_of(metric_steps);
            let record = trace_steps.is_some_and(|n| step.is_multiple_of(n));
            if !(metric || record) {
                continue;
            }
            let t = step as f64 * h;
            let theta = master.angle_deg(t);
            let mut row: Option<&mut Vec<f64>> = None;
            if record {
                if let Some(tr) = trace.as_mut() {
                    tr.data.extend_from_slice(&[t, theta, master_est_deg]);
                    row = Some(&mut tr.data);
                }
            }
            let mut fj = 0;
            let mut pj = 0;
            for (i, a) in sc.axes.iter().enumerate() {
                match a.role {
                    Role::Follower => {
                        let target_mm =
                            interpolate(&table.master, columns[fj], theta, &mut cursors[fj]);
                        let e_um = (target_mm - plants[i].x_m() * 1e3) * 1e3;
                        if metric && t >= sc.sim.error_skip_s {
                            err_stats[fj].add(e_um);
                        }
                        if let Some(r) = row.as_deref_mut() {
                            r.extend_from_slice(&[
                                target_mm,
                                plants[i].x_m() * 1e3,
                                e_um,
                                u_now[i],
                                ctrl_target[i].to_num::<f64>() * 1e-3,
                                follower
                                    .as_ref()
                                    .map_or(0.0, |f| f64::from(f.backoff_level(i))),
                            ]);
                            r.extend(follower.as_ref().map_or([1.0; 2], |f| f.ff_trim(i)));
                        }
                        fj += 1;
                    }
                    Role::Force => {
                        let p = &mut presses[pj];
                        let f = plants[i].force_n();
                        if metric && controlling && p.phase == PressPhase::Force {
                            p.stat.add(p.f_ref_n - f);
                        }
                        if let Some(r) = row.as_deref_mut() {
                            r.extend_from_slice(&[plants[i].x_m() * 1e3, f, p.f_ref_n, u_now[i]]);
                        }
                        pj += 1;
                    }
                }
            }
        }
        std::mem::swap(&mut u_now, &mut u_next);
        if k.is_multiple_of(progress_every) {
            progress(t_k);
        }
    }
    progress(n_periods as f64 * period_s);

    let mut fj = 0;
    let mut pj = 0;
    let axes = sc
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let result = match a.role {
                Role::Follower => {
                    let st = err_stats[fj];
                    fj += 1;
                    AxisResult::Follower {
                        max_error_um: st.max,
                        rms_error_um: st.rms(),
                    }
                }
                Role::Force => {
                    let p = &presses[pj];
                    pj += 1;
                    AxisResult::Force {
                        max_force_error_n: p.stat.max,
                        rms_force_error_n: p.stat.rms(),
                        switch_s: p.switch_s,
                        switch_jump_lsb: p.jump_lsb,
                        final_force_n: plants[i].force_n(),
                    }
                }
            };
            AxisReport {
                name: a.name.clone(),
                peak_command: peak[i],
                result,
            }
        })
        .collect();
    if let Some(e) = start_refused {
        return Err(ScenarioError::Invalid {
            key: "runtime".into(),
            value: format!("{e:?}"),
            reason: "the runtime refused Start".into(),
        });
    }
    let oscillation = follower_cfgs
        .iter()
        .zip(follower_idx.iter().map(|&i| &osc[i]))
        .zip(&columns)
        .map(|((a, r), col)| Oscillation {
            axis: a.name.clone(),
            reversals: r.count,
            table_reversals: table_reversals(
                &table.master,
                col,
                sc.master.start_deg,
                sc.master.end_deg,
            ),
        })
        .collect();
    let backoff_levels = follower_idx
        .iter()
        .map(|&i| follower.as_ref().map_or(0, |f| f.backoff_level(i)))
        .collect();
    Ok(RunReport {
        scenario: s.name().to_string(),
        controller: spec.controller,
        period_us: spec.period_us,
        tuned_period_us: tuning.period_us,
        sim_seconds: n_periods as f64 * period_s,
        wall_seconds: wall.elapsed().as_secs_f64(),
        steps: step,
        axes,
        trace,
        faults,
        valves_null_s,
        oscillation,
        backoff_levels,
        error_skip_s: sc.sim.error_skip_s,
        loop_response: probe.and_then(|_| bins.loop_response()),
    })
}

/// A fault the runtime latched during a run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FaultEvent {
    /// Its code (`hydra_core::runtime::Fault::code`).
    pub code: u16,
    /// Its name (`following_error`, …).
    pub name: &'static str,
    /// The axis it names (a follower or a force axis), if any.
    pub axis: Option<String>,
    /// The runtime's tick counter when it latched.
    pub tick: u32,
    /// Simulated time of that tick, s.
    pub t_s: f64,
    /// The value that tripped it (following error: |target − position| in µm).
    pub value: Option<f64>,
}

/// Velocity reversals of one follower axis against the table's own.
#[derive(Clone, Debug, PartialEq)]
pub struct Oscillation {
    /// Axis name.
    pub axis: String,
    /// Reversals of the axis' true velocity, sampled every period with a ±1 mm/s
    /// hysteresis.
    pub reversals: u32,
    /// Sign changes of the table's slope over the master's travel.
    pub table_reversals: u32,
}

impl Oscillation {
    /// Reversals beyond the table's own (0 for a run that follows its table).
    pub fn excess(&self) -> u32 {
        self.reversals.saturating_sub(self.table_reversals)
    }
}

/// Counts velocity reversals with a hysteresis of [`Reversals::BAND_M_PER_S`].
#[derive(Clone, Copy, Debug, Default)]
struct Reversals {
    sign: i8,
    count: u32,
}

impl Reversals {
    /// ±1 mm/s: slower is standing still, not a direction.
    const BAND_M_PER_S: f64 = 1e-3;

    fn add(&mut self, v: f64) {
        let s = if v > Self::BAND_M_PER_S {
            1
        } else if v < -Self::BAND_M_PER_S {
            -1
        } else {
            return;
        };
        if self.sign != 0 && s != self.sign {
            self.count += 1;
        }
        self.sign = s;
    }
}

/// The two chamber pressures (Pa) as the controller reads them through the ADC, bar.
fn adc_bar(adc: &PressureAdc, (pa, pb): (f64, f64)) -> [PressureBar; 2] {
    [pa, pb].map(|p| PressureBar::saturating_from_num(adc.read_pa(p) * 1e-5))
}

/// Sign changes of a table column's slope between master `a` and `b` (degrees).
fn table_reversals(master: &[f64], col: &[f64], a: f64, b: f64) -> u32 {
    let (lo, hi) = (a.min(b), a.max(b));
    let mut sign = 0i8;
    let mut n = 0;
    for k in 1..master.len().min(col.len()) {
        if master[k] < lo || master[k - 1] > hi {
            continue;
        }
        let d = col[k] - col[k - 1];
        let s = if d > 0.0 {
            1
        } else if d < 0.0 {
            -1
        } else {
            continue;
        };
        if sign != 0 && s != sign {
            n += 1;
        }
        sign = s;
    }
    n
}

/// The scenario's load profiles and drifts (`crate::scenario::varying`), applied to the
/// plants at each period (the controller is not told).
struct Varying {
    axes: Vec<VaryingAxis>,
    /// The supply's drift, its nominal pressure (bar) and the chambers' clamp factor.
    supply: Option<(crate::scenario::varying::SupplyDrift, f64, f64)>,
}

/// One plant's load profile, drift and nominal (load N, valve kv, bulk modulus Pa).
type VaryingAxis = (
    Option<crate::scenario::varying::LoadProfile>,
    Option<crate::scenario::varying::AxisDrift>,
    (f64, f64, f64),
);

impl Varying {
    fn new(sc: &Scenario, plants: &[HydraulicAxis]) -> Self {
        Self {
            axes: sc
                .axes
                .iter()
                .zip(plants)
                .map(|(a, p)| {
                    (
                        a.load.clone(),
                        a.drift,
                        (p.cylinder.load_n, p.valve.kv, p.cylinder.bulk_modulus_pa),
                    )
                })
                .collect(),
            supply: sc
                .supply
                .drift
                .map(|d| (d, sc.supply.supply_bar, sc.supply.clamp_factor)),
        }
    }

    fn apply(&self, t: f64, plants: &mut [HydraulicAxis]) {
        for ((load, drift, (load0, kv0, beta0)), p) in self.axes.iter().zip(plants.iter_mut()) {
            if let Some(l) = load {
                p.cylinder.load_n = load0 + l.at(t);
            }
            if let Some(d) = drift {
                let (flow, bulk) = d.at(t);
                p.valve.kv = kv0 * flow;
                p.cylinder.bulk_modulus_pa = beta0 * bulk;
            }
            if let Some((d, from, clamp)) = &self.supply {
                // The chambers' clamp follows the supply, as `Scenario::supply` builds it.
                p.supply.supply_pa = d.at(t, *from) * 1e5;
                p.supply.max_pa = clamp * p.supply.supply_pa;
            }
        }
    }
}
