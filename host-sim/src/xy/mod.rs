//! The X–Y table scenario of seed 004: two hydraulic axes of `shared/PLANT.md` with
//! deliberately mismatched dynamics, paths from the seed-003 interpolator at 1 ms, and
//! four controllers from `hydra_xy::npid`.
//!
//! * **Plant.** X is the reference axis of PLANT.md (80/45 mm cylinder, 300 kg, 24 L/min
//!   valve at 35 bar, 60 Hz spool). Y carries 1.5× the moving mass (450 kg) and a valve
//!   with 30 % less flow (16.8 L/min). Both work around mid-stroke (250 mm = path
//!   origin). 1 µm encoders, one period of computation delay, RK4 at 10 µs.
//! * **Paths** (path coordinates, µm; the axes add 250 mm): `line` (0, 0) → (80, 60) mm;
//!   `circle` centre (0, 0), radius R (default 50 mm), one counter-clockwise turn from
//!   (R, 0); `parabola` y = x²/(2·20 mm), x ∈ [−40, 40] mm.
//! * **Feed.** Cosine ramp from 0 to the feed over 0.25 s, constant, then a constant
//!   deceleration (feed/0.25 s) to the end of the path; 0.3 s of hold after it.
//! * **Controllers.** `independent`: one linear PID per axis. `ccc`: the same PIDs plus
//!   a linear PID on the model contour error (Koren's CCC, line/osculating-circle model
//!   at the reference point). `nccc`: nonlinear PIDs (TD + fal) on the axes and on the
//!   model contour error (the seed's CNP). `nccc-est`: as `nccc` with ε from the seed-003
//!   estimator instead of the model ([`hydra_xy::npid::EstimatedXy`]).
//! * **Measured.** Contour error = exact signed distance from the actual point to the
//!   path ([`crate::contour_truth`]) at every sample; tracking errors = reference −
//!   actual per axis. The disturbance peak is the largest |ε| within 1 s after the load
//!   step.

pub mod gains;
pub mod law;
pub mod tune;

use crate::contour_truth::TruthPath;
use crate::plant::{valve_command, HydraulicAxis, Supply};
use crate::sim::board::{tick_loop, SampledBoard, SimHost, CYCLES_PER_US};
use crate::sim::FaultEvent;
use anyhow::{bail, Result};
use gains::Gains;
use hydra_core::runtime::{
    BootCause, Command, EncoderSample, Fault, MasterSource, Runtime, RuntimeConfig,
};
use hydra_core::units::Counts;
use hydra_xy::contour::{ArcSpec, LineSpec, ParabolaSpec, ParametricPath};
use law::XyLaw;
use serde::Serialize;

/// Ordinary points in the estimation window (covers (N−1)·v·Ts of lag: 3.15 mm at 50 mm/s).
pub const WINDOW_N: usize = 64;
/// Extra points per segment.
pub const WINDOW_H: usize = 15;
/// Path origin on both cylinders, m (mid-stroke).
const ORIGIN_M: f64 = 0.25;
/// Control period, s.
const TS: f64 = 1e-3;
/// Default following-error limit of each axis inside the runtime, µm (the board
/// profile's 5 mm): an `xy` run whose reference − position exceeds it latches
/// `following_error`.
pub const FOLLOWING_ERROR_LIMIT_UM: f32 = 5000.0;
/// RK4 steps per period.
const SUBSTEPS: usize = 100;
/// Feed ramp time, s.
const RAMP_S: f64 = 0.25;

/// The built-in paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// (0, 0) → (80, 60) mm.
    Line,
    /// One counter-clockwise turn of radius R around (0, 0) from (R, 0).
    Circle,
    /// y = x²/(2·20 mm), x ∈ [−40, 40] mm.
    Parabola,
}

/// The four controllers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ControllerKind {
    /// Linear PID per axis, no coupling.
    Independent,
    /// Classic cross-coupled control (linear PIDs, model ε).
    Ccc,
    /// Cross-coupled nonlinear PID (TD + fal), model ε.
    Nccc,
    /// Cross-coupled nonlinear PID, the contour error ε estimated on line (adaptive
    /// window over the interpolated path).
    NcccEst,
}

impl PathKind {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Line => "line",
            PathKind::Circle => "circle",
            PathKind::Parabola => "parabola",
        }
    }
}

impl ControllerKind {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::Independent => "independent",
            ControllerKind::Ccc => "ccc",
            ControllerKind::Nccc => "nccc",
            ControllerKind::NcccEst => "nccc-est",
        }
    }
}

/// One X–Y run.
#[derive(Debug, Clone, PartialEq)]
pub struct XyScenario {
    /// Path.
    pub path: PathKind,
    /// Controller.
    pub controller: ControllerKind,
    /// Feed, mm/s (> 0, ≤ 200).
    pub feed_mm_per_s: f64,
    /// Circle radius, mm (5 … 200).
    pub radius_mm: f64,
    /// Step load on X (N, positive opposes extension) and the time it starts (s).
    pub disturbance: Option<(f64, f64)>,
    /// Gains of every controller.
    pub gains: Gains,
    /// The runtime's following-error limit of each axis, µm (10 … 100 000).
    pub following_error_um: f32,
    /// The Y axis at run time against the machine its feed-forward was identified on:
    /// valve flow ×`y_flow`, moving mass ×`y_mass` (1, 1: the same machine).
    pub y_drift: YDrift,
}

/// The Y plant's drift from the identified machine (multipliers, 0.25 … 4).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct YDrift {
    /// Valve flow gain ×.
    pub y_flow: f64,
    /// Moving mass ×.
    pub y_mass: f64,
}

impl Default for YDrift {
    fn default() -> Self {
        Self {
            y_flow: 1.0,
            y_mass: 1.0,
        }
    }
}

impl Default for XyScenario {
    fn default() -> Self {
        Self {
            path: PathKind::Circle,
            controller: ControllerKind::Nccc,
            feed_mm_per_s: 50.0,
            radius_mm: 50.0,
            disturbance: None,
            gains: Gains::default(),
            following_error_um: FOLLOWING_ERROR_LIMIT_UM,
            y_drift: YDrift::default(),
        }
    }
}

/// One sample of the trace.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Reference (path coordinates), µm (after a fault: the last one the law produced).
    pub reference_um: [f64; 2],
    /// Actual position (path coordinates), µm.
    pub actual_um: [f64; 2],
    /// Exact signed contour error, µm.
    pub contour_um: f64,
    /// The controller's ε (model or estimate), µm.
    pub controller_contour_um: f64,
    /// Direction of the path normal at the exact foot point, degrees from +X (−180 … 180].
    pub normal_deg: f64,
    /// Valve DAC codes applied, LSB (0 while the runtime has the valves unpowered).
    pub command_lsb: [f64; 2],
}

/// Per-axis figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PerAxis {
    /// X axis.
    pub x: f64,
    /// Y axis.
    pub y: f64,
}

/// Where a contour-error peak happened and which axis could act on it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PeakAt {
    /// Time of the peak, s.
    pub t_s: f64,
    /// Direction of the path normal at the foot point there, degrees from +X.
    pub normal_deg: f64,
    /// Angle between that normal and the nearest coordinate axis, degrees (0 … 45).
    /// ε = n·(P − F) changes only through the normal's components: at 0° only one axis
    /// moves the point off or onto the path (an axis reversal on a circle or at a
    /// parabola's vertex); cross-coupling can redistribute the error to the other axis
    /// only as far as this angle allows (the other axis' share is sin of it).
    pub normal_off_axis_deg: f64,
}

impl PeakAt {
    fn of(p: &Sample) -> Self {
        let n = p.normal_deg.rem_euclid(90.0);
        Self {
            t_s: p.t_s,
            normal_deg: p.normal_deg,
            normal_off_axis_deg: n.min(90.0 - n),
        }
    }
}

/// The result of a run (the `--json` object; the trace is not serialised).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct XyReport {
    /// Path name.
    pub path: &'static str,
    /// Controller name.
    pub controller: &'static str,
    /// max |exact contour error|, µm.
    pub max_contour_error_um: f64,
    /// RMS of the exact contour error, µm.
    pub rms_contour_error_um: f64,
    /// max |reference − actual| per axis, µm.
    pub max_tracking_error_um: PerAxis,
    /// Where `max_contour_error_um` happened.
    pub max_contour_error_at: PeakAt,
    /// max |ε| within 1 s after the load step, µm (null without a disturbance).
    pub disturbance_peak_contour_error_um: Option<f64>,
    /// Where the disturbance peak happened (null without a disturbance).
    pub disturbance_peak_at: Option<PeakAt>,
    /// Largest |valve command|, LSB.
    pub max_command_lsb: f64,
    /// Sign changes per second of the contour error after the ramp (oscillation check).
    pub contour_sign_changes_per_s: f64,
    /// Faults the runtime latched (`[{code, name, axis, tick, t_s, value}]`; empty: none).
    pub faults: Vec<FaultEvent>,
    /// The Y plant's drift from the identified machine in this run.
    pub y_drift: YDrift,
    /// The trace, one sample per period.
    #[serde(skip)]
    pub trace: Vec<Sample>,
}

/// The paths of the scenario as core paths and exact references.
enum CorePath {
    Line(hydra_xy::contour::Line),
    Arc(hydra_xy::contour::Arc),
    Parabola(hydra_xy::contour::Parabola),
}

fn build_path(s: &XyScenario) -> Result<(CorePath, TruthPath)> {
    Ok(match s.path {
        PathKind::Line => {
            let spec = LineSpec {
                start_um: [0.0, 0.0],
                end_um: [80_000.0, 60_000.0],
            };
            let p = spec.build().map_err(|e| anyhow::anyhow!("line: {e:?}"))?;
            (CorePath::Line(p), TruthPath::line(&spec))
        }
        PathKind::Circle => {
            let spec = ArcSpec {
                center_um: [0.0, 0.0],
                radius_um: s.radius_mm * 1000.0,
                start_deg: 0.0,
                sweep_deg: 360.0,
            };
            let p = spec.build().map_err(|e| anyhow::anyhow!("circle: {e:?}"))?;
            (CorePath::Arc(p), TruthPath::arc(&spec))
        }
        PathKind::Parabola => {
            let spec = ParabolaSpec {
                vertex_um: [0.0, 0.0],
                p_um: 20_000.0,
                axis_deg: 0.0,
                x_start_um: -40_000.0,
                x_end_um: 40_000.0,
            };
            let p = spec
                .build()
                .map_err(|e| anyhow::anyhow!("parabola: {e:?}"))?;
            (CorePath::Parabola(p), TruthPath::parabola(&spec))
        }
    })
}

/// The two axes ([`crate::machine::xy_axes`]) at rest at `start_um`.
pub(crate) fn axes(start_um: [f64; 2]) -> (HydraulicAxis, HydraulicAxis, Supply) {
    crate::machine::xy_axes(ORIGIN_M, start_um)
}

/// Runs one scenario.
pub fn simulate(s: &XyScenario) -> Result<XyReport> {
    simulate_with(s, false)
}

/// [`simulate`], ending the run at the first period a valve command reaches the DAC's
/// limit (|code| ≥ 2046): the tuning rejects such a run whatever follows
/// (`tune::cost`), so a candidate that saturates early costs only the time to saturate.
/// The report then covers the run up to that period.
pub fn simulate_until_saturated(s: &XyScenario) -> Result<XyReport> {
    simulate_with(s, true)
}

fn simulate_with(s: &XyScenario, stop_at_saturation: bool) -> Result<XyReport> {
    if !(s.feed_mm_per_s.is_finite() && s.feed_mm_per_s > 0.0 && s.feed_mm_per_s <= 200.0) {
        bail!("--feed must be in (0, 200] mm/s, got {}", s.feed_mm_per_s);
    }
    if !(s.radius_mm.is_finite() && (5.0..=200.0).contains(&s.radius_mm)) {
        bail!("--radius-mm must be in [5, 200] mm, got {}", s.radius_mm);
    }
    if !(s.following_error_um.is_finite() && (10.0..=100_000.0).contains(&s.following_error_um)) {
        bail!(
            "--following-error-um must be in [10, 100 000] µm, got {}",
            s.following_error_um
        );
    }
    if let Some((n, t)) = s.disturbance {
        if !(n.is_finite() && n.abs() <= 50_000.0 && t.is_finite() && t >= 0.0) {
            bail!("disturbance must be |N| ≤ 50 kN at a time ≥ 0 s");
        }
    }
    let d = s.y_drift;
    if !([d.y_flow, d.y_mass]
        .iter()
        .all(|k| k.is_finite() && (0.25..=4.0).contains(k)))
    {
        bail!(
            "--y-flow and --y-mass must be in [0.25, 4], got {} and {}",
            d.y_flow,
            d.y_mass
        );
    }
    let (core_path, truth) = build_path(s)?;
    match &core_path {
        CorePath::Line(p) => run(s, p, &truth, stop_at_saturation),
        CorePath::Arc(p) => run(s, p, &truth, stop_at_saturation),
        CorePath::Parabola(p) => run(s, p, &truth, stop_at_saturation),
    }
}

fn run<P: ParametricPath>(
    s: &XyScenario,
    path: &P,
    truth: &TruthPath,
    stop_at_saturation: bool,
) -> Result<XyReport> {
    let start = truth.r(truth.domain().0);
    let (mut ax, mut ay, _) = axes(start);
    // The drift acts on the plant only: the law keeps the gains and feed-forward it was
    // given (identified on the nominal machine).
    ay.valve.kv *= s.y_drift.y_flow;
    ay.cylinder.mass_kg *= s.y_drift.y_mass;
    let law = XyLaw::new(s, path, truth)?;
    let rc = runtime_config(s.following_error_um);
    let coeffs = rc
        .build()
        .map_err(|e| anyhow::anyhow!("the runtime's configuration: {e:?}"))?;
    // The firmware's tick over the two axes' sampled inputs (no pressure inputs).
    let mut tl = tick_loop(Runtime::<_, 2, 0>::new(
        coeffs,
        Some(law),
        BootCause::Normal,
    ));
    let mut host = SimHost::default();
    let mut io = SampledBoard::<2, 0>::new(EncoderSample {
        master: Counts(0),
        slaves: [Counts(0); 2],
        master_edges: None,
    });
    let period_ns = 1000 * CYCLES_PER_US;
    let mut pending = [0.0f64; 2];
    let mut trace = Vec::new();
    let mut faults: Vec<FaultEvent> = Vec::new();
    let mut finished_at: Option<f64> = None;
    let h = TS / SUBSTEPS as f64;
    let mut k: u64 = 0;
    loop {
        let t = k as f64 * TS;
        if let Some(tf) = finished_at {
            if t > tf + 0.3 {
                break;
            }
        }
        if t > 600.0 {
            bail!("the path did not finish in 600 s");
        }
        // Sample: 1 µm encoders on both axes (path coordinates).
        let actual = [(ax.x_m() - ORIGIN_M) * 1e6, (ay.x_m() - ORIGIN_M) * 1e6];
        let enc = |v: f64| Counts(v.round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32);
        io.enc.slaves = [enc(actual[0]), enc(actual[1])];
        if k == 0 {
            host.queue(Command::Start);
        }
        tl.run(&mut io, &mut host);
        host.now_ns = host.now_ns.wrapping_add(period_ns);
        if let Some(Some(e)) = host.take_refusal() {
            bail!("the runtime refused Start: {e:?}");
        }
        let rt = tl.runtime();
        let st = rt.status();
        if let Some(r) = st.fault {
            if faults.last().map(|l| (l.code, l.tick)) != Some((r.fault.code(), r.tick)) {
                faults.push(FaultEvent {
                    code: r.fault.code(),
                    name: r.fault.name(),
                    axis: r
                        .fault
                        .slave()
                        .map(|a| ["x", "y"][usize::from(a).min(1)].to_string()),
                    tick: r.tick,
                    t_s: t,
                    value: match r.fault {
                        Fault::FollowingError { axis } => st
                            .error_um
                            .get(usize::from(axis))
                            .map(|e| e.to_num::<f64>().abs()),
                        _ => None,
                    },
                });
                // A faulted run ends 0.3 s later (the valves are at null).
                finished_at.get_or_insert(t);
            }
        }
        let lt = rt.law().map(|l| l.last).unwrap_or_default();
        if lt.finished && finished_at.is_none() {
            finished_at = Some(t);
        }
        let near = truth.nearest(actual);
        let nrm = truth.left_normal(near.u);
        // What the valves get: the DAC codes while the runtime powers them, else 0.
        let codes = if io.enable {
            io.codes.map(|c| f64::from(c.get()))
        } else {
            [0.0; 2]
        };
        trace.push(Sample {
            t_s: t,
            reference_um: lt.reference_um,
            actual_um: actual,
            contour_um: near.eps,
            controller_contour_um: lt.controller_contour_um,
            normal_deg: nrm[1].atan2(nrm[0]).to_degrees(),
            command_lsb: codes,
        });
        if stop_at_saturation && codes.iter().any(|c| c.abs() >= 2046.0) {
            break;
        }
        // Plant: the code written now acts from the next period.
        let applied = pending;
        pending = io.codes.map(|c| valve_command(c.get(), io.enable));
        if let Some((n, t0)) = s.disturbance {
            ax.cylinder.load_n = if t >= t0 { n } else { 0.0 };
        }
        for _ in 0..SUBSTEPS {
            ax.step(applied[0], h);
            ay.step(applied[1], h);
        }
        k += 1;
    }
    Ok(report(s, trace, faults))
}

/// The runtime of an `xy` run: the time master, 1 ms, both axes' 1 µm encoders and the
/// runtime's default plausibility (1 m/s), a following-error limit of
/// `following_error_um` per axis.
pub fn runtime_config(following_error_um: f32) -> RuntimeConfig<2> {
    RuntimeConfig::<2> {
        period_us: 1000,
        master_source: MasterSource::Time,
        following_error_limit_um: [following_error_um; 2],
        ..RuntimeConfig::default()
    }
}

/// The sample with the largest |exact ε| (the first of equal ones).
fn largest_contour_error<'a>(it: impl Iterator<Item = &'a Sample>) -> Option<&'a Sample> {
    it.fold(None, |b: Option<&Sample>, p| match b {
        Some(q) if q.contour_um.abs() >= p.contour_um.abs() => Some(q),
        _ => Some(p),
    })
}

fn report(s: &XyScenario, trace: Vec<Sample>, faults: Vec<FaultEvent>) -> XyReport {
    let n = trace.len().max(1) as f64;
    let max_at = largest_contour_error(trace.iter());
    let max_c = max_at.map_or(0.0, |p| p.contour_um.abs());
    let rms = (trace.iter().map(|p| p.contour_um.powi(2)).sum::<f64>() / n).sqrt();
    let ex = trace
        .iter()
        .map(|p| (p.reference_um[0] - p.actual_um[0]).abs())
        .fold(0.0, f64::max);
    let ey = trace
        .iter()
        .map(|p| (p.reference_um[1] - p.actual_um[1]).abs())
        .fold(0.0, f64::max);
    let dist_at = s.disturbance.and_then(|(_, t0)| {
        largest_contour_error(trace.iter().filter(|p| p.t_s >= t0 && p.t_s <= t0 + 1.0))
    });
    let dist = s
        .disturbance
        .map(|_| dist_at.map_or(0.0, |p| p.contour_um.abs()));
    let max_cmd = trace
        .iter()
        .map(|p| p.command_lsb[0].abs().max(p.command_lsb[1].abs()))
        .fold(0.0, f64::max);
    let steady: Vec<&Sample> = trace.iter().filter(|p| p.t_s > RAMP_S).collect();
    let changes = steady
        .windows(2)
        .filter(|w| w[0].contour_um.signum() != w[1].contour_um.signum())
        .count();
    let dur = steady.len().max(1) as f64 * TS;
    XyReport {
        path: s.path.name(),
        controller: s.controller.name(),
        max_contour_error_um: max_c,
        rms_contour_error_um: rms,
        max_tracking_error_um: PerAxis { x: ex, y: ey },
        max_contour_error_at: max_at.map_or(
            PeakAt {
                t_s: 0.0,
                normal_deg: 0.0,
                normal_off_axis_deg: 0.0,
            },
            PeakAt::of,
        ),
        disturbance_peak_contour_error_um: dist,
        disturbance_peak_at: dist_at.map(PeakAt::of),
        max_command_lsb: max_cmd,
        contour_sign_changes_per_s: changes as f64 / dur,
        faults,
        y_drift: s.y_drift,
        trace,
    }
}
