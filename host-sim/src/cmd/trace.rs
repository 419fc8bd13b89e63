//! `host-sim trace --port PORT --seconds S --csv OUT [--plot FILE]`: records the board's
//! telemetry (every `--every` ticks) to CSV and optionally an SVG plot.
//!
//! CSV columns: `t_s` (board ticks × period), `master` (master units: degrees), then per
//! axis `target<i>_mm`, `actual<i>_mm`, `error<i>_mm`, `dac<i>` (LSB).

use super::serial::Link;
use hydra_core::protocol::msg::Telemetry;
use hydra_core::protocol::Request;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `trace`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// Recording time, s.
    #[arg(long)]
    pub seconds: f64,
    /// Output CSV.
    #[arg(long)]
    pub csv: PathBuf,
    /// Optional SVG plot of target and actual.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// One sample every this many ticks (1 … 65 535).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..))]
    pub every: u16,
}

/// Records telemetry for `seconds`.
pub fn record(link: &mut Link, seconds: f64, every: u16) -> anyhow::Result<Vec<Telemetry>> {
    link.telemetry.clear();
    link.expect_ack(&Request::SetTelemetry {
        decimation: every.max(1),
    })?;
    let end = Instant::now() + Duration::from_secs_f64(seconds.max(0.0));
    while Instant::now() < end {
        for (_, r) in link.read_frames()? {
            if let hydra_core::protocol::Response::Telemetry(t) = r {
                link.telemetry.push(t);
            }
        }
    }
    link.expect_ack(&Request::SetTelemetry { decimation: 0 })?;
    Ok(std::mem::take(&mut link.telemetry))
}

/// Runs `trace`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 86_400.0,
        "--seconds {}: a recording time must be > 0 s (and at most a day)",
        args.seconds
    );
    crate::csvout::writable(&args.csv)?;
    if let Some(p) = &args.plot {
        crate::csvout::writable(p)?;
    }
    let mut link = Link::open(&args.port)?;
    let period_s = f64::from(link.info.period_us) * 1e-6;
    let samples = record(&mut link, args.seconds, args.every)?;
    anyhow::ensure!(!samples.is_empty(), "no telemetry received");
    let mm = |raw: i32| f64::from(raw) / 256.0 / 1000.0;
    let n = samples[0].axes.len();
    let mut header = vec!["t_s".to_string(), "master".to_string()];
    for i in 0..n {
        header.extend([
            format!("target{i}_mm"),
            format!("actual{i}_mm"),
            format!("error{i}_mm"),
            format!("dac{i}"),
        ]);
    }
    let mut o = crate::csvout::CsvOut::new(Vec::new(), &header)?;
    let t0 = samples[0].tick;
    for s in &samples {
        let t = f64::from(s.tick.wrapping_sub(t0)) * period_s;
        let mut row = vec![
            format!("{t:.4}"),
            format!("{:.4}", s.master as f64 / 65536.0 / 1000.0),
        ];
        for a in &s.axes {
            row.extend([
                format!("{:.4}", mm(a.target_um)),
                format!("{:.4}", mm(a.actual_um)),
                format!("{:.4}", mm(a.target_um) - mm(a.actual_um)),
                a.dac.to_string(),
            ]);
        }
        o.row(&row)?;
    }
    crate::csvout::save(&args.csv, &o.text())?;
    eprintln!("{} samples → {}", samples.len(), args.csv.display());
    if let Some(p) = &args.plot {
        plot(p, &samples, period_s)?;
    }
    Ok(())
}

/// The plot: [`crate::plot::slave_panels`] of the telemetry.
fn plot(path: &std::path::Path, s: &[Telemetry], period_s: f64) -> anyhow::Result<()> {
    let mm = |raw: i32| f64::from(raw) / 256.0 / 1000.0;
    let t0 = s.first().map_or(0, |x| x.tick);
    let t: Vec<f64> = s
        .iter()
        .map(|x| f64::from(x.tick.wrapping_sub(t0)) * period_s)
        .collect();
    let n = s.first().map_or(0, |x| x.axes.len());
    let col = |i: usize, f: &dyn Fn(&hydra_core::protocol::msg::AxisSample) -> f64| {
        s.iter()
            .map(|x| x.axes.get(i).map_or(0.0, f))
            .collect::<Vec<f64>>()
    };
    let ps = crate::plot::slave_panels(
        n,
        &|i| col(i, &|a| mm(a.target_um)),
        &|i| col(i, &|a| mm(a.actual_um)),
        &|i| col(i, &|a| f64::from(a.dac)),
    );
    crate::plot::plot_panels(path, "trace (telemetry)", ("t (s)", &t), &ps, None)
}
