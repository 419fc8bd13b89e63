//! `host-sim robust`: the robustness box (crate::robust) with the scenario's gains — the
//! machine off nominal in every corner, max / RMS error and whether it oscillates.

use crate::robust::{cases, evaluate, Case};

/// Arguments of `host-sim robust`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scenario, law and period.
    #[command(flatten)]
    pub target: super::SimTarget,
    /// Print one JSON object (`cases`: label, factors, max_um, rms_um, oscillating, …).
    #[arg(long)]
    pub json: bool,
    /// Exit 1 when a case oscillates or its max error exceeds this, µm.
    #[arg(long, value_name = "UM")]
    pub require_max_um: Option<f64>,
}

/// Runs `host-sim robust`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if let Some(m) = args.require_max_um {
        anyhow::ensure!(
            m.is_finite() && m > 0.0,
            "--require-max-um must be a positive number of µm, not {m}"
        );
    }
    let super::Loaded {
        s,
        table,
        controller,
        period_us,
    } = args.target.load()?;
    let variants = cases(&s);
    let bar = indicatif::ProgressBar::new(variants.len() as u64);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "robustness box [{bar:30}] {pos}/{len} machines, {elapsed} so far, ETA {eta}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    let result = evaluate(&s, &table, controller, period_us, &variants, &|n| {
        bar.set_position(n as u64)
    });
    bar.finish_and_clear();
    let result = result?;
    let failing: Vec<&Case> = result
        .iter()
        .filter(|c| c.oscillating || args.require_max_um.is_some_and(|m| c.max_um > m))
        .collect();
    if args.json {
        let o = serde_json::json!({
            "scenario": s.name(),
            "controller": controller.name(),
            "period_us": period_us,
            "cases": result,
        });
        println!("{o}");
    } else {
        println!(
            "{} — {} at {} µs, the scenario's gains; the plant off nominal, the controller not told",
            s.name(),
            controller.name(),
            period_us
        );
        println!(
            "{:<32} {:>10} {:>9} {:>7} {:>11} {:>8}",
            "machine", "max µm", "RMS µm", "peak u", "oscillates", "backoff"
        );
        for c in &result {
            let osc = if c.oscillating {
                format!("yes ({})", c.excess_reversals)
            } else {
                "no".into()
            };
            println!(
                "{:<32} {:>10.1} {:>9.2} {:>7.3} {:>11} {:>8}",
                c.label, c.max_um, c.rms_um, c.peak_command, osc, c.backoff_level
            );
            for f in &c.faults {
                println!("{:<32} FAULT {f}", "");
            }
        }
        let worst = result.iter().skip(1).fold(0.0f64, |m, c| m.max(c.max_um));
        println!(
            "worst off-nominal max {worst:.1} µm; {} of {} machines oscillate",
            result.iter().filter(|c| c.oscillating).count(),
            result.len()
        );
    }
    if let Some(m) = args.require_max_um {
        if !failing.is_empty() {
            let names: Vec<&str> = failing.iter().map(|c| c.label.as_str()).collect();
            anyhow::bail!(
                "{} machine(s) oscillate or exceed {m} µm: {}",
                failing.len(),
                names.join(", ")
            );
        }
    }
    Ok(())
}
