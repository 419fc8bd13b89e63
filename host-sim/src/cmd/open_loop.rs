//! `host-sim open-loop`: drive one axis of the plant with a recorded valve command.
//!
//! For checking the model against a real machine: record the valve command and the
//! cylinder's response on the machine, replay the command here and compare.
//!
//! Input `--command-csv`: header `t,u`, then rows of time (s, strictly increasing, ≥ 0)
//! and normalised valve command `u ∈ [−1, 1]` (1 = full opening extending). The command
//! is held between rows (zero-order hold, as a DAC holds it); before the first row the
//! spool is commanded to 0. The simulation ends at the last row's time.
//!
//! Output `--csv`: `t,x_mm,v_mm_s,pA_bar,pB_bar,spool` every 1 ms (true plant values,
//! not the quantised sensor readings).

use crate::camfile::{csv_records, line_error, CsvRecords, TableError};
use crate::plant::HydraulicAxis;
use crate::scenario::Scenario;
use anyhow::Context as _;
use std::path::{Path, PathBuf};

/// Arguments of `host-sim open-loop`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recorded valve command: CSV `t,u` (s, normalised −1…1), held between rows.
    #[arg(long, value_name = "FILE")]
    pub command_csv: PathBuf,
    /// Scenario whose plant is driven (default: the reference machine of PLANT.md).
    #[arg(long, value_name = "S.toml")]
    pub scenario: Option<PathBuf>,
    /// Axis of the scenario to drive (default: the first `[[axis]]`).
    #[arg(long)]
    pub axis: Option<String>,
    /// Initial piston position, mm (default: the axis' `x0_mm`, else mid-stroke).
    #[arg(long, value_name = "X")]
    pub x0_mm: Option<f64>,
    /// Output CSV: `t,x_mm,v_mm_s,pA_bar,pB_bar,spool` every 1 ms.
    #[arg(long, value_name = "OUT")]
    pub csv: PathBuf,
}

/// One output row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// Piston position, mm.
    pub x_mm: f64,
    /// Piston speed, mm/s.
    pub v_mm_s: f64,
    /// Chamber-A pressure, bar.
    pub pa_bar: f64,
    /// Chamber-B pressure, bar.
    pub pb_bar: f64,
    /// Normalised spool position.
    pub spool: f64,
}

/// Parses a `t,u` command recording; errors name the line.
pub fn parse_command(text: &str, path: &Path) -> Result<Vec<(f64, f64)>, TableError> {
    let at = |line: usize, reason: String| line_error(path, line, reason);
    let CsvRecords {
        header_line: hl,
        header,
        rows,
    } = csv_records(text, path, "t,u")?;
    if header != ["t", "u"] {
        return Err(at(
            hl,
            format!("header must be `t,u`, found `{}`", header.join(",")),
        ));
    }
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (line, f) in rows {
        if f.len() != 2 {
            return Err(at(line, format!("{} fields, expected 2 (t,u)", f.len())));
        }
        let num = |s: &str, name: &str| -> Result<f64, TableError> {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    at(
                        line,
                        format!("column `{name}`: `{s}` is not a finite number"),
                    )
                })
        };
        let (t, u) = (num(&f[0], "t")?, num(&f[1], "u")?);
        if t < 0.0 {
            return Err(at(line, format!("t = {t} is negative")));
        }
        if let Some(&(tp, _)) = out.last() {
            if t <= tp {
                return Err(at(
                    line,
                    format!("t = {t} does not increase (previous {tp})"),
                ));
            }
        }
        if !(-1.0..=1.0).contains(&u) {
            return Err(at(line, format!("u = {u} is outside [−1, 1]")));
        }
        out.push((t, u));
    }
    if out.is_empty() {
        return Err(TableError::File {
            path: path.to_path_buf(),
            reason: "no command rows after the header".into(),
        });
    }
    Ok(out)
}

/// Drives `axis` with the held command `cmd` (`(t, u)` rows) by RK4 steps of `step_s`
/// until the last row's time, sampling every `every_s`.
pub fn simulate(
    axis: &mut HydraulicAxis,
    cmd: &[(f64, f64)],
    step_s: f64,
    every_s: f64,
) -> Vec<Sample> {
    let t_end = cmd.last().map_or(0.0, |c| c.0);
    let n_steps = (t_end / step_s).round() as u64;
    let every = ((every_s / step_s).round() as u64).max(1);
    let mut out = Vec::with_capacity((n_steps / every + 1) as usize);
    let mut j = 0usize; // rows[..j] have started
    let mut u = 0.0;
    for k in 0..=n_steps {
        let t = k as f64 * step_s;
        while j < cmd.len() && cmd[j].0 <= t + 1e-9 * step_s {
            u = cmd[j].1;
            j += 1;
        }
        if k % every == 0 {
            let (pa, pb) = axis.pressures_pa();
            out.push(Sample {
                t,
                x_mm: axis.x_m() * 1e3,
                v_mm_s: axis.v_m_per_s() * 1e3,
                pa_bar: pa * 1e-5,
                pb_bar: pb * 1e-5,
                spool: axis.spool(),
            });
        }
        if k < n_steps {
            axis.step(u, step_s);
        }
    }
    out
}

/// The scenario of `--scenario` (default: the reference machine) and its axis `--axis`
/// (default: the first) — `open-loop`'s and `identify`'s choice of the axis.
pub fn scenario_axis(
    scenario: Option<&Path>,
    axis: Option<&str>,
) -> anyhow::Result<(Scenario, crate::scenario::AxisCfg)> {
    let s = match scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let a = match axis {
        Some(name) => s
            .axes
            .iter()
            .find(|a| a.name == name)
            .with_context(|| format!("--axis {name}: the scenario has no axis of that name"))?,
        None => s.axes.first().context("the scenario has no axis")?,
    }
    .clone();
    Ok((s, a))
}

/// Runs `host-sim open-loop`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let (scenario, axis_cfg) = scenario_axis(args.scenario.as_deref(), args.axis.as_deref())?;
    let axis_cfg = &axis_cfg;
    let stroke = axis_cfg.cylinder.stroke_mm;
    let x0 = args.x0_mm.or(axis_cfg.x0_mm).unwrap_or(0.5 * stroke);
    if !(0.0..=stroke).contains(&x0) {
        anyhow::bail!("--x0-mm {x0}: outside the stroke [0, {stroke}] mm");
    }
    let text = std::fs::read_to_string(&args.command_csv).map_err(|source| TableError::Io {
        path: args.command_csv.clone(),
        source,
    })?;
    let cmd = parse_command(&text, &args.command_csv)?;
    let mut axis = axis_cfg.plant(scenario.supply(), x0 * 1e-3);
    let samples = simulate(&mut axis, &cmd, scenario.step_s(), 1e-3);
    let header = ["t", "x_mm", "v_mm_s", "pA_bar", "pB_bar", "spool"];
    let mut o = crate::csvout::CsvOut::new(Vec::new(), header)?;
    for r in &samples {
        o.row([
            format!("{:.4}", r.t),
            format!("{:.6}", r.x_mm),
            format!("{:.6}", r.v_mm_s),
            format!("{:.5}", r.pa_bar),
            format!("{:.5}", r.pb_bar),
            format!("{:.6}", r.spool),
        ])?;
    }
    crate::csvout::save(&args.csv, &o.text())?;
    eprintln!(
        "open-loop: axis `{}`, {} rows of command, {:.3} s simulated, {} samples → {}",
        axis_cfg.name,
        cmd.len(),
        samples.last().map_or(0.0, |r| r.t),
        samples.len(),
        args.csv.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_errors_name_the_line() {
        let e = |s: &str| {
            parse_command(s, Path::new("c.csv"))
                .unwrap_err()
                .to_string()
        };
        assert!(e("").contains("empty file"));
        assert!(e("time,u\n").contains("c.csv:1: header must be `t,u`"));
        assert!(e("t,u\n0,0\n0,0.1\n").contains("c.csv:3: t = 0 does not increase"));
        assert!(e("t,u\n0,2\n").contains("c.csv:2: u = 2 is outside"));
        assert!(e("t,u\n0,x\n").contains("c.csv:2: column `u`"));
        assert!(e("t,u\n0\n").contains("c.csv:2: 1 fields"));
        assert!(e("t,u\n").contains("no command rows"));
        assert_eq!(
            parse_command("t,u\n0,0.5\n0.1,-0.5\n", Path::new("c")).unwrap(),
            [(0.0, 0.5), (0.1, -0.5)]
        );
    }
}
