//! `host-sim status --port PORT [--json]`: the board's state, faults, tables, timing and
//! per-axis position / target / error in engineering units.

use super::serial::Link;
use hydra_core::protocol::msg::{
    StatusMsg, FLAG_LINK_LOST, FLAG_PRESSURE_STALE, FLAG_UNREFERENCED, NO_TABLE,
};
use hydra_core::protocol::{Request, Response};
use hydra_core::runtime::Fault;

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
    /// Its name (`following_error`, `estop`, …; `hydra_core::runtime::Fault::name`).
    pub fault_name: Option<String>,
    /// The slave axis it names, if any.
    pub fault_axis: Option<u8>,
    /// A slave is not referenced yet (Start is refused until it is).
    pub unreferenced: bool,
    /// The host-link watchdog held the axes since the last Start.
    pub link_lost: bool,
    /// The pressure inputs are stale.
    pub pressure_stale: bool,
    /// Master, master units (degrees for the rotary table).
    pub master: f64,
    /// Active table id, if any.
    pub active_id: Option<u32>,
    /// Committed (not yet active) table id.
    pub committed_id: Option<u32>,
    /// Table id in flash.
    pub saved_id: Option<u32>,
    /// The flash slot the board booted (none: nothing saved booted).
    pub boot_slot: Option<u8>,
    /// Why (`newest`, `fallback_unreadable`, `fallback_settings`, `fallback_table`,
    /// `no_save`, `none_bootable`; [`boot_words`] says it in words).
    pub boot_reason: String,
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
        fault_name: (s.fault_code != 0).then(|| {
            Fault::from_code(s.fault_code)
                .map_or("unknown", |f| f.name())
                .to_string()
        }),
        fault_axis: Fault::from_code(s.fault_code).and_then(Fault::slave),
        unreferenced: s.flags & FLAG_UNREFERENCED != 0,
        link_lost: s.flags & FLAG_LINK_LOST != 0,
        pressure_stale: s.flags & FLAG_PRESSURE_STALE != 0,
        master: s.master as f64 / 65536.0 / 1000.0,
        active_id: id(s.active_id),
        committed_id: id(s.committed_id),
        saved_id: id(s.saved_id),
        boot_slot: (s.boot_slot != 0xFF).then_some(s.boot_slot),
        boot_reason: boot_name(s.boot_reason).to_string(),
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

/// Each boot reason's JSON name and words (`Status.boot_reason`).
const BOOT: [(hydra_core::protocol::BootReason, &str, &str); 6] = {
    use hydra_core::protocol::BootReason as B;
    [
        (B::NoSave, "no_save", "nothing saved, boot configuration"),
        (B::Newest, "newest", "the last save"),
        (
            B::FallbackUnreadable,
            "fallback_unreadable",
            "the save before the last (the last one did not read back)",
        ),
        (
            B::FallbackSettings,
            "fallback_settings",
            "the save before the last (the last one's settings were refused)",
        ),
        (
            B::FallbackTable,
            "fallback_table",
            "the save before the last (the last one's table breaks its rules)",
        ),
        (
            B::NoneBootable,
            "none_bootable",
            "no save could boot, boot configuration",
        ),
    ]
};

/// The JSON name of a `Status.boot_reason` code.
fn boot_name(code: u8) -> &'static str {
    BOOT.iter()
        .find(|(r, _, _)| *r as u8 == code)
        .map_or("unknown", |(_, name, _)| name)
}

/// What the board booted, in words.
pub fn boot_words(r: &Report) -> String {
    let slot = r
        .boot_slot
        .map_or_else(String::new, |s| format!("slot {s}: "));
    let why = BOOT
        .iter()
        .find(|(_, name, _)| *name == r.boot_reason)
        .map_or("unknown reason", |(_, _, words)| words);
    format!("{slot}{why}")
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
    let table = |t: Option<u32>| t.map_or_else(|| "none".to_string(), |v| v.to_string());
    println!("state        {}", r.state);
    match &r.fault_name {
        None => println!("fault        none"),
        Some(n) => println!(
            "fault        {n}{} (code {:#06x})",
            r.fault_axis
                .map_or_else(String::new, |a| format!(" on axis {a}")),
            r.fault_code
        ),
    }
    let mut notes = Vec::new();
    if r.unreferenced {
        notes.push("a slave is not referenced: set-position or home it before Start");
    }
    if r.link_lost {
        notes.push("the host-link watchdog held the axes");
    }
    if r.pressure_stale {
        notes.push("pressure inputs stale");
    }
    for n in notes {
        println!("note         {n}");
    }
    println!("master       {:.3}", r.master);
    println!(
        "tables       active {}, committed {}, saved {}{}{}",
        table(r.active_id),
        table(r.committed_id),
        table(r.saved_id),
        if r.end_of_table { ", at end" } else { "" },
        if r.activation_pending {
            ", activation armed"
        } else {
            ""
        }
    );
    println!("boot         {}", boot_words(&r));
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

#[cfg(test)]
mod tests {
    use super::*;
    use hydra_core::protocol::msg::AxisStatus;

    #[test]
    fn a_fault_is_named_with_its_axis_and_flags_are_spelled_out() {
        let mut s = StatusMsg {
            state: 3,
            flags: FLAG_UNREFERENCED,
            fault_code: 0x0601,
            fault_axis: 1,
            active_id: 7,
            committed_id: NO_TABLE,
            saved_id: NO_TABLE,
            boot_slot: 1,
            boot_reason: 4,
            upload_rows: 0,
            ticks: 10,
            tick_max_ns: 0,
            tick_mean_ns: 0,
            overruns: 0,
            master: 0,
            axes: heapless::Vec::new(),
        };
        let _ = s.axes.push(AxisStatus {
            pos_um: 256_000,
            target_um: 0,
            error_um: 0,
            dac: 0,
        });
        let r = report(&s);
        assert_eq!(r.fault_name.as_deref(), Some("following_error"));
        assert_eq!(r.fault_axis, Some(1));
        assert!(r.unreferenced && !r.link_lost && !r.pressure_stale);
        assert_eq!((r.active_id, r.committed_id), (Some(7), None));
        assert_eq!(
            (r.boot_slot, r.boot_reason.as_str()),
            (Some(1), "fallback_table")
        );
        assert!(boot_words(&r).starts_with("slot 1: the save before the last"));
        assert!((r.axes[0].pos_mm - 1.0).abs() < 1e-12);
        s.fault_code = 0;
        assert_eq!(report(&s).fault_name, None);
    }
}
