//! `host-sim scurve`: plan a jerk-limited 7-phase move (an N-axis straight line, SPEC §B)
//! with the controller's fixed-point code and write every control-period sample.
//!
//! ```text
//! host-sim scurve --to X[,Y,…] --vmax V --amax A --jerk J --period T
//!                 [--from X0[,Y0,…]] --csv FILE [--json]
//! ```
//!
//! Units: positions mm, V mm/s, A mm/s², J mm/s³ (the limits apply to the path), T s.
//! Up to 8 axes; positions must be representable as `PosUm` (±8388 mm, 1/256 µm).
//!
//! `--csv`: header `t,pos,vel,acc,axis0,axis1,…`; one row per period from t = 0 to the
//! last sample, which equals the target. `pos`, `vel`, `acc` are the path's (mm, mm/s,
//! mm/s²: distance travelled along the line), `axisN` the axis positions (mm), exactly as
//! the controller samples them. Every number has 17 significant digits (`%.16e`).
//!
//! `--json`: one object on stdout with `duration` (the time-optimal move time, s),
//! `phase_durations` (the 7 phases, s), `final` (per-axis last sample, mm), `samples`
//! (rows written), and diagnostics: `regime`, `leader`, `path_length` (mm),
//! `last_sample_time` (s), `time_error` (last sample time − duration, s),
//! `max_position_error` (largest |path position − exact profile| over the samples, mm)
//! and `final_error` (per-axis last sample − target, mm).

use anyhow::{bail, Context as _};
use hydra_core::scurve::{Cursor, LineMove, PathLimits, Regime, ScurveError};
use hydra_core::units::PosUm;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Largest number of axes of one line.
pub const MAX_AXES: usize = 8;

/// Arguments of `host-sim scurve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Target point, mm, one value per axis (comma-separated).
    #[arg(
        long,
        value_name = "X[,Y,…]",
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    pub to: Vec<f64>,
    /// Start point, mm (default: the origin in every axis).
    #[arg(
        long,
        value_name = "X0[,Y0,…]",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub from: Option<Vec<f64>>,
    /// Path velocity limit V, mm/s.
    #[arg(long, value_name = "V")]
    pub vmax: f64,
    /// Path acceleration limit A, mm/s².
    #[arg(long, value_name = "A")]
    pub amax: f64,
    /// Path jerk limit J, mm/s³.
    #[arg(long, value_name = "J")]
    pub jerk: f64,
    /// Control period T, s.
    #[arg(long, value_name = "T")]
    pub period: f64,
    /// Output CSV: `t,pos,vel,acc,axis0,…`, one row per period.
    #[arg(long, value_name = "FILE")]
    pub csv: PathBuf,
    /// Print a JSON summary (duration, phase_durations, final, samples, …) on stdout.
    #[arg(long)]
    pub json: bool,
}

/// What a planned and sampled move reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Report {
    /// Time-optimal move time, s.
    pub duration: f64,
    /// Durations of the seven phases, s.
    pub phase_durations: [f64; 7],
    /// Per-axis position of the last sample, mm.
    #[serde(rename = "final")]
    pub final_mm: Vec<f64>,
    /// Number of samples (CSV rows).
    pub samples: u64,
    /// Which limits the profile reaches.
    pub regime: &'static str,
    /// Leader axis (largest |Δ|).
    pub leader: usize,
    /// Path length, mm.
    pub path_length: f64,
    /// Time of the last sample, s.
    pub last_sample_time: f64,
    /// last_sample_time − duration, s (in [0, T)).
    pub time_error: f64,
    /// Largest |sampled path position − exact profile|, mm.
    pub max_position_error: f64,
    /// Per-axis last sample − target, mm.
    pub final_error: Vec<f64>,
}

/// A number with 17 significant digits.
fn num(x: f64) -> String {
    format!("{x:.16e}")
}

fn regime_name(r: Regime) -> &'static str {
    match r {
        Regime::Empty => "empty",
        Regime::BothLimits => "both-limits",
        Regime::AccNotReached => "acceleration-not-reached",
        Regime::VelNotReached => "velocity-not-reached",
        Regime::NeitherReached => "neither-reached",
    }
}

/// The argument an S-curve error is about, in the command line's units.
fn explain(e: ScurveError) -> anyhow::Error {
    let msg = match e {
        ScurveError::Velocity => {
            "--vmax: the path velocity limit must be a finite number > 0 (mm/s)"
        }
        ScurveError::Acceleration => {
            "--amax: the path acceleration limit must be a finite number > 0 (mm/s²)"
        }
        ScurveError::Jerk => "--jerk: the path jerk limit must be a finite number > 0 (mm/s³)",
        ScurveError::Period => {
            "--period: the control period must be a finite number in (0, 3600] s"
        }
        ScurveError::DistanceTooLong => "--from/--to: the move is too long for the position format",
        ScurveError::DurationTooLong => {
            "--from/--to: the move lasts 2^32 − 2 periods or more (raise the limits or the period)"
        }
    };
    anyhow::anyhow!("{msg}")
}

fn pos_um(mm: f64, what: &str, axis: usize) -> anyhow::Result<PosUm> {
    if !mm.is_finite() {
        bail!("{what}: axis {axis} is not a finite number");
    }
    PosUm::checked_from_num(mm * 1000.0).with_context(|| {
        format!("{what}: axis {axis} = {mm} mm is outside the position range ±8388 mm")
    })
}

/// Plans the line and writes the CSV to `out`; returns the report.
pub fn write_move(
    from_mm: &[f64],
    to_mm: &[f64],
    limits_mm: [f64; 3],
    period_s: f64,
    out: &mut dyn std::io::Write,
) -> anyhow::Result<Report> {
    macro_rules! dispatch {
        ($($n:literal),*) => {
            match to_mm.len() {
                $($n => write_line::<$n>(from_mm, to_mm, limits_mm, period_s, out),)*
                n => bail!("--to: {n} axes given, 1 … {MAX_AXES} supported"),
            }
        };
    }
    if from_mm.len() != to_mm.len() {
        bail!(
            "--from has {} axes but --to has {}",
            from_mm.len(),
            to_mm.len()
        );
    }
    dispatch!(1, 2, 3, 4, 5, 6, 7, 8)
}

fn write_line<const N: usize>(
    from_mm: &[f64],
    to_mm: &[f64],
    [v, a, j]: [f64; 3],
    period_s: f64,
    out: &mut dyn std::io::Write,
) -> anyhow::Result<Report> {
    let mut from = [PosUm::ZERO; N];
    let mut to = [PosUm::ZERO; N];
    for (i, ((f, t), (fm, tm))) in from
        .iter_mut()
        .zip(to.iter_mut())
        .zip(from_mm.iter().zip(to_mm))
        .enumerate()
    {
        *f = pos_um(*fm, "--from", i)?;
        *t = pos_um(*tm, "--to", i)?;
    }
    let limits = PathLimits {
        vel_um_per_s: v * 1000.0,
        acc_um_per_s2: a * 1000.0,
        jerk_um_per_s3: j * 1000.0,
    };
    let mv = LineMove::plan(from, to, &limits, period_s).map_err(explain)?;
    let p = mv.profile();
    let plan = p.plan();
    // Leader LSB (1/256 µm) → path mm.
    let to_path_mm = mv.path_per_leader() / 256_000.0;

    let mut header: Vec<String> = ["t", "pos", "vel", "acc"].map(String::from).into();
    header.extend((0..N).map(|i| format!("axis{i}")));
    let mut o = crate::csvout::CsvOut::new(out, &header)?;
    let mut cursor = Cursor::new();
    let mut max_err = 0.0f64;
    let mut rows = 0u64;
    let mut last = from;
    while !cursor.done(p) {
        let k = cursor.tick();
        let t = f64::from(k) * period_s;
        let s = cursor.next(p);
        let smp = p.sample(k);
        let exact = plan.state_at(t).0;
        max_err = max_err.max((s as f64 - exact).abs() * to_path_mm);
        let x = mv.axes_at(s);
        let mut row = vec![
            num(t),
            num(mv.path_um(s) / 1000.0),
            num(p.vel_to_lsb_per_s(smp.vel_q) * to_path_mm),
            num(p.acc_to_lsb_per_s2(smp.acc_q) * to_path_mm),
        ];
        row.extend(x.iter().map(|xi| num(xi.to_num::<f64>() / 1000.0)));
        o.row(&row)?;
        last = x;
        rows += 1;
    }
    o.finish()?;
    let last_t = f64::from(p.end_tick()) * period_s;
    Ok(Report {
        duration: plan.duration_s(),
        phase_durations: plan.phase_durations_s(),
        final_mm: last.iter().map(|x| x.to_num::<f64>() / 1000.0).collect(),
        samples: rows,
        regime: regime_name(plan.regime),
        leader: mv.leader(),
        path_length: mv.path_length_um() / 1000.0,
        last_sample_time: last_t,
        time_error: last_t - plan.duration_s(),
        max_position_error: max_err,
        final_error: last
            .iter()
            .zip(&to)
            .map(|(x, t)| (x.to_num::<f64>() - t.to_num::<f64>()) / 1000.0)
            .collect(),
    })
}

/// Plans, writes `csv`, returns the report (the body of [`run`]).
pub fn plan_to_csv(args: &Args, csv: &Path) -> anyhow::Result<Report> {
    let from = args
        .from
        .clone()
        .unwrap_or_else(|| vec![0.0; args.to.len()]);
    let file = std::fs::File::create(csv)
        .with_context(|| format!("--csv: cannot create {}", csv.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let report = write_move(
        &from,
        &args.to,
        [args.vmax, args.amax, args.jerk],
        args.period,
        &mut w,
    )?;
    w.flush()
        .with_context(|| format!("--csv: cannot write {}", csv.display()))?;
    Ok(report)
}

/// Runs `host-sim scurve`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let r = plan_to_csv(args, &args.csv)?;
    if args.json {
        println!("{}", serde_json::to_string(&r)?);
    } else {
        println!(
            "{}: {} samples, move time {:.6} s ({}), last sample at {:.6} s, final {:?} mm",
            args.csv.display(),
            r.samples,
            r.duration,
            r.regime,
            r.last_sample_time,
            r.final_mm
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_mem(from: &[f64], to: &[f64], lim: [f64; 3], t: f64) -> (String, Report) {
        let mut buf = Vec::new();
        let r = write_move(from, to, lim, t, &mut buf).unwrap();
        (String::from_utf8(buf).unwrap(), r)
    }

    #[test]
    fn paper_case_csv() {
        let (csv, r) = run_mem(&[0.0], &[10.0], [1.5, 1.0, 1.0], 0.05);
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("t,pos,vel,acc,axis0"));
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len() as u64, r.samples);
        assert_eq!(rows[0], vec![0.0; 5]);
        let last = rows.last().unwrap();
        assert_eq!((last[1], last[4]), (10.0, 10.0));
        assert_eq!(r.final_mm, vec![10.0]);
        assert_eq!(r.final_error, vec![0.0]);
        assert_eq!(r.regime, "both-limits");
        assert!((r.duration - (10.0 / 1.5 + 2.5)).abs() < 1e-12);
        assert!(r.time_error >= 0.0 && r.time_error < 0.05);
        // 17 significant digits.
        let first_t = csv.lines().nth(2).unwrap().split(',').next().unwrap();
        assert_eq!(first_t, "5.0000000000000003e-2");
        // Path velocity never above V (mm/s).
        assert!(rows.iter().all(|r| r[2] <= 1.5 && r[2] >= 0.0));
    }

    #[test]
    fn two_axes_and_errors() {
        let (_, r) = run_mem(&[1.0, -2.0], &[4.0, 2.0], [100.0, 500.0, 5000.0], 0.001);
        assert_eq!(r.path_length, 5.0);
        assert_eq!(r.final_mm, vec![4.0, 2.0]);
        assert_eq!(r.leader, 1);
        let err = |from: &[f64], to: &[f64], lim: [f64; 3], t: f64| {
            write_move(from, to, lim, t, &mut Vec::new())
                .unwrap_err()
                .to_string()
        };
        assert!(err(&[0.0], &[1.0], [0.0, 1.0, 1.0], 0.001).starts_with("--vmax"));
        assert!(err(&[0.0], &[1.0], [1.0, -1.0, 1.0], 0.001).starts_with("--amax"));
        assert!(err(&[0.0], &[1.0], [1.0, 1.0, f64::NAN], 0.001).starts_with("--jerk"));
        assert!(err(&[0.0], &[1.0], [1.0, 1.0, 1.0], 0.0).starts_with("--period"));
        assert!(err(&[0.0], &[1e5], [1.0, 1.0, 1.0], 0.001).starts_with("--to"));
        assert!(err(&[0.0, 0.0], &[1.0], [1.0, 1.0, 1.0], 0.001).starts_with("--from"));
        assert!(err(&[0.0; 9], &[1.0; 9], [1.0, 1.0, 1.0], 0.001).starts_with("--to"));
        // Zero length: one sample, at the start.
        let (csv, r) = run_mem(&[3.0], &[3.0], [1.0, 1.0, 1.0], 0.01);
        assert_eq!(r.samples, 1);
        assert_eq!(r.duration, 0.0);
        assert_eq!(csv.lines().count(), 2);
    }
}
