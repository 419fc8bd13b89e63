//! `host-sim status --port PORT [--json]`: the board's state, faults, tables, timing and
//! per-axis position / target / error in engineering units.

use super::serial::Link;
use hydra_core::protocol::msg::{StatusMsg, NO_TABLE};
use hydra_core::protocol::{Request, Response};

/// Arguments of `status`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Per-axis status in engineering units.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct AxisReport {
    /// Position, mm.
    pub pos_mm: f64,
    /// Target, mm.
    pub target_mm: f64,
    /// Following error, mm.
    pub error_mm: f64,
    /// Valve DAC code, LSB.
    pub dac: i16,
}

/// The status in engineering units (the `--json` schema).
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// idle / following / holding / fault.
    pub state: String,
    /// Latched fault code (0 = none).
    pub fault_code: u16,
    /// Master, master units (degrees for the rotary table).
    pub master: f64,
    /// Active table id, if any.
    pub active_id: Option<u32>,
    /// Committed (not yet active) table id.
    pub committed_id: Option<u32>,
    /// Table id in flash.
    pub saved_id: Option<u32>,
    /// The running table has ended.
    pub end_of_table: bool,
    /// An activation waits for a safe point.
    pub activation_pending: bool,
    /// Ticks since boot.
    pub ticks: u32,
    /// Longest tick, µs.
    pub tick_max_us: f64,
    /// Mean tick, µs.
    pub tick_mean_us: f64,
    /// Overruns.
    pub overruns: u32,
    /// Per axis.
    pub axes: Vec<AxisReport>,
}

fn id(x: u32) -> Option<u32> {
    (x != NO_TABLE).then_some(x)
}

/// Converts a Status message (master counts per unit: 1000 for mdeg → degrees).
pub fn report(s: &StatusMsg) -> Report {
    let um = |raw: i32| f64::from(raw) / 256.0 / 1000.0;
    Report {
        state: match s.state {
            0 => "idle",
            1 => "following",
            2 => "holding",
            3 => "fault",
            _ => "unknown",
        }
        .to_string(),
        fault_code: s.fault_code,
        master: s.master as f64 / 65536.0 / 1000.0,
        active_id: id(s.active_id),
        committed_id: id(s.committed_id),
        saved_id: id(s.saved_id),
        end_of_table: s.flags & 1 != 0,
        activation_pending: s.flags & 2 != 0,
        ticks: s.ticks,
        tick_max_us: f64::from(s.tick_max_ns) / 1000.0,
        tick_mean_us: f64::from(s.tick_mean_ns) / 1000.0,
        overruns: s.overruns,
        axes: s
            .axes
            .iter()
            .map(|a| AxisReport {
                pos_mm: um(a.pos_um),
                target_mm: um(a.target_um),
                error_mm: um(a.error_um),
                dac: a.dac,
            })
            .collect(),
    }
}

/// Asks for the status.
pub fn fetch(port: &str) -> anyhow::Result<Report> {
    let mut link = Link::open(port)?;
    match link.request(&Request::GetStatus)? {
        Response::Status(s) => Ok(report(&s)),
        r => anyhow::bail!("GetStatus answered {r:?}"),
    }
}

/// Runs `status`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let r = fetch(&args.port)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(());
    }
    println!("state        {}", r.state);
    println!("fault code   {:#06x}", r.fault_code);
    println!("master       {:.3}", r.master);
    println!(
        "tables       active {:?}, committed {:?}, saved {:?}{}{}",
        r.active_id,
        r.committed_id,
        r.saved_id,
        if r.end_of_table { ", at end" } else { "" },
        if r.activation_pending {
            ", activation armed"
        } else {
            ""
        }
    );
    println!(
        "tick         max {:.1} µs, mean {:.1} µs, {} overruns, {} ticks",
        r.tick_max_us, r.tick_mean_us, r.overruns, r.ticks
    );
    for (i, a) in r.axes.iter().enumerate() {
        println!(
            "axis {i}       pos {:.3} mm, target {:.3} mm, error {:.3} mm, dac {}",
            a.pos_mm, a.target_mm, a.error_mm, a.dac
        );
    }
    Ok(())
}
