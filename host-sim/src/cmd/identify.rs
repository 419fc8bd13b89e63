//! `host-sim identify`: fit an axis' valve, oil, mass and friction to an open-loop
//! recording (`crate::identify`) and write them as a machine file in the scenario
//! format (`run`, `robust` and `run --tune` read it).
//!
//! The recording is either
//!
//! - **the board's capture** of a test move (`host-sim motion test … --csv REC.csv`, or
//!   any `host-sim capture` CSV: columns `t_s`, `dac<i>`, `actual<i>_mm`, `pa<i>_bar`,
//!   `pb<i>_bar` of slave `--slave i`) — fitted without a spool signal from the
//!   quantised readings (`crate::identify::spoolless`); `--trace` may be given several
//!   times (e.g. a step, a chirp and a PRBS test), fitted together; or
//! - **an open-loop recording** with the true plant signals: one CSV with the header
//!   `t,u,x_mm,v_mm_s,pA_bar,pB_bar,spool` (s, normalised command, mm, mm/s, bar, bar,
//!   normalised spool) — `host-sim open-loop`'s output joined with its command — or
//!   `open-loop`'s output alone with `--command-csv` (the `t,u` command it was driven
//!   with, held between rows).

use crate::cmd::open_loop::parse_command;
use crate::identify::spoolless::{identify_spoolless, Recording};
use crate::identify::{identify, Identified, Sample};
use crate::scenario::Scenario;
use anyhow::Context as _;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `host-sim identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The recording: a capture CSV of the board (`motion test`, `capture`; repeat
    /// `--trace` to fit several together), or an open-loop CSV
    /// `t,u,x_mm,v_mm_s,pA_bar,pB_bar,spool` (or without `u`, with `--command-csv`).
    #[arg(long, value_name = "REC.csv", required = true)]
    pub trace: Vec<PathBuf>,
    /// A capture's slave (0-based) [0].
    #[arg(long)]
    pub slave: Option<usize>,
    /// A capture: the piston's position in its cylinder (0 = retracted) minus the
    /// board's position, mm [0: the board's frame is the cylinder's]. The chamber
    /// volumes depend on it.
    #[arg(long, allow_negative_numbers = true)]
    pub position_offset_mm: Option<f64>,
    /// A capture: the valve's null code (the board's `axis/<n>/valve/null_lsb`), LSB [0].
    #[arg(long, allow_negative_numbers = true)]
    pub valve_null_lsb: Option<f64>,
    /// A capture: how much later than the position the board's pressures were sampled,
    /// ms [0]. The viscous friction is sensitive to it (module docs of
    /// `identify::spoolless`).
    #[arg(long, allow_negative_numbers = true)]
    pub pressure_skew_ms: Option<f64>,
    /// The `t,u` command the recording was driven with, when the trace has no `u` column.
    #[arg(long, value_name = "CMD.csv")]
    pub command_csv: Option<PathBuf>,
    /// The machine's known geometry and supply (default: the reference machine).
    #[arg(long, value_name = "S.toml")]
    pub scenario: Option<PathBuf>,
    /// Axis of the scenario (default: the first).
    #[arg(long)]
    pub axis: Option<String>,
    /// Write the identified machine here (scenario format).
    #[arg(long, value_name = "MACHINE.toml")]
    pub out: Option<PathBuf>,
    /// Print one JSON object: every parameter with its value and 1σ uncertainty.
    #[arg(long)]
    pub json: bool,
}

/// Reads the recording; errors name the file and line.
fn read_recording(trace: &Path, command: Option<&Path>) -> anyhow::Result<Vec<Sample>> {
    let mut r = csv::Reader::from_path(trace)
        .with_context(|| format!("reading the recording {}", trace.display()))?;
    let header: Vec<String> = r
        .headers()
        .with_context(|| format!("{}: no header", trace.display()))?
        .iter()
        .map(str::to_string)
        .collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let need = ["t", "x_mm", "v_mm_s", "pA_bar", "pB_bar", "spool"];
    let mut idx = Vec::new();
    for n in need {
        idx.push(col(n).with_context(|| {
            format!(
                "{}: no `{n}` column (header: {}); expected t,u,x_mm,v_mm_s,pA_bar,pB_bar,spool",
                trace.display(),
                header.join(",")
            )
        })?);
    }
    let u_col = col("u");
    let cmd = match (u_col, command) {
        (Some(_), _) => None,
        (None, Some(p)) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("reading the command {}", p.display()))?;
            Some(parse_command(&text, p)?)
        }
        (None, None) => anyhow::bail!(
            "{}: no `u` column; give the command it was driven with (--command-csv)",
            trace.display()
        ),
    };
    let mut out = Vec::new();
    let mut cmd_at = 0usize; // the command row in force (times increase: a walking index)
    for (k, rec) in r.records().enumerate() {
        let line = k + 2;
        let rec = rec.with_context(|| format!("{}:{line}", trace.display()))?;
        let f = |i: usize, name: &str| -> anyhow::Result<f64> {
            rec.get(i)
                .and_then(|s| s.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .with_context(|| format!("{}:{line}: `{name}` is not a number", trace.display()))
        };
        let t = f(idx[0], "t")?;
        let u = match (&cmd, u_col) {
            (_, Some(i)) => f(i, "u")?,
            (Some(c), None) => {
                while c.get(cmd_at + 1).is_some_and(|(tc, _)| *tc <= t + 1e-9) {
                    cmd_at += 1;
                }
                c.get(cmd_at)
                    .filter(|(tc, _)| *tc <= t + 1e-9)
                    .map_or(0.0, |c| c.1)
            }
            (None, None) => 0.0,
        };
        if let Some(prev) = out.last().map(|s: &Sample| s.t) {
            anyhow::ensure!(
                t > prev,
                "{}:{line}: time {t} s does not increase (previous {prev} s)",
                trace.display()
            );
        }
        out.push(Sample {
            t,
            u,
            x_m: f(idx[1], "x_mm")? * 1e-3,
            v_m_s: f(idx[2], "v_mm_s")? * 1e-3,
            pa_pa: f(idx[3], "pA_bar")? * 1e5,
            pb_pa: f(idx[4], "pB_bar")? * 1e5,
            spool: f(idx[5], "spool")?,
        });
    }
    Ok(out)
}

/// Whether `path` is a capture (its header has `t_s` and `dac0`).
fn is_capture(path: &Path) -> anyhow::Result<bool> {
    let mut r = csv::Reader::from_path(path)
        .with_context(|| format!("reading the recording {}", path.display()))?;
    let h = r
        .headers()
        .with_context(|| format!("{}: no header", path.display()))?;
    Ok(h.iter().any(|c| c == "t_s") && h.iter().any(|c| c == "dac0"))
}

/// Reads slave `slave` of a capture CSV (`capture::csv`'s columns): the position moved by
/// `offset_mm` into the cylinder's frame, the valve command less the null `null_lsb`
/// (LSB) over the DAC's 2 047, a tick driven when `valve_power` is 1 and the state is
/// manual, following or holding (when the capture has those columns); the ticks must be
/// consecutive (`tick`, when present) and evenly spaced. Errors name the file, the line
/// and the column.
pub fn read_capture(
    path: &Path,
    slave: usize,
    offset_mm: f64,
    null_lsb: f64,
) -> anyhow::Result<Recording> {
    let mut r = csv::Reader::from_path(path)
        .with_context(|| format!("reading the recording {}", path.display()))?;
    let header: Vec<String> = r
        .headers()
        .with_context(|| format!("{}: no header", path.display()))?
        .iter()
        .map(str::to_string)
        .collect();
    let names = [
        "t_s".to_string(),
        format!("dac{slave}"),
        format!("actual{slave}_mm"),
        format!("pa{slave}_bar"),
        format!("pb{slave}_bar"),
    ];
    let mut idx = Vec::new();
    for n in &names {
        idx.push(header.iter().position(|h| h == n).with_context(|| {
            format!(
                "{}: no `{n}` column — the capture has no slave {slave} (header: {})",
                path.display(),
                header.join(",")
            )
        })?);
    }
    let col = |n: &str| header.iter().position(|h| h == n);
    let (tick_col, state_col, power_col) = (col("tick"), col("state"), col("valve_power"));
    let mut rec = Recording::default();
    let mut t = Vec::new();
    let mut last_tick: Option<u32> = None;
    for (k, row) in r.records().enumerate() {
        let line = k + 2;
        let row = row.with_context(|| format!("{}:{line}", path.display()))?;
        let f = |j: usize| -> anyhow::Result<f64> {
            row.get(idx[j])
                .and_then(|s| s.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .with_context(|| {
                    format!("{}:{line}: `{}` is not a number", path.display(), names[j])
                })
        };
        if let Some(c) = tick_col {
            let tick: u32 = row
                .get(c)
                .and_then(|s| s.trim().parse().ok())
                .with_context(|| format!("{}:{line}: `tick` is not a tick", path.display()))?;
            if let Some(prev) = last_tick {
                // The board's tick counter is 32 bits: it may wrap inside a capture.
                anyhow::ensure!(
                    tick == prev.wrapping_add(1),
                    "{}:{line}: tick {tick} does not follow {prev}: the capture is not one \
                     row per tick",
                    path.display()
                );
            }
            last_tick = Some(tick);
        }
        t.push(f(0)?);
        let dac = f(1)?;
        anyhow::ensure!(
            dac.abs() <= 2047.0,
            "{}:{line}: dac{slave} {dac} is outside the DAC's ±2047",
            path.display()
        );
        rec.u.push(((dac - null_lsb) / 2047.0).clamp(-1.0, 1.0));
        rec.x_m.push((f(2)? + offset_mm) * 1e-3);
        rec.pa_pa.push(f(3)? * 1e5);
        rec.pb_pa.push(f(4)? * 1e5);
        let powered = power_col.is_none_or(|c| row.get(c).map(str::trim) == Some("1"));
        let controlled = state_col.is_none_or(|c| {
            matches!(
                row.get(c).map(str::trim),
                Some("manual" | "following" | "holding" | "holding_end")
            )
        });
        rec.driven.push(powered && controlled);
    }
    anyhow::ensure!(t.len() >= 2, "{}: fewer than two rows", path.display());
    let period = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    anyhow::ensure!(
        period > 0.0,
        "{}: `t_s` does not increase ({} s … {} s)",
        path.display(),
        t[0],
        t[t.len() - 1]
    );
    for (k, w) in t.windows(2).enumerate() {
        // Consecutive ticks prove it where the capture has them; else each step of
        // `t_s` (printed to 0.1 ms: two roundings) within 1 % of the period plus 0.1 ms.
        if tick_col.is_some() {
            break;
        }
        anyhow::ensure!(
            ((w[1] - w[0]) - period).abs() <= 0.01 * period + 1e-4,
            "{}:{}: the capture is not one row per tick (t_s {} after {})",
            path.display(),
            k + 3,
            w[1],
            w[0]
        );
    }
    anyhow::ensure!(
        rec.driven.iter().any(|&d| d),
        "{}: the valve was never powered and in control (valve_power, state)",
        path.display()
    );
    rec.period_s = period;
    Ok(rec)
}

/// The machine file: the scenario's supply and axis geometry with the fitted values (and
/// the board's control period, when fitted from its capture).
fn machine_toml(
    s: &Scenario,
    axis: &str,
    id: &Identified,
    source: &str,
    period_us: Option<u32>,
) -> String {
    let v = |n: &str| id.get(n).map_or(0.0, |p| p.value);
    let line = |n: &str, key: &str| -> String {
        id.get(n).map_or(String::new(), |p| {
            format!("{key} = {:.6e}   # fit residual σ {:.2e}\n", p.value, p.std)
        })
    };
    let mut o = String::new();
    let _ = writeln!(
        o,
        "# Identified by `host-sim identify` from {} ({} of {} samples used).\n\
         # The valve's flow gain per direction: extend {:.3} l/min, retract {:.3} l/min\n\
         # (rated at 35 bar; the model has one, their mean); overlap {:.4} of the travel\n\
         # (the model has none: a fitted overlap is not simulated);\n\
         # oil column at mid-stroke {:.1} Hz, damping {:.4}.{}",
        source,
        id.used_samples,
        id.samples,
        v("rated_flow_extend_l_per_min"),
        v("rated_flow_retract_l_per_min"),
        v("overlap"),
        v("hydraulic_frequency_hz"),
        v("hydraulic_damping"),
        id.get("valve_delay_ms").map_or(String::new(), |d| format!(
            "\n# Fitted without a spool signal: a delay of {:.3} ms before the valve \
             (not in the model: the controller's period is), lag 2ζ/ω + delay {:.3} ms.",
            d.value,
            v("valve_lag_ms")
        )),
    );
    let _ = writeln!(o, "name = \"{}_identified\"\n", s.name());
    if let Some(p) = period_us {
        let _ = writeln!(
            o,
            "[sim]\nperiod_us = {p}   # the board's, from the capture\n"
        );
    }
    let _ = writeln!(
        o,
        "[supply]\nsupply_bar = {}\ntank_bar = {}\nclamp_factor = {}\n",
        s.supply.supply_bar, s.supply.tank_bar, s.supply.clamp_factor
    );
    let Some(a) = s.axes.iter().find(|a| a.name == axis) else {
        return o;
    };
    let _ = writeln!(o, "[[axis]]\nname = \"{}\"\nrole = \"follower\"\n", a.name);
    o.push_str("[axis.valve]\n");
    o.push_str(&line("valve_bandwidth_hz", "bandwidth_hz"));
    o.push_str(&line("valve_damping", "damping"));
    let _ = writeln!(
        o,
        "rated_flow_l_per_min = {:.6e}\nrated_dp_bar = 35\nleakage_m3_per_s_pa = {}\n",
        0.5 * (v("rated_flow_extend_l_per_min") + v("rated_flow_retract_l_per_min")),
        a.valve.leakage_m3_per_s_pa
    );
    let c = &a.cylinder;
    let _ = writeln!(
        o,
        "[axis.cylinder]\nbore_mm = {}\nrod_mm = {}\nstroke_mm = {}\ndead_volume_a_l = {}\ndead_volume_b_l = {}\ncoulomb_smoothing_mm_per_s = {}",
        c.bore_mm, c.rod_mm, c.stroke_mm, c.dead_volume_a_l, c.dead_volume_b_l,
        c.coulomb_smoothing_mm_per_s
    );
    o.push_str(&line("bulk_modulus_pa", "bulk_modulus_pa"));
    o.push_str(&line("mass_kg", "mass_kg"));
    o.push_str(&line("viscous_n_s_per_m", "viscous_n_s_per_m"));
    o.push_str(&line("coulomb_n", "coulomb_n"));
    o.push_str(&line("load_n", "load_n"));
    o
}

/// Runs `host-sim identify`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let (s, a) =
        crate::cmd::open_loop::scenario_axis(args.scenario.as_deref(), args.axis.as_deref())?;
    let a = &a;
    if let Some(out) = &args.out {
        crate::csvout::writable(out)?;
    }
    let known = a.plant(s.supply(), 0.5 * a.cylinder.stroke_mm * 1e-3);
    let captures = args
        .trace
        .iter()
        .map(|p| is_capture(p))
        .collect::<anyhow::Result<Vec<bool>>>()?;
    let names = args
        .trace
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let mut board_period_us = None;
    let id = if captures.iter().all(|&c| c) {
        anyhow::ensure!(
            args.command_csv.is_none(),
            "--command-csv is for an open-loop recording; a capture has its command (dac)"
        );
        let null_lsb = args.valve_null_lsb.unwrap_or(0.0);
        anyhow::ensure!(
            null_lsb.is_finite() && null_lsb.abs() <= 2047.0,
            "--valve-null-lsb {null_lsb}: must be within ±2047"
        );
        let offset_mm = args.position_offset_mm.unwrap_or(0.0);
        anyhow::ensure!(
            offset_mm.is_finite() && offset_mm.abs() <= 8000.0,
            "--position-offset-mm {offset_mm}: must be within ±8000 mm"
        );
        let recs = args
            .trace
            .iter()
            .map(|p| read_capture(p, args.slave.unwrap_or(0), offset_mm, null_lsb))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let period = recs[0].period_s;
        anyhow::ensure!(
            recs.iter()
                .all(|r| (r.period_s - period).abs() <= 1e-3 * period),
            "the captures were recorded at different periods"
        );
        let skew_ms = args.pressure_skew_ms.unwrap_or(0.0);
        anyhow::ensure!(
            skew_ms.is_finite() && skew_ms.abs() <= 1e3 * period,
            "--pressure-skew-ms {skew_ms}: must be within one period ({} ms)",
            1e3 * period
        );
        // The machine file runs at the board's period (`tune` tunes for it).
        board_period_us = Some((period * 1e6).round() as u32);
        identify_spoolless(&known, &recs, skew_ms * 1e-3)
    } else {
        anyhow::ensure!(
            args.trace.len() == 1
                && args.slave.is_none()
                && args.position_offset_mm.is_none()
                && args.pressure_skew_ms.is_none()
                && args.valve_null_lsb.is_none(),
            "an open-loop recording is fitted alone (one --trace, no --slave or \
             --position-offset-mm, --pressure-skew-ms or --valve-null-lsb); {names} mixes \
             kinds or has several"
        );
        let rec = read_recording(&args.trace[0], args.command_csv.as_deref())?;
        identify(&known, &rec)
    }
    .with_context(|| format!("identifying axis `{}` from {names}", a.name))?;
    if args.json {
        println!("{}", serde_json::json!({ "axis": a.name, "fit": id }));
    } else {
        println!(
            "axis `{}`: {} of {} samples used",
            a.name, id.used_samples, id.samples
        );
        for p in &id.params {
            println!("  {:<30} {:>14.6e} ± {:.2e}", p.name, p.value, p.std);
        }
    }
    if let Some(out) = &args.out {
        let text = machine_toml(&s, &a.name, &id, &names, board_period_us);
        // What is written must load as a scenario (its validation names a bad value).
        Scenario::parse(&text, out)
            .and_then(|m| m.validate())
            .context("the identified machine is not a valid scenario")?;
        crate::csvout::save(out, &text)?;
        eprintln!("identify: machine written to {}", out.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "t_s,tick,master_deg,state,valve_power,estop,command,target0_mm,\
                          actual0_mm,error0_mm,dac0,pa0_bar,pb0_bar";

    fn write(dir: &Path, name: &str, rows: &[&str]) -> PathBuf {
        let p = dir.join(name);
        let mut text = format!("{HEADER}\n");
        for r in rows {
            text.push_str(r);
            text.push('\n');
        }
        std::fs::write(&p, text).unwrap();
        p
    }

    fn row(t: f64, dac: &str) -> String {
        let tick = (t * 1e3).round() as u64 + 100;
        format!("{t:.4},{tick},0,manual,1,0,0,250,250.001,-0.001,{dac},62.5,91.5")
    }

    #[test]
    fn a_capture_is_read_in_the_cylinders_frame_and_bad_ones_are_refused_by_line() {
        let dir = tempfile::tempdir().unwrap();
        let good: Vec<String> = (0..5).map(|k| row(f64::from(k) * 1e-3, "-2047")).collect();
        let good: Vec<&str> = good.iter().map(String::as_str).collect();
        let p = write(dir.path(), "good.csv", &good);
        assert!(is_capture(&p).unwrap());
        let r = read_capture(&p, 0, 10.0, 0.0).unwrap();
        assert!((r.period_s - 1e-3).abs() < 1e-12);
        assert_eq!(r.u[0], -1.0);
        assert!((r.x_m[0] - 0.260_001).abs() < 1e-12, "offset added");
        assert!((r.pa_pa[0] - 62.5e5).abs() < 1e-6);
        // No slave 1 in this capture.
        let e = read_capture(&p, 1, 0.0, 0.0).unwrap_err().to_string();
        assert!(e.contains("no `dac1` column"), "{e}");
        // A DAC code out of range, a missing tick, not a number: the line named.
        let bad = [row(0.0, "0"), row(1e-3, "5000")];
        let bad: Vec<&str> = bad.iter().map(String::as_str).collect();
        let e = format!(
            "{:#}",
            read_capture(&write(dir.path(), "dac.csv", &bad), 0, 0.0, 0.0).unwrap_err()
        );
        assert!(e.contains("dac.csv:3") && e.contains("±2047"), "{e}");
        let gap = [
            row(0.0, "0"),
            row(1e-3, "0"),
            row(3e-3, "0"),
            row(4e-3, "0"),
        ];
        let gap: Vec<&str> = gap.iter().map(String::as_str).collect();
        let e = format!(
            "{:#}",
            read_capture(&write(dir.path(), "gap.csv", &gap), 0, 0.0, 0.0).unwrap_err()
        );
        assert!(e.contains("not one row per tick"), "{e}");
        // A 333 µs period: `t_s` rounded to 0.1 ms steps unevenly, the ticks prove it.
        let odd: Vec<String> = (0..50u32)
            .map(|k| {
                format!(
                    "{:.4},{},0,manual,1,0,0,250,250.001,-0.001,0,62.5,91.5",
                    f64::from(k) * 333e-6,
                    k + 7
                )
            })
            .collect();
        let odd: Vec<&str> = odd.iter().map(String::as_str).collect();
        let r = read_capture(&write(dir.path(), "odd.csv", &odd), 0, 0.0, 0.0).unwrap();
        assert!((r.period_s - 333e-6).abs() < 2e-6, "{}", r.period_s);
        let nan = [row(0.0, "0"), row(1e-3, "x")];
        let nan: Vec<&str> = nan.iter().map(String::as_str).collect();
        let e = format!(
            "{:#}",
            read_capture(&write(dir.path(), "nan.csv", &nan), 0, 0.0, 0.0).unwrap_err()
        );
        assert!(
            e.contains("nan.csv:3") && e.contains("`dac0` is not a number"),
            "{e}"
        );
        let one = [row(0.0, "0")];
        let one: Vec<&str> = one.iter().map(String::as_str).collect();
        assert!(read_capture(&write(dir.path(), "one.csv", &one), 0, 0.0, 0.0).is_err());
        // The null is taken off the command; an unpowered (idle) tick is not driven.
        let mixed = [
            row(0.0, "-12").replace("manual,1", "idle,0"),
            row(1e-3, "-12"),
            row(2e-3, "2035"),
        ];
        let mixed: Vec<&str> = mixed.iter().map(String::as_str).collect();
        let r = read_capture(&write(dir.path(), "mixed.csv", &mixed), 0, 0.0, -12.0).unwrap();
        assert_eq!(r.u, vec![0.0, 0.0, 2047.0 / 2047.0]);
        assert_eq!(r.driven, vec![false, true, true]);
        // A time that does not increase (ticks unknown), or a valve never driven: refused.
        let flat = [
            "0,,,manual,1,0,0,0,250,0,0,60,90",
            "0,,,manual,1,0,0,0,250,0,0,60,90",
        ];
        let header_no_tick = HEADER.replace("t_s,tick", "t_s,tick_");
        let p = dir.path().join("flat.csv");
        std::fs::write(&p, format!("{header_no_tick}\n{}\n{}\n", flat[0], flat[1])).unwrap();
        let e = format!("{:#}", read_capture(&p, 0, 0.0, 0.0).unwrap_err());
        assert!(e.contains("does not increase"), "{e}");
        let idle: Vec<String> = (0..3)
            .map(|k| row(f64::from(k) * 1e-3, "0").replace("manual,1", "idle,0"))
            .collect();
        let idle: Vec<&str> = idle.iter().map(String::as_str).collect();
        let e = format!(
            "{:#}",
            read_capture(&write(dir.path(), "idle.csv", &idle), 0, 0.0, 0.0).unwrap_err()
        );
        assert!(e.contains("never powered"), "{e}");
        // An open-loop recording is not a capture.
        let ol = dir.path().join("ol.csv");
        std::fs::write(&ol, "t,u,x_mm,v_mm_s,pA_bar,pB_bar,spool\n").unwrap();
        assert!(!is_capture(&ol).unwrap());
    }
}
