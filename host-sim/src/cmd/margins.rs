//! `host-sim margins [SCENARIO] [--controller C] [--period-us N] [--axis NAME] [--json]`:
//! a follower's loop gain and phase margins, measured on the simulated machine by a
//! valve probe (crate::margins).

use crate::margins::{measure, LoopMargins};

/// Arguments of `host-sim margins`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scenario, law and period.
    #[command(flatten)]
    pub target: super::SimTarget,
    /// The follower axis (default: the first).
    #[arg(long, value_name = "NAME")]
    pub axis: Option<String>,
    /// Print one JSON object (the margins and every point of the response).
    #[arg(long)]
    pub json: bool,
}

/// Runs `host-sim margins`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let super::Loaded {
        s,
        table,
        controller,
        period_us,
    } = args.target.load()?;
    let m = measure(&s, &table, controller, period_us, args.axis.as_deref())?;
    if args.json {
        let o = serde_json::json!({
            "scenario": s.name(),
            "controller": controller.name(),
            "period_us": period_us,
            "margins": m,
        });
        println!("{o}");
    } else {
        println!(
            "{} — {} at {} µs, axis {}: the loop broken at the valve command, a {} % probe",
            s.name(),
            controller.name(),
            period_us,
            m.axis,
            crate::margins::PROBE_AMPLITUDE * 100.0
        );
        println!(
            "{:>9} {:>9} {:>10} {:>9}",
            "f Hz", "|L| dB", "∠L °", "|1+L|"
        );
        for p in &m.points {
            println!(
                "{:>9.2} {:>9.2} {:>10.1} {:>9.3}",
                p.freq_hz, p.mag_db, p.phase_deg, p.distance_to_minus_one
            );
        }
        println!("{}", summary(&m));
    }
    Ok(())
}

/// One line: the margins and where they are.
pub fn summary(m: &LoopMargins) -> String {
    let pm = match (m.phase_margin_deg, m.gain_crossover_hz) {
        (Some(pm), Some(f)) => format!("phase margin {pm:.1}° at {f:.1} Hz"),
        _ => "no gain crossover in the measured range".to_string(),
    };
    let gm = match (m.gain_margin_db, m.phase_crossover_hz) {
        (Some(gm), Some(f)) => format!("gain margin {gm:.1} dB at {f:.1} Hz"),
        _ => "no phase crossover above it in the measured range".to_string(),
    };
    // Above the first gain crossover, |L| back above 1 (the oil column's peak).
    let peak = m.gain_crossover_hz.and_then(|fc| {
        m.points
            .iter()
            .filter(|p| p.freq_hz > fc)
            .max_by(|a, b| a.mag_db.total_cmp(&b.mag_db))
    });
    let resonance = match peak {
        Some(p) if p.mag_db > 0.0 => format!(
            "; |L| rises again to {:+.1} dB at {:.1} Hz (∠L {:.0}°)",
            p.mag_db, p.freq_hz, p.phase_deg
        ),
        _ => String::new(),
    };
    format!(
        "{pm}, {gm}, modulus margin min|1+L| {:.2} (M_s {:.1} dB){resonance}",
        m.modulus_margin,
        -20.0 * m.modulus_margin.log10()
    )
}
