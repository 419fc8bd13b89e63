//! `host-sim status --port PORT [--watch] [--json]`: the board's state, the latched fault
//! with the value that tripped it and its limit, the fault history, inputs, tables,
//! timing, the link, and per-axis position / target / error with the reference state,
//! in engineering units. `--watch` redraws in place (5 Hz by default) until Ctrl-C.

use super::serial::Link;
use hydra_core::protocol::diag::{FaultEventMsg, FaultsMsg};
use hydra_core::protocol::msg::{
    StatusMsg, FLAG_LINK_LOST, FLAG_PRESSURE_STALE, FLAG_UNREFERENCED, INPUT_ESTOP,
    INPUT_VALVE_POWER, NO_TABLE,
};
use hydra_core::protocol::{Request, Response};
use hydra_core::runtime::{Fault, FaultKind};
use std::time::{Duration, Instant};

/// Arguments of `status`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// Print JSON (with --watch: one JSON object per line, each refresh).
    #[arg(long)]
    pub json: bool,
    /// Redraw in place until Ctrl-C.
    #[arg(long)]
    pub watch: bool,
    /// Refresh interval of --watch, ms (50 … 10 000).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(50..=10_000))]
    pub interval_ms: u64,
    /// With --watch: stop after this many refreshes (0: until Ctrl-C).
    #[arg(long, default_value_t = 0)]
    pub count: u64,
}

/// One fault event in engineering units.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct FaultReport {
    /// Tick it was raised.
    pub tick: u32,
    /// Time since boot, s.
    pub time_s: f64,
    /// Fault code.
    pub code: u16,
    /// Its name (`following_error`, …).
    pub name: String,
    /// The slave it names, if any.
    pub axis: Option<u8>,
    /// The value that tripped it (in `unit`; none for a state such as the E-stop).
    pub value: Option<f64>,
    /// Its limit (in `unit`).
    pub limit: Option<f64>,
    /// `mm`, `counts` or `s`; empty when the fault has no value.
    pub unit: String,
}

/// The inputs and outputs a person checks first.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct Inputs {
    /// The E-stop input is active (the chain is open).
    pub estop: bool,
    /// Valve power (the amplifiers' enable) is on.
    pub valve_power: bool,
}

/// The host link as the board saw it, and the round trip the host measured.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct LinkReport {
    /// Frames the board received whole since boot.
    pub frames: u32,
    /// Frames it received damaged (COBS, length, CRC).
    pub bad_frames: u32,
    /// Requests it refused.
    pub naks: u32,
    /// GetStatus round trip, ms.
    pub round_trip_ms: f64,
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
    /// `referenced`, `homing` (waiting for the reference edge) or `unreferenced`.
    pub reference: String,
    /// In state manual: `hold`, `jog` (jogging or braking), `move` (an S-curve move) or
    /// `test` (an identification test move).
    pub manual: String,
    /// The gain backoff's level (core `axis::backoff`): 0 the set gain; 1 … 4 the
    /// proportional gain cut to 0.36, 0.27, 0.20, 0.15 of it after an oscillation.
    pub backoff: u8,
    /// The feed-forward trim's learned ratios (core `axis::ff_trim`) for retracting and
    /// extending feed-forward: 1 the calibrated valve gain.
    pub ff_trim: [f64; 2],
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
    /// The value that tripped the latched fault (`fault_unit`), from the history.
    pub fault_value: Option<f64>,
    /// Its limit.
    pub fault_limit: Option<f64>,
    /// Their unit (`mm`, `counts`, `s`; empty: a state, not a value).
    pub fault_unit: String,
    /// The last 16 fault events, oldest first.
    pub faults: Vec<FaultReport>,
    /// E-stop and valve power.
    pub inputs: Inputs,
    /// A slave is not referenced yet (Start is refused until it is).
    pub unreferenced: bool,
    /// The host-link watchdog held the axes since the last Start.
    pub link_lost: bool,
    /// The pressure inputs are stale.
    pub pressure_stale: bool,
    /// Master, master units (degrees for the rotary table: 1 000 counts per °).
    pub master: f64,
    /// The master's unit.
    pub master_unit: String,
    /// Who owns the machine (moves and configures it): `none`, `host` (the serial
    /// host), `plc` (docs/plc.md).
    pub owner: String,
    /// Active table id, if any.
    pub active_id: Option<u32>,
    /// Its rows.
    pub active_rows: u16,
    /// CRC-32 of its rows (as `upload` prints it), hex.
    pub active_crc: String,
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
    /// Control period, µs.
    pub period_us: u32,
    /// Time since boot (ticks × period), s.
    pub time_s: f64,
    /// Longest tick, µs.
    pub tick_max_us: f64,
    /// Mean tick, µs.
    pub tick_mean_us: f64,
    /// Overruns.
    pub overruns: u32,
    /// Per axis.
    pub axes: Vec<AxisReport>,
    /// The link.
    pub link: LinkReport,
}

fn id(x: u32) -> Option<u32> {
    (x != NO_TABLE).then_some(x)
}

/// The name of a state code (`hydra_core::runtime::State::code`).
pub fn state_name(code: u8) -> &'static str {
    match code {
        0 => "idle",
        1 => "following",
        2 => "holding",
        3 => "fault",
        4 => "manual",
        _ => "unknown",
    }
}

/// A fault event's value and limit in engineering units, and the unit
/// (`hydra_core::runtime::FaultEvent` documents the raw units by kind).
fn event_values(
    f: Option<Fault>,
    e: &FaultEventMsg,
    period_s: f64,
) -> (Option<f64>, Option<f64>, &'static str) {
    let mm = |raw: i32| f64::from(raw) / 256.0 / 1000.0;
    match f.map(Fault::kind) {
        Some(FaultKind::FollowingError) => (Some(mm(e.value)), Some(mm(e.limit)), "mm"),
        // The law flagged the axis: its error then, for context (no limit was exceeded).
        Some(FaultKind::Controller) => (Some(mm(e.value)), None, "mm"),
        Some(FaultKind::EncoderJump) => {
            (Some(f64::from(e.value)), Some(f64::from(e.limit)), "counts")
        }
        Some(FaultKind::MasterStalled) => (
            Some(f64::from(e.value) * period_s),
            Some(f64::from(e.limit) * period_s),
            "s",
        ),
        _ => (None, None, ""),
    }
}

/// The fault history in engineering units.
pub fn fault_reports(f: &FaultsMsg, period_us: u32) -> Vec<FaultReport> {
    let period_s = f64::from(period_us) * 1e-6;
    f.events
        .iter()
        .map(|e| {
            let fault = Fault::from_code(e.code);
            let (value, limit, unit) = event_values(fault, e, period_s);
            FaultReport {
                tick: e.tick,
                time_s: f64::from(e.tick) * period_s,
                code: e.code,
                name: fault.map_or("unknown", Fault::name).to_string(),
                axis: fault.and_then(Fault::slave),
                value,
                limit,
                unit: unit.to_string(),
            }
        })
        .collect()
}

/// Converts a Status message with the fault history and link statistics (`Faults`), the
/// board's period and the measured round trip.
pub fn report_with(s: &StatusMsg, f: &FaultsMsg, period_us: u32, round_trip_ms: f64) -> Report {
    let um = |raw: i32| f64::from(raw) / 256.0 / 1000.0;
    let faults = fault_reports(f, period_us);
    // The latched fault's event: the newest with its code.
    let latched = faults
        .iter()
        .rev()
        .find(|e| e.code == s.fault_code && s.fault_code != 0);
    Report {
        state: state_name(s.state).to_string(),
        fault_code: s.fault_code,
        fault_name: (s.fault_code != 0).then(|| {
            Fault::from_code(s.fault_code)
                .map_or("unknown", |f| f.name())
                .to_string()
        }),
        fault_axis: Fault::from_code(s.fault_code).and_then(Fault::slave),
        fault_value: latched.and_then(|e| e.value),
        fault_limit: latched.and_then(|e| e.limit),
        fault_unit: latched.map_or_else(String::new, |e| e.unit.clone()),
        inputs: Inputs {
            estop: s.inputs & INPUT_ESTOP != 0,
            valve_power: s.inputs & INPUT_VALVE_POWER != 0,
        },
        faults,
        unreferenced: s.flags & FLAG_UNREFERENCED != 0,
        link_lost: s.flags & FLAG_LINK_LOST != 0,
        pressure_stale: s.flags & FLAG_PRESSURE_STALE != 0,
        master: s.master as f64 / 65536.0 / 1000.0,
        master_unit: "deg".to_string(),
        owner: match s.owner {
            0 => "none",
            1 => "host",
            2 => "plc",
            _ => "unknown",
        }
        .to_string(),
        active_id: id(s.active_id),
        active_rows: s.active_rows,
        active_crc: format!("{:08x}", s.active_crc),
        committed_id: id(s.committed_id),
        saved_id: id(s.saved_id),
        boot_slot: (s.boot_slot != 0xFF).then_some(s.boot_slot),
        boot_reason: boot_name(s.boot_reason).to_string(),
        end_of_table: s.flags & 1 != 0,
        activation_pending: s.flags & 2 != 0,
        ticks: s.ticks,
        period_us,
        time_s: f64::from(s.ticks) * f64::from(period_us) * 1e-6,
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
                reference: match a.reference {
                    2 => "referenced",
                    1 => "homing",
                    _ => "unreferenced",
                }
                .to_string(),
                manual: match a.manual {
                    1 => "jog",
                    2 => "move",
                    3 => "test",
                    _ => "hold",
                }
                .to_string(),
                backoff: a.backoff,
                ff_trim: a.ff_trim.map(|t| 1.0 + f64::from(t) * 1e-4),
            })
            .collect(),
        link: LinkReport {
            frames: f.link.frames,
            bad_frames: f.link.bad_frames,
            naks: f.link.naks,
            round_trip_ms,
        },
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

/// Asks for the status and the fault history over an open link.
pub fn fetch_on(link: &mut Link) -> anyhow::Result<Report> {
    let t0 = Instant::now();
    let s = match link.request(&Request::GetStatus)? {
        Response::Status(s) => s,
        r => anyhow::bail!("GetStatus answered {r:?}"),
    };
    let rtt_ms = t0.elapsed().as_secs_f64() * 1e3;
    let f = match link.request(&Request::GetFaults)? {
        Response::Faults(f) => f,
        r => anyhow::bail!("GetFaults answered {r:?}"),
    };
    Ok(report_with(&s, &f, link.info.period_us, rtt_ms))
}

/// Asks for the status.
pub fn fetch(port: &str) -> anyhow::Result<Report> {
    fetch_on(&mut Link::open(port)?)
}

/// Runs `status`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let mut link = Link::open(&args.port)?;
    if !args.watch {
        let r = fetch_on(&mut link)?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&r)?);
        } else {
            print!("{}", text(&r));
        }
        return Ok(());
    }
    let mut n = 0u64;
    loop {
        let next = Instant::now() + Duration::from_millis(args.interval_ms);
        let r = fetch_on(&mut link)?;
        if args.json {
            println!("{}", serde_json::to_string(&r)?);
        } else {
            // Home and clear, then the page: redrawn in place.
            print!("\x1b[H\x1b[2J{}", text(&r));
            println!("(every {} ms; Ctrl-C to stop)", args.interval_ms);
        }
        use std::io::Write;
        std::io::stdout().flush()?;
        n += 1;
        if args.count != 0 && n >= args.count {
            return Ok(());
        }
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
}

fn value_words(v: Option<f64>, limit: Option<f64>, unit: &str) -> String {
    match (v, limit) {
        (Some(v), Some(l)) => format!(": {v:.3} {unit} (limit {l:.3} {unit})"),
        (Some(v), None) => format!(": error {v:.3} {unit} then"),
        _ => String::new(),
    }
}

/// The status as a page of text.
pub fn text(r: &Report) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let table = |t: Option<u32>| t.map_or_else(|| "none".to_string(), |v| v.to_string());
    let _ = writeln!(o, "state        {}", r.state);
    match &r.fault_name {
        None => {
            let _ = writeln!(o, "fault        none");
        }
        Some(n) => {
            let _ = writeln!(
                o,
                "fault        {n}{}{} (code {:#06x})",
                r.fault_axis
                    .map_or_else(String::new, |a| format!(" on axis {a}")),
                value_words(r.fault_value, r.fault_limit, &r.fault_unit),
                r.fault_code
            );
        }
    }
    let _ = writeln!(
        o,
        "inputs       E-stop {}, valve power {}",
        if r.inputs.estop {
            "ACTIVE (chain open)"
        } else {
            "released"
        },
        if r.inputs.valve_power { "on" } else { "off" }
    );
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
        let _ = writeln!(o, "note         {n}");
    }
    let _ = writeln!(o, "master       {:.3} {}", r.master, r.master_unit);
    let _ = writeln!(o, "owner        {}", r.owner);
    let _ = writeln!(
        o,
        "tables       active {}{}, committed {}, saved {}{}{}",
        table(r.active_id),
        if r.active_id.is_some() {
            format!(" ({} rows, CRC {})", r.active_rows, r.active_crc)
        } else {
            String::new()
        },
        table(r.committed_id),
        table(r.saved_id),
        if r.end_of_table { ", at end" } else { "" },
        if r.activation_pending {
            ", activation armed"
        } else {
            ""
        }
    );
    let _ = writeln!(o, "boot         {}", boot_words(r));
    let _ = writeln!(
        o,
        "tick         {} µs period, max {:.1} µs, mean {:.1} µs, {} overruns, {} ticks ({:.1} s since boot)",
        r.period_us, r.tick_max_us, r.tick_mean_us, r.overruns, r.ticks, r.time_s
    );
    let _ = writeln!(
        o,
        "link         {} frames, {} damaged, {} refused; round trip {:.1} ms",
        r.link.frames, r.link.bad_frames, r.link.naks, r.link.round_trip_ms
    );
    for (i, a) in r.axes.iter().enumerate() {
        let _ = writeln!(
            o,
            "axis {i}       pos {:.3} mm, target {:.3} mm, error {:.3} mm, dac {}, {}{}{}{}",
            a.pos_mm,
            a.target_mm,
            a.error_mm,
            a.dac,
            a.reference,
            if r.state == "manual" {
                format!(", {}", a.manual)
            } else {
                String::new()
            },
            match a.backoff {
                0 => String::new(),
                l => format!(
                    ", gain backed off to level {l} (an oscillation was seen: the set Kp is too high for this machine)"
                ),
            },
            if a.ff_trim == [1.0; 2] {
                String::new()
            } else {
                format!(
                    ", feed-forward trimmed ×{:.3} retracting / ×{:.3} extending (the valve's flow gain, learned)",
                    a.ff_trim[0], a.ff_trim[1]
                )
            }
        );
    }
    if r.faults.is_empty() {
        let _ = writeln!(o, "history      no fault since boot");
    }
    for (k, e) in r.faults.iter().enumerate() {
        let ago = r.time_s - e.time_s;
        let _ = writeln!(
            o,
            "{} {:>8.3} s ({:.1} s ago, tick {}): {}{}{}",
            if k == 0 {
                "history     "
            } else {
                "            "
            },
            e.time_s,
            ago,
            e.tick,
            e.name,
            e.axis.map_or_else(String::new, |a| format!(" on axis {a}")),
            value_words(e.value, e.limit, &e.unit)
        );
    }
    o
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
            ..StatusMsg::default()
        };
        let _ = s.axes.push(AxisStatus {
            pos_um: 256_000,
            target_um: 0,
            error_um: 0,
            dac: 0,
            reference: 1,
            manual: 0,
            backoff: 0,
            ff_trim: [0; 2],
        });
        let r = report_with(&s, &FaultsMsg::default(), 1000, 0.0);
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
        assert_eq!(r.axes[0].reference, "homing");
        s.fault_code = 0;
        assert_eq!(
            report_with(&s, &FaultsMsg::default(), 1000, 0.0).fault_name,
            None
        );
    }

    #[test]
    fn the_latched_fault_gets_its_value_and_limit_from_the_history() {
        let s = StatusMsg {
            state: 3,
            fault_code: 0x0601,
            ticks: 12_000,
            inputs: INPUT_ESTOP,
            ..StatusMsg::default()
        };
        let mut f = FaultsMsg::default();
        for (code, tick, value, limit) in [
            (0x0500, 2_000, 75, 60),
            (0x0601, 10_000, 2_500 << 8, 2_000 << 8),
            (0x0100, 10_001, 0, 0),
        ] {
            f.events
                .push(FaultEventMsg {
                    code,
                    tick,
                    value,
                    limit,
                })
                .unwrap();
        }
        f.link.bad_frames = 3;
        let r = report_with(&s, &f, 1000, 0.5);
        assert_eq!(
            (r.fault_value, r.fault_limit, r.fault_unit.as_str()),
            (Some(2.5), Some(2.0), "mm")
        );
        assert!(r.inputs.estop && !r.inputs.valve_power);
        assert_eq!(r.faults.len(), 3);
        assert_eq!(r.faults[0].name, "encoder_jump");
        assert_eq!(
            (r.faults[0].value, r.faults[0].unit.as_str()),
            (Some(75.0), "counts")
        );
        assert_eq!(r.faults[2].value, None, "an E-stop is a state, not a value");
        assert!((r.time_s - 12.0).abs() < 1e-9);
        let t = text(&r);
        assert!(
            t.contains("following_error on axis 1: 2.500 mm (limit 2.000 mm)"),
            "{t}"
        );
        assert!(t.contains("E-stop ACTIVE"), "{t}");
        assert!(t.contains("(2.0 s ago, tick 10000)"), "{t}");
        assert!(t.contains("3 damaged"), "{t}");
    }
}
