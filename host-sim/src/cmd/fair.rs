//! `host-sim fair`: every controller tuned by the same procedure at each period
//! ([`crate::fair`]), the rule's gains and the procedure's side by side.

use crate::fair::{compare, Fair};
use crate::scenario::{Controller, Scenario};
use std::path::PathBuf;

/// Arguments of `host-sim fair`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario file (default: host-sim/scenarios/tangent.toml; its force axes are left
    /// out of the runs).
    pub scenario: Option<PathBuf>,
    /// Laws to tune (default: all three).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub controller: Vec<Controller>,
    /// Control periods, µs (default: 72000,10000,1000).
    #[arg(long, value_name = "N,…", value_delimiter = ',')]
    pub period_us: Vec<u32>,
    /// Print one JSON object (`results`: controller, period_us, rule, best, runs).
    #[arg(long)]
    pub json: bool,
    /// Also print the chosen sets as `[[tuning]]` blocks to paste into a scenario.
    #[arg(long)]
    pub toml: bool,
}

/// Runs `host-sim fair`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let path = args
        .scenario
        .clone()
        .unwrap_or_else(|| super::shipped_scenario("tangent.toml"));
    let s = Scenario::load(&path)?;
    let table = s.load_table(None)?;
    let controllers = if args.controller.is_empty() {
        Controller::ALL.to_vec()
    } else {
        args.controller.clone()
    };
    let periods = if args.period_us.is_empty() {
        vec![72_000, 10_000, 1000]
    } else {
        args.period_us.clone()
    };
    let jobs: Vec<(Controller, u32)> = periods
        .iter()
        .flat_map(|&p| controllers.iter().map(move |&c| (c, p)))
        .collect();
    let bar = indicatif::ProgressBar::new(0);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "fair tuning [{bar:30}] {pos}/{len} runs, {elapsed} so far, ETA {eta}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    let result = compare(&s, &table, &jobs, &|n, total| {
        bar.set_length(total as u64);
        bar.set_position(n as u64);
    });
    bar.finish_and_clear();
    let result = result?;
    if args.json {
        let o = serde_json::json!({ "scenario": s.name(), "results": result });
        println!("{o}");
    } else {
        print_table(s.name(), &result);
    }
    if args.toml {
        for f in &result {
            print!("{}", crate::autotune::to_toml(&f.tuning));
        }
    }
    Ok(())
}

fn print_table(name: &str, result: &[Fair]) {
    println!(
        "{name} — every law tuned by one procedure (host-sim/src/fair.rs): the rule's set, then the best of {} runs with Kp ≤ √2 × the rule's",
        result.first().map_or(0, |f| f.runs)
    );
    println!(
        "{:<12} {:>7} | {:>8} {:>8} {:>10} {:>8} | {:>8} {:>8} {:>10} {:>8}",
        "controller",
        "period",
        "rule Kp",
        "Ki",
        "max µm",
        "RMS µm",
        "fair Kp",
        "Ki",
        "max µm",
        "RMS µm"
    );
    for f in result {
        println!(
            "{:<12} {:>4} ms | {:>8.4} {:>8.4} {:>10.1} {:>8.1} | {:>8.4} {:>8.4} {:>10.1} {:>8.1}",
            f.controller,
            f.period_us / 1000,
            f.rule.kp_lsb_per_um,
            f.rule.ki_lsb_per_um_s,
            f.rule.max_um,
            f.rule.rms_um,
            f.best.kp_lsb_per_um,
            f.best.ki_lsb_per_um_s,
            f.best.max_um,
            f.best.rms_um
        );
        if !f.best.faults.is_empty() {
            println!(
                "{:<12} every set faulted; the rule's shown: {}",
                "",
                f.best.faults.join(", ")
            );
        }
    }
}
