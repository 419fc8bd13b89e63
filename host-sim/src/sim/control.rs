//! The controllers of a run, built from the scenario: the core's [`Follower`] for the
//! table-following axes and the core's press law for the force axes.
//!
//! The follower is generic over the number of slave axes `S`; the simulator supports 1 to
//! [`MAX_FOLLOWERS`] follower axes through one monomorphisation each, behind the
//! object-safe [`FollowerDyn`]. Tables hold up to [`TABLE_CAPACITY`] nodes.

use crate::camfile::CamCsv;
use crate::scenario::{AxisCfg, Controller, Role, Scenario, ScenarioError, Tuning};
use crate::tuning::{follower_config, press_config};
use hydra_core::axis::{PressCoeffs, PressOutput, PressState};
use hydra_core::follower::{Follower, FollowerError, FollowerInputs};
use hydra_core::table::{AxisLimits, CamTable, Node, TableError, TableLimits};
use hydra_core::units::{CmdLsb, DacCode, Master, MasterRate, PosUm, PressureBar, VelUmPerS};

/// Largest number of nodes of a simulated table.
pub const TABLE_CAPACITY: usize = 4096;
/// Largest number of follower axes of a scenario.
pub const MAX_FOLLOWERS: usize = 4;

/// One follower tick, whatever the number of axes.
pub trait FollowerDyn: Send {
    /// Runs one control period: master sample (counts) and slave positions in; valve codes,
    /// the commands before the output stage and the targets X(θ_f(k)) (µm) out. Returns the
    /// follower's filtered master estimate (counts).
    fn tick(
        &mut self,
        master: Master,
        pos: &[PosUm],
        dac: &mut [DacCode],
        cmd: &mut [CmdLsb],
        target: &mut [PosUm],
    ) -> Master;
}

struct Fw<const S: usize>(Box<Follower<S, TABLE_CAPACITY>>);

impl<const S: usize> FollowerDyn for Fw<S> {
    fn tick(
        &mut self,
        master: Master,
        pos: &[PosUm],
        dac: &mut [DacCode],
        cmd: &mut [CmdLsb],
        target: &mut [PosUm],
    ) -> Master {
        let mut pos_um = [PosUm::ZERO; S];
        pos_um.copy_from_slice(pos);
        let o = self.0.tick(&FollowerInputs { master, pos_um });
        dac.copy_from_slice(&o.dac);
        cmd.copy_from_slice(&o.cmd_lsb);
        target.copy_from_slice(&o.target_um);
        self.0.master_estimate().pos
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
/// scenario's master encoder; slaves mm → µm) and validates it against the axes: stroke,
/// and the slope against each axis' full-opening speed at the fastest master speed
/// (nominal speed plus ripple), building it in place in `dst` (a 4 096-row table is
/// 160 KiB: never on the stack). Errors name the CSV line.
fn build_table<const S: usize>(
    s: &Scenario,
    csv: &CamCsv,
    dst: &mut CamTable<S, TABLE_CAPACITY>,
) -> Result<(), ScenarioError> {
    let axes = followers(s);
    let cols: Vec<&[f64]> = axes
        .iter()
        .map(|a| {
            csv.column(&a.name).ok_or_else(|| {
                invalid(
                    format!("axis.{}.name", a.name),
                    &a.name,
                    "no column of that name in the table",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let res = s.master.resolution_deg;
    let nodes: Vec<Node<S>> = (0..csv.master.len())
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
    let cfg = follower_config::<S>(s, t, controller, period_us)?;
    let mut f: Box<Follower<S, TABLE_CAPACITY>> = Box::new(Follower::unconfigured());
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
                followers(s)[axis].name
            ),
            format!("{error:?}"),
            format!("rejected at the run's period of {period_us} µs"),
        ),
    })?;
    f.load_table(&table);
    Ok(Box::new(Fw::<S>(f)))
}

/// The follower of a run (`None` if the scenario has no follower axis).
pub fn build_follower(
    s: &Scenario,
    csv: &CamCsv,
    t: &Tuning,
    controller: Controller,
    period_us: u32,
) -> Result<Option<Box<dyn FollowerDyn>>, ScenarioError> {
    let f = match followers(s).len() {
        0 => return Ok(None),
        1 => build::<1>(s, csv, t, controller, period_us)?,
        2 => build::<2>(s, csv, t, controller, period_us)?,
        3 => build::<3>(s, csv, t, controller, period_us)?,
        4 => build::<4>(s, csv, t, controller, period_us)?,
        n => {
            return Err(invalid(
                "axis".into(),
                n,
                format!("at most {MAX_FOLLOWERS} follower axes are supported"),
            ))
        }
    };
    Ok(Some(f))
}

/// A force axis' controller.
#[derive(Clone, Debug)]
pub struct Press {
    coeffs: PressCoeffs,
    state: PressState,
}

impl Press {
    /// Builds the press law of a force axis with the gain set's gains (or the defaults).
    pub fn new(a: &AxisCfg, t: &Tuning, period_us: u32) -> Result<Self, ScenarioError> {
        let g = t.press.get(&a.name).cloned().unwrap_or_default();
        let cfg = press_config(a, &g).ok_or_else(|| {
            invalid(
                format!("axis.{}.press", a.name),
                "missing",
                "a force axis needs [axis.press]",
            )
        })?;
        let coeffs = cfg.build(period_us).map_err(|e| {
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
        })?;
        Ok(Self {
            coeffs,
            state: PressState::default(),
        })
    }

    /// One control tick from the position (µm) and the two pressure readings (bar).
    pub fn tick(&mut self, x: PosUm, pa: PressureBar, pb: PressureBar) -> PressOutput {
        self.state.tick(&self.coeffs, x, pa, pb)
    }
}
