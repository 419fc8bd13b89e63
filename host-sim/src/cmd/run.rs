//! `host-sim run` (one scenario, one controller) and `host-sim` with no arguments (the
//! reference comparison: tangent.toml, three controllers, 72 ms and 1 ms).

use crate::camfile::CamCsv;
use crate::plot::plot_run;
use crate::scenario::{Controller, Scenario};
use crate::sim::{run as simulate, AxisResult, RunReport, RunSpec};
use anyhow::Context as _;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Arguments of `host-sim run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario file (TOML); see host-sim/scenarios/tangent.toml.
    pub scenario: PathBuf,
    /// Follower law (default: the scenario's `sim.controller`).
    #[arg(long, value_enum)]
    pub controller: Option<Controller>,
    /// Control period, µs (default: the scenario's `sim.period_us`).
    #[arg(long, value_name = "N")]
    pub period_us: Option<u32>,
    /// Cam table CSV replacing the scenario's `[table]`.
    #[arg(long, value_name = "FILE.csv")]
    pub table: Option<PathBuf>,
    /// Write the trace (every 1 ms) to this CSV file.
    #[arg(long, value_name = "TRACE.csv")]
    pub csv: Option<PathBuf>,
    /// Write an SVG plot of the run to this file.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Print exactly one JSON object with the results on stdout.
    #[arg(long)]
    pub json: bool,
    /// Exit 0 even when the runtime latched a fault (by default the exit code is 3).
    #[arg(long)]
    pub allow_fault: bool,
    /// Instead of running: apply the tuning procedure (docs/sim.md) to `--controller`
    /// (default: all three) at `--period-us` and print the `[[tuning]]` sets as TOML.
    #[arg(long, conflicts_with_all = ["json", "csv", "plot"])]
    pub tune: bool,
    /// With `--tune`: the machine(s) the gain margin of 6 dB must hold on — `nominal`
    /// (the scenario's machine, the shipped sets), `box` (every machine of the
    /// robustness box of `host-sim robust`: mass ×0.5–2, bulk modulus ×0.5–1.5, valve
    /// flow ±20 %, supply 120–180 bar) or `measured` (the scenario's machine, Kp then
    /// lowered until the whole loop measures ≥ 6 dB and ≥ 45°, `host-sim margins`).
    #[arg(long, value_enum, default_value = "nominal", requires = "tune")]
    pub margins: crate::autotune::Margins,
}

/// Trace period of `--csv` and the plots, s.
const TRACE_EVERY_S: f64 = 1e-3;

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("{prefix:>24} [{bar:30}] {pos:>3}/{len} s simulated {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ")
}

fn run_with_bar(
    s: &Scenario,
    table: &CamCsv,
    spec: &RunSpec,
    bar: &ProgressBar,
) -> anyhow::Result<RunReport> {
    let total = s.duration_s()?;
    bar.set_length(total.ceil() as u64);
    let r = simulate(s, table, spec, &mut |t| bar.set_position(t as u64))?;
    bar.finish_with_message(format!("{:.2} s wall", r.wall_seconds));
    Ok(r)
}

/// The JSON object of a run (the shape docs/sim.md documents; force axes under `force_axes`).
pub fn to_json(r: &RunReport) -> serde_json::Value {
    let mut axes = serde_json::Map::new();
    let mut force = serde_json::Map::new();
    for a in &r.axes {
        match &a.result {
            AxisResult::Follower {
                max_error_um,
                rms_error_um,
            } => {
                axes.insert(
                    a.name.clone(),
                    serde_json::json!({
                        "max_error_um": max_error_um,
                        "rms_error_um": rms_error_um,
                        "peak_command": a.peak_command,
                    }),
                );
            }
            AxisResult::Force {
                max_force_error_n,
                rms_force_error_n,
                switch_s,
                switch_jump_lsb,
                final_force_n,
            } => {
                force.insert(
                    a.name.clone(),
                    serde_json::json!({
                        "max_force_error_n": max_force_error_n,
                        "rms_force_error_n": rms_force_error_n,
                        "peak_command": a.peak_command,
                        "switch_s": switch_s,
                        "switch_jump_lsb": switch_jump_lsb,
                        "final_force_n": final_force_n,
                    }),
                );
            }
        }
    }
    let faults: Vec<serde_json::Value> = r
        .faults
        .iter()
        .map(|f| {
            serde_json::json!({
                "code": f.code,
                "name": f.name,
                "axis": f.axis,
                "tick": f.tick,
                "t_s": f.t_s,
                "value": f.value,
            })
        })
        .collect();
    let mut osc = serde_json::Map::new();
    for o in &r.oscillation {
        osc.insert(
            o.axis.clone(),
            serde_json::json!({
                "reversals": o.reversals,
                "table_reversals": o.table_reversals,
                "excess": o.excess(),
            }),
        );
    }
    let mut o = serde_json::json!({
        "scenario": r.scenario,
        "controller": r.controller.name(),
        "period_us": r.period_us,
        "sim_seconds": r.sim_seconds,
        "wall_seconds": r.wall_seconds,
        "axes": axes,
        "faults": faults,
        "valves_null_s": r.valves_null_s,
        "oscillation": osc,
    });
    if !force.is_empty() {
        o["force_axes"] = serde_json::Value::Object(force);
    }
    o
}

fn summary_line(r: &RunReport) -> String {
    let mut s = format!(
        "{:<12} {:>8}",
        r.controller.name(),
        format_period(r.period_us)
    );
    for a in &r.axes {
        match &a.result {
            AxisResult::Follower {
                max_error_um,
                rms_error_um,
            } => s.push_str(&format!(
                " | {:>10.1} {:>9.1} {:>6.3}",
                max_error_um, rms_error_um, a.peak_command
            )),
            AxisResult::Force {
                max_force_error_n,
                rms_force_error_n,
                ..
            } => s.push_str(&format!(
                " | {:>9.0} {:>8.0} {:>6.3}",
                max_force_error_n, rms_force_error_n, a.peak_command
            )),
        }
    }
    s.push_str(&format!(
        " | {:>6.2} s ({:>4.0}× real time)",
        r.wall_seconds,
        r.sim_seconds / r.wall_seconds.max(1e-9)
    ));
    s
}

fn summary_header(r: &RunReport) -> String {
    let mut h1 = format!("{:<12} {:>8}", "controller", "period");
    let mut h2 = format!("{:<12} {:>8}", "", "");
    for a in &r.axes {
        match a.result {
            AxisResult::Follower { .. } => {
                h1.push_str(&format!(" | {:^27}", format!("{} error", a.name)));
                h2.push_str(&format!(
                    " | {:>10} {:>9} {:>6}",
                    "max µm", "RMS µm", "peak u"
                ));
            }
            AxisResult::Force { .. } => {
                h1.push_str(&format!(" | {:^25}", format!("{} force error", a.name)));
                h2.push_str(&format!(" | {:>9} {:>8} {:>6}", "max N", "RMS N", "peak u"));
            }
        }
    }
    h1.push_str(" | wall time");
    format!("{h1}\n{h2}")
}

fn format_period(us: u32) -> String {
    if us.is_multiple_of(1000) {
        format!("{} ms", us / 1000)
    } else {
        format!("{us} µs")
    }
}

fn note_tuning(r: &RunReport) {
    if r.tuned_period_us != r.period_us {
        eprintln!(
            "note: no gain set of `{}` tuned at {} µs; using the set tuned at {} µs",
            r.controller.name(),
            r.period_us,
            r.tuned_period_us
        );
    }
}

/// Runs `host-sim run`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let s = Scenario::load(&args.scenario)?;
    if args.tune {
        let period_us = args.period_us.unwrap_or(s.sim.period_us);
        let controllers = match args.controller {
            Some(c) => vec![c],
            None => Controller::ALL.to_vec(),
        };
        for c in controllers {
            let (t, ku) = crate::autotune::tune(&s, c, period_us, args.margins)?;
            let over = args.margins.ku_note();
            for (axis, k) in ku {
                println!(
                    "# {axis}: ultimate gain K_u = {k:.4} ({} @ {period_us} µs{over})",
                    c.name()
                );
            }
            println!("{}", crate::autotune::to_toml(&t));
        }
        return Ok(());
    }
    let table = s.load_table(args.table.as_deref())?;
    let spec = RunSpec {
        controller: args.controller.unwrap_or(s.sim.controller),
        period_us: args.period_us.unwrap_or(s.sim.period_us),
        trace_every_s: (args.csv.is_some() || args.plot.is_some()).then_some(TRACE_EVERY_S),
    };
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    bar.set_style(bar_style());
    bar.set_prefix(format!(
        "{} @ {}",
        spec.controller.name(),
        format_period(spec.period_us)
    ));
    let r = run_with_bar(&s, &table, &spec, &bar)?;
    bar.finish_and_clear();
    note_tuning(&r);
    if let (Some(path), Some(tr)) = (&args.csv, &r.trace) {
        std::fs::write(path, tr.to_csv()).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.plot {
        plot_run(&r, path).with_context(|| format!("plotting {}", path.display()))?;
    }
    if args.json {
        println!("{}", to_json(&r));
    } else {
        println!("{}", summary_header(&r));
        println!("{}", summary_line(&r));
        for f in &r.faults {
            println!("{}", fault_line(f));
        }
        if let (Some(first), Some(t)) = (r.faults.first(), r.valves_null_s) {
            let ticks = ((t - first.t_s) * 1e6 / f64::from(r.period_us)).round();
            println!("valves at null from {t:.3} s ({ticks} tick(s) after the first fault)");
        }
    }
    if let (Some(first), false) = (r.faults.first(), args.allow_fault) {
        return Err(FaultLatched {
            first: fault_line(first),
            count: r.faults.len(),
        }
        .into());
    }
    Ok(())
}

/// The exit code of a run in which the runtime latched a fault (`--allow-fault`: 0).
pub const FAULT_EXIT_CODE: u8 = 3;

/// The run's results were printed, but the runtime latched a fault: `host-sim` exits
/// with [`FAULT_EXIT_CODE`].
#[derive(Debug, thiserror::Error)]
#[error("the runtime latched {count} fault(s), the first: {first} (exit code 3; --allow-fault: 0)")]
pub struct FaultLatched {
    /// The first fault, as [`fault_line`] prints it.
    pub first: String,
    /// Faults latched.
    pub count: usize,
}

/// One fault for people: `FAULT following_error (0x0600) on tangent at 2.913 s (tick 2914): 20012.4 µm`.
pub fn fault_line(f: &crate::sim::FaultEvent) -> String {
    let mut s = format!("FAULT {} (0x{:04x})", f.name, f.code);
    if let Some(a) = &f.axis {
        s.push_str(&format!(" on {a}"));
    }
    s.push_str(&format!(" at {:.3} s (tick {})", f.t_s, f.tick));
    if let Some(v) = f.value {
        s.push_str(&format!(": {v:.1} µm"));
    }
    s
}

/// The scenario of the reference comparison: `host-sim/scenarios/tangent.toml` from the
/// working directory or from the source tree, else the built-in reference machine (the
/// same values, generated table).
fn reference_scenario() -> anyhow::Result<Scenario> {
    let p = super::shipped_scenario("tangent.toml");
    if p.is_file() {
        return Ok(Scenario::load(&p)?);
    }
    Ok(Scenario {
        name: "tangent".into(),
        ..Scenario::default()
    })
}

/// The periods of the reference comparison, µs.
pub const DEFAULT_PERIODS_US: [u32; 2] = [72_000, 1000];

/// `host-sim` with no arguments: the reference comparison.
pub fn run_default() -> anyhow::Result<()> {
    let s = reference_scenario()?;
    let table = s.load_table(None)?;
    let out = PathBuf::from("out");
    std::fs::create_dir_all(&out).context("creating out/")?;
    let mut specs = Vec::new();
    for period_us in DEFAULT_PERIODS_US {
        for controller in Controller::ALL {
            specs.push(RunSpec {
                controller,
                period_us,
                trace_every_s: Some(TRACE_EVERY_S),
            });
        }
    }
    eprintln!(
        "host-sim: {} ({} s of machine time) with {} controllers at {} — {} runs",
        s.name(),
        s.duration_s()?,
        Controller::ALL.len(),
        DEFAULT_PERIODS_US.map(format_period).join(" and "),
        specs.len()
    );
    let mp = MultiProgress::with_draw_target(ProgressDrawTarget::stderr());
    let bars: Vec<ProgressBar> = specs
        .iter()
        .map(|sp| {
            let b = mp.add(ProgressBar::new(1));
            b.set_style(bar_style());
            b.set_prefix(format!(
                "{} @ {}",
                sp.controller.name(),
                format_period(sp.period_us)
            ));
            b
        })
        .collect();
    let results: Mutex<Vec<Option<anyhow::Result<RunReport>>>> =
        Mutex::new((0..specs.len()).map(|_| None).collect());
    let next = AtomicUsize::new(0);
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(specs.len());
    std::thread::scope(|sc| {
        for _ in 0..threads {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(spec) = specs.get(i) else { break };
                let r = run_with_bar(&s, &table, spec, &bars[i]);
                if let Ok(mut v) = results.lock() {
                    v[i] = Some(r);
                }
            });
        }
    });
    mp.clear().ok();
    let results = results.into_inner().unwrap_or_default();
    let mut reports = Vec::new();
    for r in results.into_iter().flatten() {
        reports.push(r?);
    }
    let Some(first) = reports.first() else {
        anyhow::bail!("no run finished");
    };
    println!("{}", summary_header(first));
    for r in &reports {
        println!("{}", summary_line(r));
    }
    let mut written = Vec::new();
    for r in &reports {
        note_tuning(r);
        let path = out.join(format!(
            "{}_{}_{}us.svg",
            r.scenario,
            r.controller.name(),
            r.period_us
        ));
        plot_run(r, &path).with_context(|| format!("plotting {}", path.display()))?;
        written.push(path.display().to_string());
    }
    println!(
        "\nerrors: table at the actual table angle − actual position, after {} s; peak u: largest valve command (1 = full opening)",
        s.sim.error_skip_s
    );
    println!("plots: {}", written.join(", "));
    Ok(())
}
