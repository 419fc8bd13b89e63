//! The X–Y table scenario of seed 004: two hydraulic axes of `shared/PLANT.md` with
//! deliberately mismatched dynamics, paths from the seed-003 interpolator at 1 ms, and
//! four controllers from `hydra_core::npid`.
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
//!   estimator instead of the model ([`hydra_core::npid::EstimatedXy`]).
//! * **Measured.** Contour error = exact signed distance from the actual point to the
//!   path ([`crate::contour_truth`]) at every sample; tracking errors = reference −
//!   actual per axis. The disturbance peak is the largest |ε| within 1 s after the load
//!   step.

pub mod gains;
pub mod tune;

use crate::contour_truth::TruthPath;
use crate::plant::{HydraulicAxis, Supply};
use crate::scenario::{AxisCfg, Scenario};
use anyhow::{bail, Result};
use gains::Gains;
use hydra_core::contour::{
    curvature_per_m, ArcSpec, ContourWindow, InterpConfig, Interpolator, LineSpec, ParabolaSpec,
    ParametricPath,
};
use hydra_core::npid::{
    Ccc, Cnp, CrossCoupled, EstimatedXy, PathFrame, VelocityFf, XyCoeffs, XyOutput,
};
use hydra_core::units::{PosUm, VelUmPerS};
use serde::Serialize;

/// Ordinary points in the estimation window (covers (N−1)·v·Ts of lag: 3.15 mm at 50 mm/s).
pub const WINDOW_N: usize = 64;
/// Extra points per segment.
pub const WINDOW_H: usize = 15;
/// Path origin on both cylinders, m (mid-stroke).
const ORIGIN_M: f64 = 0.25;
/// Control period, s.
const TS: f64 = 1e-3;
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
    /// Cross-coupled nonlinear PID, ε from the seed-003 estimator.
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
        }
    }
}

/// One sample of the trace.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Reference (path coordinates), µm.
    pub reference_um: [f64; 2],
    /// Actual position (path coordinates), µm.
    pub actual_um: [f64; 2],
    /// Exact signed contour error, µm.
    pub contour_um: f64,
    /// The controller's ε (model or estimate), µm.
    pub controller_contour_um: f64,
    /// Direction of the path normal at the exact foot point, degrees from +X (−180 … 180].
    pub normal_deg: f64,
    /// Valve commands, LSB.
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
    /// The trace, one sample per period.
    #[serde(skip)]
    pub trace: Vec<Sample>,
}

/// The paths of the scenario as core paths and exact references.
enum CorePath {
    Line(hydra_core::contour::Line),
    Arc(hydra_core::contour::Arc),
    Parabola(hydra_core::contour::Parabola),
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

/// The two axes: X per PLANT.md, Y with 1.5× mass and 30 % less valve flow.
pub(crate) fn axes(start_um: [f64; 2]) -> (HydraulicAxis, HydraulicAxis, Supply) {
    let supply = Scenario::default().supply();
    let x = AxisCfg::default();
    let mut y = AxisCfg::default();
    y.cylinder.mass_kg *= 1.5;
    y.valve.rated_flow_l_per_min *= 0.7;
    let ax = HydraulicAxis::at_rest(
        x.valve_si(),
        x.cylinder_si(),
        supply,
        ORIGIN_M + start_um[0] * 1e-6,
    );
    let ay = HydraulicAxis::at_rest(
        y.valve_si(),
        y.cylinder_si(),
        supply,
        ORIGIN_M + start_um[1] * 1e-6,
    );
    (ax, ay, supply)
}

/// The controller of a run.
enum Ctl {
    Linear(Ccc, XyCoeffs<hydra_core::npid::PidCoeffs>, bool),
    Nonlinear(Cnp, XyCoeffs<hydra_core::npid::NpidCoeffs>),
    Estimated(
        Box<EstimatedXy<WINDOW_N, WINDOW_H>>,
        XyCoeffs<hydra_core::npid::NpidCoeffs>,
    ),
}

fn um(v: f64) -> PosUm {
    PosUm::saturating_from_num(v)
}

/// Runs one scenario.
pub fn simulate(s: &XyScenario) -> Result<XyReport> {
    if !(s.feed_mm_per_s.is_finite() && s.feed_mm_per_s > 0.0 && s.feed_mm_per_s <= 200.0) {
        bail!("--feed must be in (0, 200] mm/s, got {}", s.feed_mm_per_s);
    }
    if !(s.radius_mm.is_finite() && (5.0..=200.0).contains(&s.radius_mm)) {
        bail!("--radius-mm must be in [5, 200] mm, got {}", s.radius_mm);
    }
    if let Some((n, t)) = s.disturbance {
        if !(n.is_finite() && n.abs() <= 50_000.0 && t.is_finite() && t >= 0.0) {
            bail!("disturbance must be |N| ≤ 50 kN at a time ≥ 0 s");
        }
    }
    let (core_path, truth) = build_path(s)?;
    match &core_path {
        CorePath::Line(p) => run(s, p, &truth),
        CorePath::Arc(p) => run(s, p, &truth),
        CorePath::Parabola(p) => run(s, p, &truth),
    }
}

fn run<P: ParametricPath>(s: &XyScenario, path: &P, truth: &TruthPath) -> Result<XyReport> {
    let interp_c = InterpConfig {
        period_us: 1000,
        q_s: 1.0,
        h_max: WINDOW_H as u16,
    }
    .build()
    .map_err(|e| anyhow::anyhow!("interpolator: {e:?}"))?;
    let start = truth.r(truth.domain().0);
    let (mut ax, mut ay, _) = axes(start);
    let g = &s.gains;
    let p0 = [um(start[0]), um(start[1])];
    let mut ctl = match s.controller {
        ControllerKind::Independent | ControllerKind::Ccc => {
            let c = g.linear_coeffs(s.controller == ControllerKind::Independent)?;
            let st = CrossCoupled::at_rest(
                Default::default(),
                Default::default(),
                Default::default(),
                p0,
            );
            Ctl::Linear(st, c, s.controller == ControllerKind::Ccc)
        }
        ControllerKind::Nccc => {
            let c = g.nonlinear_coeffs(false)?;
            let st = CrossCoupled::at_rest(
                Default::default(),
                Default::default(),
                Default::default(),
                p0,
            );
            Ctl::Nonlinear(st, c)
        }
        ControllerKind::NcccEst => {
            let c = g.nonlinear_coeffs(true)?;
            let st = CrossCoupled::at_rest(
                Default::default(),
                Default::default(),
                Default::default(),
                p0,
            );
            Ctl::Estimated(Box::new(EstimatedXy::start(path, st)), c)
        }
    };
    let ffc = g.ff_coeffs()?;
    let mut ff = [VelocityFf::at_rest(p0[0]), VelocityFf::at_rest(p0[1])];
    let mut window: Box<ContourWindow<WINDOW_N, WINDOW_H>> = Box::default();
    let mut interp = Interpolator::start(path, &mut *window);
    let total_len = truth.arc_length(truth.domain().1);
    let feed = s.feed_mm_per_s * 1000.0;
    let decel = feed / RAMP_S;
    let mut pending = [0.0f64; 2];
    let mut trace = Vec::new();
    let mut finished_at: Option<f64> = None;
    let h = TS / SUBSTEPS as f64;
    let mut k: u64 = 0;
    let mut u_path = truth.domain().0;
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
        // Sample.
        let actual = [(ax.x_m() - ORIGIN_M) * 1e6, (ay.x_m() - ORIGIN_M) * 1e6];
        let meas = [um(actual[0].round()), um(actual[1].round())];
        // Feed: cosine ramp up, constant deceleration to the end.
        let ramp = if t < RAMP_S {
            0.5 - 0.5 * (std::f64::consts::PI * t / RAMP_S).cos()
        } else {
            1.0
        };
        let remaining = (total_len - truth.arc_length(u_path)).max(0.0);
        let f = (feed * ramp).min((2.0 * decel * remaining).sqrt().max(500.0));
        let fq = VelUmPerS::saturating_from_num(f);
        let (reference, out, fin, u_now): ([f64; 2], XyOutput, bool, f64) = match &mut ctl {
            Ctl::Estimated(e, c) => {
                let per = e.tick_with_feedforward(&interp_c, c, &ffc, path, fq, meas);
                let r = per.reference.pos_um();
                (
                    [r.x.to_num(), r.y.to_num()],
                    per.output,
                    per.reference.finished,
                    per.reference.point.u.to_num(),
                )
            }
            other => {
                let rf = interp.step(&interp_c, path, fq, &mut *window);
                let r = rf.pos_um();
                let pt = path.eval(rf.point.u);
                let kappa = curvature_per_m(&pt).unwrap_or_default();
                let frame = PathFrame::from_contour(rf.point.tangent, kappa);
                let refp = [r.x, r.y];
                let u_ff = [ff[0].step(&ffc[0], r.x), ff[1].step(&ffc[1], r.y)];
                match other {
                    Ctl::Linear(st, ..) => st.set_feedforward(u_ff),
                    Ctl::Nonlinear(st, _) => st.set_feedforward(u_ff),
                    Ctl::Estimated(..) => unreachable!(),
                }
                let out = match other {
                    Ctl::Linear(st, c, true) => st.tick_model(c, refp, meas, &frame),
                    Ctl::Linear(st, c, false) => st.tick_independent(c, refp, meas, &frame),
                    Ctl::Nonlinear(st, c) => st.tick_model(c, refp, meas, &frame),
                    Ctl::Estimated(..) => unreachable!(),
                };
                (
                    [r.x.to_num(), r.y.to_num()],
                    out,
                    rf.finished,
                    rf.point.u.to_num(),
                )
            }
        };
        u_path = u_now;
        if fin && finished_at.is_none() {
            finished_at = Some(t);
        }
        let near = truth.nearest(actual);
        let exact = near.eps;
        let nrm = truth.left_normal(near.u);
        let cmd = [
            out.command[0].to_num::<f64>(),
            out.command[1].to_num::<f64>(),
        ];
        trace.push(Sample {
            t_s: t,
            reference_um: reference,
            actual_um: actual,
            contour_um: exact,
            controller_contour_um: out.contour_error_um.to_num(),
            normal_deg: nrm[1].atan2(nrm[0]).to_degrees(),
            command_lsb: cmd,
        });
        // Plant: the command computed now acts from the next period.
        let applied = pending;
        pending = [cmd[0] / 2047.0, cmd[1] / 2047.0];
        if let Some((n, t0)) = s.disturbance {
            ax.cylinder.load_n = if t >= t0 { n } else { 0.0 };
        }
        for _ in 0..SUBSTEPS {
            ax.step(applied[0], h);
            ay.step(applied[1], h);
        }
        k += 1;
    }
    Ok(report(s, trace))
}

/// The sample with the largest |exact ε| (the first of equal ones).
fn largest_contour_error<'a>(it: impl Iterator<Item = &'a Sample>) -> Option<&'a Sample> {
    it.fold(None, |b: Option<&Sample>, p| match b {
        Some(q) if q.contour_um.abs() >= p.contour_um.abs() => Some(q),
        _ => Some(p),
    })
}

fn report(s: &XyScenario, trace: Vec<Sample>) -> XyReport {
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
        trace,
    }
}
