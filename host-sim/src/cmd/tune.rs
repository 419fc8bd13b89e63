//! `host-sim tune --machine MACHINE.toml [--period-us N] [--controller C] [--margins
//! nominal|box] [--out TUNED.toml] [--json]`: gains for the machine the board is
//! connected to — typically the machine file `host-sim identify` wrote from the board's
//! own test moves — by the project's one tuning procedure (`crate::autotune`: the
//! ultimate gain of a P step test on *that* machine, Kp = K_u/2 — a 6 dB gain margin —,
//! the PI corner a quarter of the crossover, the feed-forward from *its* valve's
//! full-opening speeds), then checked: the machine follows its table with the new gains
//! (max / RMS error and whether it oscillates, as `robust` judges it), and the gain and
//! phase margins it leaves are measured on it (`crate::margins`, a probe at the valve).
//!
//! `--margins box` asks the 6 dB on every machine of the robustness box around the
//! machine file instead (robust against what identification missed, at the price of
//! the nominal figure); `--margins measured` lowers Kp until the whole loop measures
//! gain margin ≥ 6 dB and phase margin ≥ 45° on the machine (`autotune::
//! meet_measured_margins`). `--out` writes the machine file with the new `[[tuning]]`
//! appended (what `run`, `robust` and the next `tune` read), only when the check did not
//! oscillate; the gain set is printed in the scenario's TOML either way — each key of
//! `[tuning.axes.<name>]` is the board's setting `axis/<n>/<key>` (`param set`). The
//! check runs the machine file's own table (the reference table unless it names one) at
//! the machine file's period (the board's, when `identify` wrote it from a capture)
//! unless `--period-us` says otherwise. `--settings-out` writes the same set as a settings
//! file for the board ([`super::param_file::from_tuning`]), which `param load` sends
//! whole.

use crate::autotune::{tune, Margins};
use crate::robust::{evaluate, Variant};
use crate::scenario::{Controller, Scenario};
use anyhow::Context as _;
use std::path::PathBuf;

/// Arguments of `host-sim tune`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The machine: a scenario file (`identify --out` writes one).
    #[arg(long, value_name = "MACHINE.toml")]
    pub machine: PathBuf,
    /// Control period, µs (default: the machine file's `sim.period_us`).
    #[arg(long, value_name = "N")]
    pub period_us: Option<u32>,
    /// Follower law [feedforward: the board's].
    #[arg(long, value_enum)]
    pub controller: Option<Controller>,
    /// Where the 6 dB gain margin must hold: the machine itself (`nominal`: on the P
    /// step test), every machine of the robustness box around it (`box`), or the machine
    /// itself measured with the whole loop, gain margin ≥ 6 dB and phase margin ≥ 45°
    /// (`measured`: Kp lowered until the probe of `host-sim margins` says so).
    #[arg(long, value_enum, default_value = "nominal")]
    pub margins: Margins,
    /// Write the machine file with the new gain set appended here.
    #[arg(long, value_name = "TUNED.toml")]
    pub out: Option<PathBuf>,
    /// Write the gain set as a settings file for the board here (`host-sim param load
    /// --port P FILE` sends it whole): each follower axis, in the machine file's order,
    /// is slave `--slave`, `--slave` + 1, ….
    #[arg(long, value_name = "SETTINGS.toml")]
    pub settings_out: Option<PathBuf>,
    /// The board slave of the machine file's first follower axis (`--settings-out`).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub slave: u8,
    /// Print one JSON object: `ultimate_gain`, `gains` (the TOML), `check` (max_um,
    /// rms_um, oscillating, faults).
    #[arg(long)]
    pub json: bool,
}

/// Runs `host-sim tune`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    for out in [&args.out, &args.settings_out].into_iter().flatten() {
        crate::csvout::writable(out)?;
    }
    let mut s = Scenario::load(&args.machine)?;
    let original = std::fs::read_to_string(&args.machine)
        .with_context(|| format!("reading {}", args.machine.display()))?;
    let controller = args.controller.unwrap_or(Controller::Feedforward);
    let period_us = args.period_us.unwrap_or(s.sim.period_us);
    if args.out.is_some() {
        // The file's own gain sets (not the reference ones a file without any gets).
        let own: toml::Value = toml::from_str(&original)
            .with_context(|| format!("reading {}", args.machine.display()))?;
        let has = own
            .get("tuning")
            .and_then(toml::Value::as_array)
            .is_some_and(|a| {
                a.iter().any(|t| {
                    t.get("controller").and_then(toml::Value::as_str) == Some(controller.name())
                        && t.get("period_us").and_then(toml::Value::as_integer)
                            == Some(i64::from(period_us))
                })
            });
        anyhow::ensure!(
            !has,
            "{} already has a gain set for {} @ {period_us} µs: tune the machine file \
             `identify` wrote (or remove that [[tuning]])",
            args.machine.display(),
            controller.name()
        );
    }
    let (t, ku) = tune(&s, controller, period_us, args.margins)
        .with_context(|| format!("tuning {}", args.machine.display()))?;
    let text = crate::autotune::to_toml(&t);
    let settings = super::param_file::from_tuning(&s, &t, args.slave)?;
    s.tuning
        .retain(|x| !(x.controller == controller && x.period_us == period_us));
    s.tuning.push(t);
    let table = s.load_table(None)?;
    let check = evaluate(
        &s,
        &table,
        controller,
        period_us,
        &[Variant::nominal(&s)],
        &|_| {},
    )?;
    let c = check
        .first()
        .ok_or_else(|| anyhow::anyhow!("the check ran no case"))?;
    // The margins the gains leave on the machine, measured per follower (a loop that
    // oscillates has none: the check has said so). Information, not a verdict: a
    // measurement that cannot be made is reported and the check stays the judge.
    let margins: Vec<(String, Result<crate::margins::LoopMargins, String>)> = if c.oscillating {
        Vec::new()
    } else {
        s.axes
            .iter()
            .filter(|a| a.role == crate::scenario::Role::Follower)
            .map(|a| {
                let m = crate::margins::measure(&s, &table, controller, period_us, Some(&a.name))
                    .map_err(|e| e.to_string());
                (a.name.clone(), m)
            })
            .collect()
    };
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "machine": args.machine.display().to_string(),
                "controller": controller.name(),
                "period_us": period_us,
                "ultimate_gain": ku.iter().map(|(a, k)| serde_json::json!({"axis": a, "k_u": k})).collect::<Vec<_>>(),
                "gains": text,
                "check": {"max_um": c.max_um, "rms_um": c.rms_um, "oscillating": c.oscillating, "faults": c.faults},
                "margins": margins.iter().map(|(axis, m)| match m {
                    Ok(m) => serde_json::json!(m),
                    Err(e) => serde_json::json!({"axis": axis, "error": e}),
                }).collect::<Vec<_>>(),
            })
        );
    } else {
        for (axis, k) in &ku {
            println!(
                "# {axis}: ultimate gain K_u = {k:.4} ({} @ {period_us} µs{})",
                controller.name(),
                args.margins.ku_note()
            );
        }
        println!("{text}");
        println!(
            "# check on {}: max {:.2} µm, RMS {:.3} µm, {}",
            args.machine.display(),
            c.max_um,
            c.rms_um,
            if c.oscillating {
                format!("OSCILLATES ({})", c.faults.join(", "))
            } else {
                "no oscillation".into()
            }
        );
        for (axis, m) in &margins {
            match m {
                Ok(m) => println!(
                    "# {axis}: {} (`host-sim margins` — the loop broken at the valve)",
                    super::margins::summary(m)
                ),
                Err(e) => println!("# {axis}: margins not measured: {e}"),
            }
        }
    }
    anyhow::ensure!(
        !c.oscillating,
        "the machine oscillates with the gains the procedure chose (see the check above); \
         nothing written"
    );
    if let Some(out) = &args.out {
        let mut body = format!(
            "{original}\n# Tuned by `host-sim tune --margins {}` ({} @ {period_us} µs).\n{text}",
            args.margins.name(),
            controller.name()
        );
        if !body.ends_with('\n') {
            body.push('\n');
        }
        // What is written must load as a scenario with this gain set in it.
        let back = Scenario::parse(&body, out)
            .and_then(|m| m.validate().map(|()| m))
            .context("the tuned machine file is not a valid scenario")?;
        anyhow::ensure!(
            back.tuning
                .iter()
                .any(|x| x.controller == controller && x.period_us == period_us),
            "the tuned machine file lost its gain set"
        );
        crate::csvout::save(out, &body)?;
        eprintln!("tune: machine with its gains written to {}", out.display());
    }
    if let Some(out) = &args.settings_out {
        crate::csvout::save(out, &settings)?;
        eprintln!(
            "tune: the board's settings written to {} (`host-sim param load --port P {}`)",
            out.display(),
            out.display()
        );
    }
    Ok(())
}
