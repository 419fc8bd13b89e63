//! The controllers of a run, built from the scenario, inside the core's [`Runtime`] run
//! by the firmware's tick, [`TickLoop::run`], over a [`SampledBoard`]: the core's
//! [`Follower`] for the table-following axes and the press law for the force axes, one
//! law ([`PressAxes`]) over every axis of the scenario — so the fault rules (E-stop,
//! following error, encoder plausibility, master stall, pressure health) are live on
//! every axis and a latched fault puts every valve at null.
//!
//! The law is generic over the number of slave axes `S`; the simulator supports 1 to
//! [`MAX_AXES`] axes through one monomorphisation each, behind the object-safe
//! [`FollowerDyn`]. Runtime slave `i` is the scenario's axis `i`. Tables hold up to
//! [`TABLE_CAPACITY`] nodes.

use super::board::{SampledBoard, SimHost, CYCLES_PER_US};
use crate::camfile::CamCsv;
use crate::scenario::gains::{follower_config, press_config};
use crate::scenario::{AxisCfg, Controller, Role, Scenario, ScenarioError, Tuning};
use hydra_core::axis::{PressCoeffs, PressOutput};
use hydra_core::follower::{Follower, FollowerError};
use hydra_core::master::EdgeReading;
use hydra_core::runtime::{
    BootCause, Command, CommandError, EncoderSample, FaultRecord, PressAxes, Runtime,
    RuntimeConfig, State, TickLoop, MAX_STEP_LIMIT_COUNTS,
};
use hydra_core::table::{AxisLimits, CamTable, Node, TableError, TableLimits};
use hydra_core::units::{Counts, DacCode, Master, MasterRate, PosUm, PressureBar, VelUmPerS};

/// Largest number of nodes of a simulated table.
pub const TABLE_CAPACITY: usize = 4096;
/// Largest number of axes (followers and force axes) of a scenario.
pub const MAX_AXES: usize = 4;
/// The runtime's pressure inputs: chambers A and B of each of up to [`MAX_AXES`] axes
/// (slave k on inputs 2k, 2k + 1, as on the board).
const PRESSURES: usize = 2 * MAX_AXES;
/// The inner follower's own following-error limit on a force axis, µm (its largest): the
/// follower's output there is discarded, and its latched fault would null the axis'
/// manual moves. The runtime's limit (the gain set's) still applies.
const PRESS_INNER_FE_LIMIT_UM: f32 = 1e6;

/// What one runtime tick gives the simulator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FollowerTick {
    /// The follower's filtered master estimate, master counts.
    pub master_estimate: Master,
    /// Valves powered (Following / Holding): otherwise the spools are centred.
    pub enable: bool,
    /// The runtime's state after the tick.
    pub state: State,
    /// The latched fault, if any.
    pub fault: Option<FaultRecord>,
    /// Start was refused at the first tick (the run then never controls).
    pub start_refused: Option<CommandError>,
}

/// What the board's inputs read at one period's sample instant.
#[derive(Clone, Copy, Debug)]
pub struct Reading<'a> {
    /// The master encoder count.
    pub master: i64,
    /// The master's edge timer, if the board has one.
    pub master_edges: Option<EdgeReading>,
    /// Each axis' encoder count.
    pub slaves: &'a [i64],
    /// Each axis' chamber A and B pressure, bar.
    pub pressures: &'a [[PressureBar; 2]],
    /// The E-stop chain is open.
    pub estop: bool,
    /// The pressure inputs are updating.
    pub pressure_live: bool,
}

/// The law of a run inside the runtime, whatever the number of axes.
pub trait FollowerDyn: Send {
    /// One control period, one [`TickLoop::run`] (the firmware's tick) over the board
    /// inputs `r`: valve codes (the nulls unless controlling) and the targets X(θ_f(k))
    /// (µm) out. The first tick starts the runtime (Start).
    fn tick(&mut self, r: &Reading, dac: &mut [DacCode], target: &mut [PosUm]) -> FollowerTick;

    /// |target − position| of axis `j` at the last tick, µm (the value a
    /// following-error fault trips on).
    fn error_um(&self, j: usize) -> f64;

    /// The gain backoff's level of axis `j` (core `axis::backoff`; 0 = the set gain).
    fn backoff_level(&self, j: usize) -> u8;

    /// The feed-forward trim's ratios of axis `j`, `[negative, positive]` feed-forward
    /// (core `axis::ff_trim`; 1 = the calibrated gain).
    fn ff_trim(&self, j: usize) -> [f64; 2];

    /// Force axis `j`'s press output of the last tick (`None`: not a force axis).
    fn press(&self, j: usize) -> Option<PressOutput>;
}

type Law<const S: usize> = Box<PressAxes<Follower<S, TABLE_CAPACITY>, S>>;

struct Rt<const S: usize> {
    tl: TickLoop<Law<S>, S, PRESSURES>,
    io: SampledBoard<S, PRESSURES>,
    host: SimHost,
    period_ns: u32,
    started: bool,
    /// |target − position| per slave at the last tick (the law's, also on the tick a
    /// fault latched), µm.
    error_um: [f64; S],
}

fn counts(c: i64) -> Counts {
    Counts(c.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
}

impl<const S: usize> FollowerDyn for Rt<S> {
    fn tick(&mut self, r: &Reading, dac: &mut [DacCode], target: &mut [PosUm]) -> FollowerTick {
        for (o, p) in self.io.pressure_bar.chunks_exact_mut(2).zip(r.pressures) {
            o.copy_from_slice(p);
        }
        self.io.enc.master = counts(r.master);
        self.io.enc.master_edges = r.master_edges;
        for (o, &c) in self.io.enc.slaves.iter_mut().zip(r.slaves) {
            *o = counts(c);
        }
        self.io.estop = r.estop;
        self.io.pressure_live = r.pressure_live;
        if !self.started {
            self.host.queue(Command::Start);
            self.started = true;
        }
        self.tl.run(&mut self.io, &mut self.host);
        self.host.now_ns = self.host.now_ns.wrapping_add(self.period_ns);
        dac.copy_from_slice(&self.io.codes);
        let rt = self.tl.runtime();
        let st = rt.status();
        for (e, s) in self.error_um.iter_mut().zip(st.error_um) {
            *e = s.to_num::<f64>().abs();
        }
        target.copy_from_slice(&st.target_um);
        FollowerTick {
            master_estimate: rt
                .law()
                .map_or(Master::ZERO, |l| l.law().master_estimate().pos),
            enable: self.io.enable,
            state: st.state,
            fault: st.fault,
            start_refused: self.host.take_refusal().flatten(),
        }
    }

    fn error_um(&self, j: usize) -> f64 {
        self.error_um.get(j).copied().unwrap_or(0.0)
    }

    fn backoff_level(&self, j: usize) -> u8 {
        self.learned(j).backoff_level
    }

    fn ff_trim(&self, j: usize) -> [f64; 2] {
        self.learned(j).ff_trim_q16.map(|r| f64::from(r) / 65_536.0)
    }

    fn press(&self, j: usize) -> Option<PressOutput> {
        self.tl.runtime().law().and_then(|l| l.press_output(j))
    }
}

impl<const S: usize> Rt<S> {
    fn learned(&self, j: usize) -> hydra_core::runtime::Learned {
        use hydra_core::runtime::Controller as _;
        self.tl
            .runtime()
            .law()
            .map_or(hydra_core::runtime::Learned::NONE, |l| l.learned(j))
    }
}

fn invalid(key: String, value: impl ToString, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        key,
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// The follower axes of a scenario, in order.
pub fn followers(s: &Scenario) -> Vec<&AxisCfg> {
    s.axes.iter().filter(|a| a.role == Role::Follower).collect()
}

/// Builds the core's table from the CSV (master in degrees → master counts of the
/// scenario's master encoder; slaves mm → µm; a force axis' column is its start position
/// `x0_mm`, the press law driving it) and validates it against the axes: stroke,
/// and the slope against each axis' full-opening speed at the fastest master speed
/// (nominal speed plus ripple), building it in place in `dst` (a 4 096-row table is
/// 160 KiB: never on the stack). Errors name the CSV line.
fn build_table<const S: usize>(
    s: &Scenario,
    csv: &CamCsv,
    dst: &mut CamTable<S, TABLE_CAPACITY>,
) -> Result<(), ScenarioError> {
    let axes: Vec<&AxisCfg> = s.axes.iter().collect();
    let n = csv.master.len();
    let cols: Vec<std::borrow::Cow<[f64]>> = axes
        .iter()
        .map(|a| match a.role {
            Role::Force => Ok(vec![a.x0_mm.unwrap_or(0.0); n].into()),
            Role::Follower => csv.column(&a.name).map(Into::into).ok_or_else(|| {
                invalid(
                    format!("axis.{}.name", a.name),
                    &a.name,
                    "no column of that name in the table",
                )
            }),
        })
        .collect::<Result<_, _>>()?;
    let res = s.master.resolution_deg;
    let nodes: Vec<Node<S>> = (0..n)
        .map(|j| {
            let mut slave_um = [PosUm::ZERO; S];
            for (o, c) in slave_um.iter_mut().zip(&cols) {
                *o = PosUm::saturating_from_num(c[j] * 1e3);
            }
            Node {
                master: Master::saturating_from_num(csv.master[j] / res),
                slave_um,
            }
        })
        .collect();
    let supply = s.supply();
    let mut limits = [AxisLimits {
        min_um: PosUm::ZERO,
        max_um: PosUm::ZERO,
        max_speed_um_per_s: VelUmPerS::ZERO,
    }; S];
    for (l, a) in limits.iter_mut().zip(&axes) {
        let plant = a.plant(supply, 0.0);
        let v = plant
            .no_load_speed_m_per_s(true)
            .min(plant.no_load_speed_m_per_s(false));
        *l = AxisLimits {
            min_um: PosUm::ZERO,
            max_um: PosUm::saturating_from_num(a.cylinder.stroke_mm * 1e3),
            max_speed_um_per_s: VelUmPerS::saturating_from_num(v * 1e6),
        };
    }
    let fastest = s.master.speed_deg_per_s * (1.0 + s.master.ripple) / res;
    let lim = TableLimits {
        master_speed_per_s: MasterRate::saturating_from_num(fastest),
        axes: limits,
    };
    dst.rebuild_from_nodes(&nodes, &lim).map_err(|e| {
        let line = |row: usize| csv.lines.get(row).copied().unwrap_or(0);
        let path = csv.path.clone();
        let at = |row: usize, reason: String| {
            ScenarioError::Table(crate::camfile::TableError::Line {
                path: path.clone(),
                line: line(row),
                reason,
            })
        };
        let name = |axis: usize| axes.get(axis).map_or("?", |a| a.name.as_str());
        match e {
            TableError::TooFewNodes | TableError::MasterSpeed => at(0, e.to_string()),
            TableError::TooManyNodes { capacity } => at(
                capacity,
                format!("more than {capacity} nodes (the simulator's table capacity)"),
            ),
            TableError::NotMonotonic { row } => at(row, "master column not strictly monotonic".into()),
            TableError::SegmentLength { row } => at(
                row,
                format!(
                    "segment length outside 2^-15 … 65535 master counts ({} ° per count)",
                    res
                ),
            ),
            TableError::OutOfRange { row, axis } => {
                at(row, format!("`{}` outside the stroke [0, {}] mm", name(axis), axes[axis].cylinder.stroke_mm))
            }
            TableError::TooSteep { row, axis } => at(
                row,
                format!(
                    "`{}` asks for more than the axis' full-opening speed at the fastest master speed ({:.3} °/s)",
                    name(axis),
                    fastest * res
                ),
            ),
        }
    })
}

fn build<const S: usize>(
    s: &Scenario,
    csv: &CamCsv,
    t: &Tuning,
    controller: Controller,
    period_us: u32,
) -> Result<Box<dyn FollowerDyn>, ScenarioError> {
    // The table and the law are built in place on the heap (no large value on the stack).
    let mut table: Box<CamTable<S, TABLE_CAPACITY>> = Box::new(CamTable::empty());
    build_table::<S>(s, csv, &mut table)?;
    let mut cfg = follower_config::<S>(s, t, controller, period_us)?;
    let fe_limits = cfg.axes.map(|a| a.gains.following_error_um);
    let mut presses = [None; S];
    for ((p, c), a) in presses.iter_mut().zip(cfg.axes.iter_mut()).zip(&s.axes) {
        if a.role == Role::Force {
            *p = Some(press_coeffs(a, t, period_us)?);
            c.gains.following_error_um = PRESS_INNER_FE_LIMIT_UM;
        }
    }
    let mut law: Law<S> = Box::new(PressAxes::new(Follower::unconfigured()));
    let f = law.law_mut();
    f.configure(&cfg).map_err(|e| match e {
        FollowerError::MasterFilter(_) => invalid(
            format!(
                "tuning[{}@{}us].master_filter_hz",
                t.controller.name(),
                t.period_us
            ),
            t.master_filter_hz,
            format!(
                "must be in [0.1, 0.2/T = {:.3}] Hz at the run's period",
                0.2e6 / f64::from(period_us)
            ),
        ),
        FollowerError::Axis { axis, error } => invalid(
            format!(
                "tuning[{}@{}us].axes.{}",
                t.controller.name(),
                t.period_us,
                s.axes[axis].name
            ),
            format!("{error:?}"),
            format!("rejected at the run's period of {period_us} µs"),
        ),
    })?;
    f.load_table(&table);
    for (i, p) in presses.into_iter().enumerate() {
        law.set_press(i, p)
            .map_err(|e| invalid("axis".into(), e.axis, "no such runtime slave"))?;
    }
    let rc = runtime_config::<S>(s, &fe_limits, period_us);
    let coeffs = rc.build().map_err(|e| {
        invalid(
            "runtime".into(),
            format!("{e:?}"),
            format!("the runtime's configuration at {period_us} µs"),
        )
    })?;
    let rt = Runtime::new(coeffs, Some(law), BootCause::Normal);
    Ok(Box::new(Rt::<S> {
        tl: super::board::tick_loop(rt),
        io: SampledBoard::new(EncoderSample {
            master: Counts(0),
            slaves: [Counts(0); S],
            master_edges: None,
        }),
        host: SimHost::default(),
        period_ns: period_us.saturating_mul(CYCLES_PER_US),
        started: false,
        error_um: [0.0; S],
    }))
}

/// The runtime's configuration for the axes of `s`: each slave's encoder scale,
/// its following-error limit (the gain set's `following_error_um`), an encoder step
/// plausible up to 4× the axis' full-opening no-load speed, the master's up to 4× its
/// fastest speed (nominal + ripple) — both capped by the runtime's step limit of 16 383
/// counts per tick, which at long periods (≥ ≈ 70 ms with 1 µm encoders) sits below 4×
/// the axis' speed, so a loop that diverges there latches `encoder_jump`; every other rule
/// at the runtime's defaults (a master stall after 1 s standing still while following,
/// never within the end window of the table). With a force axis the pressure inputs are
/// required: stale ones latch `pressure_input`.
pub fn runtime_config<const S: usize>(
    s: &Scenario,
    following_error_um: &[f32; S],
    period_us: u32,
) -> RuntimeConfig<S> {
    let mut rc = RuntimeConfig::<S> {
        period_us,
        following_error_limit_um: *following_error_um,
        ..RuntimeConfig::default()
    };
    let cap_per_s = step_cap_counts_per_s(period_us);
    let m = &s.master;
    let peak = m.speed_deg_per_s.abs() * (1.0 + m.ripple.abs()) / m.resolution_deg;
    rc.master_max_speed_counts_per_s = (4.0 * peak).max(1000.0).min(cap_per_s) as f32;
    // A force axis' law depends on the pressures: stale ones are a fault.
    rc.pressure_required = s.axes.iter().any(|a| a.role == Role::Force);
    for (j, a) in s.axes.iter().enumerate().take(S) {
        rc.slave_um_per_count[j] = a.sensors.encoder_um as f32;
        rc.slave_max_speed_um_per_s[j] = plausible_speed_um_per_s(s, a, period_us);
    }
    rc
}

/// The runtime's 16-bit count extension bounds a plausible step: counts per second at
/// `period_us` just below [`MAX_STEP_LIMIT_COUNTS`] per tick.
fn step_cap_counts_per_s(period_us: u32) -> f64 {
    f64::from(MAX_STEP_LIMIT_COUNTS) * 0.999e6 / f64::from(period_us.max(1))
}

/// The fastest plausible encoder speed of axis `a`, µm/s: 4× its full-opening no-load
/// speed (at least 1 mm/s), capped by the runtime's step limit at `period_us`.
pub fn plausible_speed_um_per_s(s: &Scenario, a: &AxisCfg, period_us: u32) -> f32 {
    let p = a.plant(s.supply(), a.cylinder.stroke_mm * 0.5e-3);
    let v = p
        .no_load_speed_m_per_s(true)
        .max(p.no_load_speed_m_per_s(false));
    let cap_um_per_s = step_cap_counts_per_s(period_us) * a.sensors.encoder_um;
    (4.0 * v * 1e6).max(1000.0).min(cap_um_per_s) as f32
}

/// The law of a run over every axis of `s`, inside its runtime (`None` if the scenario
/// has no axis).
pub fn build_follower(
    s: &Scenario,
    csv: &CamCsv,
    t: &Tuning,
    controller: Controller,
    period_us: u32,
) -> Result<Option<Box<dyn FollowerDyn>>, ScenarioError> {
    let f = match s.axes.len() {
        0 => return Ok(None),
        1 => build::<1>(s, csv, t, controller, period_us)?,
        2 => build::<2>(s, csv, t, controller, period_us)?,
        3 => build::<3>(s, csv, t, controller, period_us)?,
        4 => build::<4>(s, csv, t, controller, period_us)?,
        n => {
            return Err(invalid(
                "axis".into(),
                n,
                format!("at most {MAX_AXES} axes are supported"),
            ))
        }
    };
    Ok(Some(f))
}

/// The press law's coefficients of force axis `a` with the gain set's gains (or the
/// defaults) at `period_us`.
fn press_coeffs(a: &AxisCfg, t: &Tuning, period_us: u32) -> Result<PressCoeffs, ScenarioError> {
    let g = t.press.get(&a.name).cloned().unwrap_or_default();
    let cfg = press_config(a, &g).ok_or_else(|| {
        invalid(
            format!("axis.{}.press", a.name),
            "missing",
            "a force axis needs [axis.press]",
        )
    })?;
    cfg.build(period_us).map_err(|e| {
        invalid(
            format!(
                "tuning[{}@{}us].press.{}",
                t.controller.name(),
                t.period_us,
                a.name
            ),
            format!("{e:?}"),
            format!("rejected at the run's period of {period_us} µs"),
        )
    })
}
