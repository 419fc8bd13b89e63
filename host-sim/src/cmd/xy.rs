//! `host-sim xy`: the two-axis X–Y table of seed 004 with independent or cross-coupled
//! control (see [`crate::xy`] for the plant, paths, controllers and what is measured).
//!
//! `--json` prints one object: `{"path", "controller", "max_contour_error_um",
//! "rms_contour_error_um", "max_tracking_error_um": {"x", "y"},
//! "max_contour_error_at": {"t_s", "normal_deg", "normal_off_axis_deg"},
//! "disturbance_peak_contour_error_um", "disturbance_peak_at" (same shape or null),
//! "max_command_lsb", "contour_sign_changes_per_s", "faults": [{"code", "name", "axis",
//! "tick", "t_s", "value"}]}`. The run goes through the core's runtime
//! ([`crate::xy::law`]): a latched fault (a following error beyond 5 mm, an implausible
//! encoder step) unpowers the valves, ends the run 0.3 s later and makes the exit code 3
//! (`--allow-fault`: 0). `normal_off_axis_deg` is the angle
//! between the path normal at the peak and the nearest axis: near 0° only that one axis
//! can act on the contour error there.

use crate::xy::{simulate, ControllerKind, PathKind, XyReport, XyScenario};
use anyhow::Result;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Arguments of the sub-command.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Path to run.
    #[arg(long, value_enum, default_value = "circle")]
    pub path: PathKind,
    /// Controller (default `nccc`; with `--tune`: tune only this one).
    #[arg(long, value_enum)]
    pub controller: Option<ControllerKind>,
    /// Feed, mm/s.
    #[arg(long = "feed", default_value_t = 50.0)]
    pub feed_mm_per_s: f64,
    /// Circle radius, mm.
    #[arg(long, default_value_t = 50.0)]
    pub radius_mm: f64,
    /// Step load on X, N (positive opposes extension).
    #[arg(long, requires = "disturbance_at_s", allow_negative_numbers = true)]
    pub disturbance_n: Option<f64>,
    /// Time of the load step, s.
    #[arg(long, requires = "disturbance_n")]
    pub disturbance_at_s: Option<f64>,
    /// Write an SVG plot (path and actual point at equal axis scales, contour error,
    /// commands).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Plot: also draw the actual path with its deviation from the reference magnified
    /// this many times (µm errors on a path of tens of mm are otherwise invisible).
    #[arg(long, value_parser = parse_magnify)]
    pub error_scale: Option<f64>,
    /// Write the trace as CSV (t_s, reference x/y µm, actual x/y µm, exact ε µm,
    /// controller ε µm, commands x/y LSB), one row per control period.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Gains file (TOML: `[axis_independent]`, `[axis_linear]`, `[contour_linear]`,
    /// `[axis_nonlinear]`, `[contour_nonlinear]`, `[axis_estimated]`,
    /// `[contour_estimated]`, `[feedforward]`; omitted tables keep the tuned defaults).
    #[arg(long)]
    pub gains: Option<PathBuf>,
    /// Velocity feed-forward (all four controllers alike): `on` (the product default,
    /// identified gains) or `off` (feedback only, as in the published comparison; scale 0).
    /// Also honoured by `--tune`: `off` tunes every controller without feed-forward.
    #[arg(long, value_enum, default_value = "on")]
    pub feedforward: OnOff,
    /// Print the result as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// The runtime's following-error limit of each axis, µm.
    #[arg(long, default_value_t = crate::xy::FOLLOWING_ERROR_LIMIT_UM)]
    pub following_error_um: f32,
    /// Exit 0 even when the runtime latched a fault (by default the exit code is 3).
    #[arg(long)]
    pub allow_fault: bool,
    /// Run the documented tuning procedure (docs/npid.md): prints every evaluated
    /// setting and the chosen gains of each controller as TOML (`--controller C`: only
    /// C's part of the procedure).
    #[arg(long)]
    pub tune: bool,
    /// Y's valve flow at run time against the machine the feed-forward was identified
    /// on (a drift: worn valve, another valve of the series), ×.
    #[arg(long, default_value_t = 1.0, conflicts_with = "tune")]
    pub y_flow: f64,
    /// Y's moving mass at run time against the identified machine (tooling), ×.
    #[arg(long, default_value_t = 1.0, conflicts_with = "tune")]
    pub y_mass: f64,
}

/// A switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// Runs the sub-command.
pub fn run(args: &Args) -> Result<()> {
    if args.tune {
        let ff_on = args.feedforward == OnOff::On;
        let tuned = crate::xy::tune::tune(args.controller, ff_on, &mut |l| println!("{l}"))?;
        for (kind, g) in tuned {
            println!("# chosen for {}\n{}", kind.name(), toml::to_string(&g)?);
        }
        return Ok(());
    }
    let mut gains: crate::xy::gains::Gains = match &args.gains {
        Some(f) => {
            let text =
                std::fs::read_to_string(f).map_err(|e| anyhow::anyhow!("{}: {e}", f.display()))?;
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", f.display()))?
        }
        None => crate::xy::gains::Gains::default(),
    };
    if args.feedforward == OnOff::Off {
        gains.feedforward.scale = 0.0;
    }
    let s = XyScenario {
        gains,
        path: args.path,
        controller: args.controller.unwrap_or(ControllerKind::Nccc),
        feed_mm_per_s: args.feed_mm_per_s,
        radius_mm: args.radius_mm,
        disturbance: args.disturbance_n.zip(args.disturbance_at_s),
        following_error_um: args.following_error_um,
        y_drift: crate::xy::YDrift {
            y_flow: args.y_flow,
            y_mass: args.y_mass,
        },
    };
    let r = simulate(&s)?;
    if let Some(p) = &args.plot {
        plot(&r, p, args.error_scale)?;
    }
    if let Some(p) = &args.csv {
        write_csv(&r, p)?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&r)?);
    } else {
        println!(
            "{} / {}: contour error max {:.1} µm, rms {:.1} µm; tracking max x {:.1} µm, y {:.1} µm",
            r.path,
            r.controller,
            r.max_contour_error_um,
            r.rms_contour_error_um,
            r.max_tracking_error_um.x,
            r.max_tracking_error_um.y
        );
        let at = |a: &crate::xy::PeakAt| {
            format!(
                "at {:.3} s, path normal {:.1}° from +X ({:.1}° off the nearest axis)",
                a.t_s, a.normal_deg, a.normal_off_axis_deg
            )
        };
        println!("max contour error {}", at(&r.max_contour_error_at));
        if let (Some(d), Some(a)) = (r.disturbance_peak_contour_error_um, &r.disturbance_peak_at) {
            println!(
                "peak contour error within 1 s of the load step: {d:.1} µm {}",
                at(a)
            );
        }
        println!(
            "largest valve command {:.0} LSB; contour-error sign changes {:.1} /s",
            r.max_command_lsb, r.contour_sign_changes_per_s
        );
        for f in &r.faults {
            println!("{}", super::run::fault_line(f));
        }
    }
    if let (Some(first), false) = (r.faults.first(), args.allow_fault) {
        return Err(super::run::FaultLatched {
            first: super::run::fault_line(first),
            count: r.faults.len(),
        }
        .into());
    }
    Ok(())
}

/// One row per period: `t_s,ref_x_um,ref_y_um,act_x_um,act_y_um,eps_um,ctl_eps_um,u_x_lsb,u_y_lsb`.
fn write_csv(r: &XyReport, file: &Path) -> Result<()> {
    let header = [
        "t_s",
        "ref_x_um",
        "ref_y_um",
        "act_x_um",
        "act_y_um",
        "eps_um",
        "ctl_eps_um",
        "u_x_lsb",
        "u_y_lsb",
    ];
    let mut o = crate::csvout::CsvOut::new(Vec::new(), header)?;
    for p in &r.trace {
        let f2 = |v: f64| format!("{v:.2}");
        let f3 = |v: f64| format!("{v:.3}");
        o.row([
            f3(p.t_s),
            f2(p.reference_um[0]),
            f2(p.reference_um[1]),
            f2(p.actual_um[0]),
            f2(p.actual_um[1]),
            f3(p.contour_um),
            f3(p.controller_contour_um),
            f2(p.command_lsb[0]),
            f2(p.command_lsb[1]),
        ])?;
    }
    crate::csvout::save(file, &o.text())
}

fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for x in v {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !(lo.is_finite() && hi.is_finite()) || lo >= hi {
        return (lo.min(0.0) - 1.0, hi.max(0.0) + 1.0);
    }
    let pad = (hi - lo) * 0.05;
    (lo - pad, hi + pad)
}

fn parse_magnify(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(k) if k.is_finite() && (1.0..=1e6).contains(&k) => Ok(k),
        _ => Err(format!(
            "{s:?}: a magnification is a number from 1 to 1 000 000"
        )),
    }
}

/// Widens the shorter of two ranges so that one mm is as long on both axes of a
/// `w × h`-pixel plotting area (a circle is drawn as a circle).
fn equal_scale(x: (f64, f64), y: (f64, f64), w: f64, h: f64) -> ((f64, f64), (f64, f64)) {
    let (sx, sy) = ((x.1 - x.0) / w, (y.1 - y.0) / h);
    let s = sx.max(sy);
    let widen = |r: (f64, f64), px: f64| {
        let c = 0.5 * (r.0 + r.1);
        (c - 0.5 * s * px, c + 0.5 * s * px)
    };
    (widen(x, w), widen(y, h))
}

/// Three panels: X–Y path (mm, equal scales; with `magnify`, the actual path's deviation
/// × that factor too), exact and controller contour error (µm), commands (LSB).
fn plot(r: &XyReport, file: &Path, magnify: Option<f64>) -> Result<()> {
    use crate::plot::{legend_entry, with_legend, LEGEND_W};
    let root = SVGBackend::new(file, (1000 + LEGEND_W, 1100)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!("{} — {}", r.path, r.controller),
        ("sans-serif", 20),
    )?;
    let (top, rest) = root.split_vertically(500);
    let (mid, bot) = rest.split_vertically(300);
    // Each panel's legend in a column right of it, never over the data.
    let ((top, top_l), (mid, mid_l), (bot, bot_l)) =
        (with_legend(&top), with_legend(&mid), with_legend(&bot));
    let tr = &r.trace;
    let (tw, th) = top.dim_in_pixel();
    // The plotting area: the panel less its margins (8 px) and label areas (50, 28 px).
    let ((x0, x1), (y0, y1)) = equal_scale(
        bounds(tr.iter().map(|s| s.reference_um[0] / 1000.0)),
        bounds(tr.iter().map(|s| s.reference_um[1] / 1000.0)),
        f64::from(tw) - 66.0,
        f64::from(th) - 44.0,
    );
    let mut c = ChartBuilder::on(&top)
        .margin(8)
        .x_label_area_size(28)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    c.configure_mesh()
        .x_desc("x (mm)")
        .y_desc("y (mm)")
        .x_label_formatter(&crate::plot::tick_format(x0, x1))
        .y_label_formatter(&crate::plot::tick_format(y0, y1))
        .draw()?;
    c.draw_series(LineSeries::new(
        tr.iter()
            .map(|s| (s.reference_um[0] / 1000.0, s.reference_um[1] / 1000.0)),
        BLUE,
    ))?;
    legend_entry(&top_l, 0, "reference", BLUE)?;
    c.draw_series(LineSeries::new(
        tr.iter()
            .map(|s| (s.actual_um[0] / 1000.0, s.actual_um[1] / 1000.0)),
        RED,
    ))?;
    legend_entry(&top_l, 1, "actual", RED)?;
    if let Some(k) = magnify {
        let green = RGBColor(44, 160, 44);
        let mag = |s: &crate::xy::Sample, i: usize| {
            (s.reference_um[i] + k * (s.actual_um[i] - s.reference_um[i])) / 1000.0
        };
        c.draw_series(LineSeries::new(
            tr.iter().map(|s| (mag(s, 0), mag(s, 1))),
            green,
        ))?;
        legend_entry(&top_l, 2, &format!("actual, deviation × {k}"), green)?;
    }
    let t1 = tr.last().map(|s| s.t_s).unwrap_or(1.0).max(1e-3);
    let (e0, e1) = bounds(
        tr.iter()
            .flat_map(|s| [s.contour_um, s.controller_contour_um]),
    );
    let mut c = ChartBuilder::on(&mid)
        .margin(8)
        .x_label_area_size(28)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t1, e0..e1)?;
    c.configure_mesh().x_desc("t (s)").y_desc("ε (µm)").draw()?;
    c.draw_series(LineSeries::new(
        tr.iter().map(|s| (s.t_s, s.contour_um)),
        RED,
    ))?;
    legend_entry(&mid_l, 0, "exact ε", RED)?;
    c.draw_series(LineSeries::new(
        tr.iter().map(|s| (s.t_s, s.controller_contour_um)),
        BLUE,
    ))?;
    legend_entry(&mid_l, 1, "controller's ε", BLUE)?;
    let (u0, u1) = bounds(tr.iter().flat_map(|s| s.command_lsb));
    let mut c = ChartBuilder::on(&bot)
        .margin(8)
        .x_label_area_size(28)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t1, u0..u1)?;
    c.configure_mesh().x_desc("t (s)").y_desc("LSB").draw()?;
    for (i, col) in [BLUE, RED].into_iter().enumerate() {
        c.draw_series(LineSeries::new(
            tr.iter().map(|s| (s.t_s, s.command_lsb[i])),
            col,
        ))?;
        legend_entry(&bot_l, i, if i == 0 { "U1 (x)" } else { "U2 (y)" }, col)?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod plot_tests {
    use super::*;

    #[test]
    fn a_circle_is_drawn_as_a_circle_and_magnification_is_bounded() {
        // 100 mm × 20 mm of data on a 900 × 450 px area: y widened to 50 mm.
        let ((x0, x1), (y0, y1)) = equal_scale((0.0, 100.0), (40.0, 60.0), 900.0, 450.0);
        assert!(((x1 - x0) / 900.0 - (y1 - y0) / 450.0).abs() < 1e-12);
        assert_eq!((x0, x1), (0.0, 100.0));
        assert!((y0 - 25.0).abs() < 1e-9 && (y1 - 75.0).abs() < 1e-9);
        assert_eq!(parse_magnify("200"), Ok(200.0));
        for bad in ["0.5", "-3", "nan", "1e9", "x"] {
            assert!(parse_magnify(bad).is_err(), "{bad}");
        }
    }
}
