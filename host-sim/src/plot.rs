//! SVG plots of a run's trace (plotters, SVG backend only: no system dependencies).
//!
//! One figure per run, panels stacked vertically: for each follower axis the table
//! target and the actual position, then its tracking error; the valve commands of every
//! axis; for each force axis the force and its reference.

use crate::sim::{RunReport, Trace};
use plotters::prelude::*;
use std::path::Path;

const PALETTE: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// One panel of a figure: its title, y-axis label and named series (on the figure's
/// common time axis).
pub struct Panel {
    /// Title.
    pub title: String,
    /// y-axis label (with the unit).
    pub y_label: String,
    /// Named series, one value per time sample.
    pub series: Vec<(String, Vec<f64>)>,
}

fn range(series: &[(String, Vec<f64>)]) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for v in series.iter().flat_map(|s| s.1.iter()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (lo - pad, hi + pad)
}

fn panels(r: &RunReport, tr: &Trace) -> Vec<Panel> {
    let mut out = Vec::new();
    let col = |n: &str| tr.column(n).unwrap_or_default();
    let mut commands = Vec::new();
    for a in &r.axes {
        let n = &a.name;
        if tr.columns.contains(&format!("{n}_target_mm")) {
            out.push(Panel {
                title: format!("{n}: table at the actual master vs actual position"),
                y_label: "mm".into(),
                series: vec![
                    ("target".into(), col(&format!("{n}_target_mm"))),
                    ("actual".into(), col(&format!("{n}_x_mm"))),
                ],
            });
            out.push(Panel {
                title: format!("{n}: tracking error (target − actual)"),
                y_label: "µm".into(),
                series: vec![("error".into(), col(&format!("{n}_error_um")))],
            });
        }
        commands.push((n.clone(), col(&format!("{n}_u"))));
    }
    out.push(Panel {
        title: "valve commands (1 = full opening)".into(),
        y_label: "u".into(),
        series: commands,
    });
    for a in &r.axes {
        let n = &a.name;
        if tr.columns.contains(&format!("{n}_force_n")) {
            out.push(Panel {
                title: format!("{n}: force (A_A·p_A − A_B·p_B) and its reference"),
                y_label: "kN".into(),
                series: vec![
                    (
                        "reference".into(),
                        col(&format!("{n}_force_ref_n"))
                            .iter()
                            .map(|f| f * 1e-3)
                            .collect(),
                    ),
                    (
                        "force".into(),
                        col(&format!("{n}_force_n"))
                            .iter()
                            .map(|f| f * 1e-3)
                            .collect(),
                    ),
                ],
            });
        }
    }
    out
}

/// The board's per-slave panels of a recording (`trace`, `capture`): for each of `n`
/// slaves its target and actual position (mm), then every slave's following error (µm)
/// and valve command (LSB). `target(i)`, `actual(i)` are slave i's series in mm,
/// `dac(i)` in LSB.
pub fn slave_panels(
    n: usize,
    target: &dyn Fn(usize) -> Vec<f64>,
    actual: &dyn Fn(usize) -> Vec<f64>,
    dac: &dyn Fn(usize) -> Vec<f64>,
) -> Vec<Panel> {
    let mut ps: Vec<Panel> = (0..n)
        .map(|i| Panel {
            title: format!("slave {i}: target and actual position"),
            y_label: "mm".into(),
            series: vec![
                (format!("target {i}"), target(i)),
                (format!("actual {i}"), actual(i)),
            ],
        })
        .collect();
    ps.push(Panel {
        title: "following error (target − actual)".into(),
        y_label: "µm".into(),
        series: (0..n)
            .map(|i| {
                let e = target(i)
                    .iter()
                    .zip(actual(i))
                    .map(|(t, a)| (t - a) * 1000.0)
                    .collect();
                (format!("error {i}"), e)
            })
            .collect(),
    });
    ps.push(Panel {
        title: "valve commands".into(),
        y_label: "DAC LSB".into(),
        series: (0..n).map(|i| (format!("dac {i}"), dac(i))).collect(),
    });
    ps
}

/// Width of the legend column right of each panel, px.
pub const LEGEND_W: u32 = 170;

/// A panel's area split into the chart and, right of it, its legend column
/// ([`LEGEND_W`] px): the legend never covers the data.
pub fn with_legend<DB: DrawingBackend>(
    a: &DrawingArea<DB, plotters::coord::Shift>,
) -> (
    DrawingArea<DB, plotters::coord::Shift>,
    DrawingArea<DB, plotters::coord::Shift>,
) {
    let (w, _) = a.dim_in_pixel();
    a.split_horizontally(w.saturating_sub(LEGEND_W))
}

/// Legend entry `i` (a line in `color`, then `name`) in a panel's legend column.
pub fn legend_entry<DB: DrawingBackend>(
    legend: &DrawingArea<DB, plotters::coord::Shift>,
    i: usize,
    name: &str,
    color: RGBColor,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let y = 40 + 18 * i as i32;
    legend
        .draw(&PathElement::new(
            vec![(4, y), (24, y)],
            color.stroke_width(2),
        ))
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    legend
        .draw(&Text::new(name, (30, y - 7), ("sans-serif", 13)))
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    Ok(())
}

/// At most this many buckets per series: each keeps its minimum and maximum, so peaks
/// survive the thinning (a 32 s trace at 1 ms is 32 000 points a series).
const BUCKETS: usize = 1500;

/// Min/max decimation of `(t, v)` to at most `2·BUCKETS` points.
fn thin(t: &[f64], v: &[f64]) -> Vec<(f64, f64)> {
    let n = t.len().min(v.len());
    let per = n.div_ceil(BUCKETS).max(1);
    if per <= 2 {
        return t.iter().copied().zip(v.iter().copied()).collect();
    }
    let mut out = Vec::with_capacity(2 * BUCKETS + 2);
    let mut i = 0;
    while i < n {
        let end = (i + per).min(n);
        let (mut lo, mut hi) = (i, i);
        for j in i..end {
            if v[j] < v[lo] {
                lo = j;
            }
            if v[j] > v[hi] {
                hi = j;
            }
        }
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out.push((t[a], v[a]));
        if b != a {
            out.push((t[b], v[b]));
        }
        i = end;
    }
    out
}

/// Writes the SVG figure of a run with a trace to `path`.
pub fn plot_run(r: &RunReport, path: &Path) -> anyhow::Result<()> {
    let tr = r
        .trace
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("the run has no trace to plot"))?;
    let t = tr.column("t_s").unwrap_or_default();
    let title = format!(
        "{} — {} @ {} µs (statistics from {} s: the dashed line)",
        r.scenario,
        r.controller.name(),
        r.period_us,
        r.error_skip_s
    );
    plot_panels(
        path,
        &title,
        ("t (s)", &t),
        &panels(r, tr),
        Some(r.error_skip_s),
    )?;
    // The same panels against the master angle: a cam table's error belongs to where
    // on the table it happens.
    if let Some(m) = tr.column("master_deg") {
        let p = path.with_extension("master.svg");
        let ps = panels(r, tr);
        plot_panels(
            &p,
            &format!("{} — against the master", r.scenario),
            ("master (°)", &m),
            &ps,
            None,
        )?;
    }
    Ok(())
}

/// Tick labels for an axis spanning `lo … hi`: the decimals that tell ticks about a tenth
/// of the span apart, and no sign on zero (`-0.0` → `0.0`).
pub fn tick_format(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let step = ((hi - lo).abs() / 10.0).max(1e-12);
    let decimals = (-step.log10().floor()).clamp(0.0, 9.0) as usize;
    move |v: &f64| {
        let s = format!("{v:.decimals$}");
        match s.strip_prefix('-') {
            Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
            _ => s,
        }
    }
}

/// Writes a figure of stacked `panels` over the common x samples `(label, x)` (time, or
/// the master for a cam table) to `path`, each panel with its legend; `marker` draws a
/// vertical line at that x (a trigger).
pub fn plot_panels(
    path: &Path,
    title: &str,
    (x_desc, t): (&str, &[f64]),
    ps: &[Panel],
    marker: Option<f64>,
) -> anyhow::Result<()> {
    let h_panel = 260u32;
    let height = 40 + h_panel * ps.len() as u32;
    let root = SVGBackend::new(path, (1100 + LEGEND_W, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 20))?;
    let areas = root.split_evenly((ps.len(), 1));
    let x_fmt = tick_format(
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0),
    );
    let (t0, t1) = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0).max(1e-9),
    );
    for (area, p) in areas.iter().zip(ps) {
        let (lo, hi) = range(&p.series);
        let (area, legend) = with_legend(area);
        let mut chart = ChartBuilder::on(&area)
            .caption(&p.title, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t1, lo..hi)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(p.y_label.as_str())
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&tick_format(lo, hi))
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        for (i, (name, v)) in p.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            chart.draw_series(LineSeries::new(thin(t, v), color.stroke_width(1)))?;
            legend_entry(&legend, i, name, color)?;
        }
        if let Some(m) = marker {
            let dashed = DashedLineSeries::new([(m, lo), (m, hi)], 6, 4, BLACK.mix(0.6).into());
            chart.draw_series(dashed)?;
        }
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_carry_no_negative_zero_and_enough_decimals() {
        let f = tick_format(-1.0, 1.0);
        assert_eq!(f(&-0.0), "0.0");
        assert_eq!(f(&-0.04), "0.0");
        assert_eq!(f(&-0.2), "-0.2");
        let g = tick_format(0.0, 500.0);
        assert_eq!(g(&250.0), "250");
        let h = tick_format(0.0, 0.01);
        assert_eq!(h(&0.005), "0.005");
    }
}
