//! `host-sim capture --port P --trigger T --pre-ms A --post-ms B --csv F [--plot F.svg]`:
//! the board's loop-rate capture — every tick's target, actual, error, valve command,
//! pressures and state for each slave, frozen around a trigger — read back to CSV and
//! an SVG plot.
//!
//! Triggers: `now`, `fault` (entering Fault), `state` (any state change), `command` (a
//! tick that applied a host command), `threshold:CHANNEL>VALUE` or `<VALUE`, with
//! CHANNEL one of `master` (°), `target<i>`, `actual<i>`, `error<i>` (mm), `dac<i>`
//! (LSB), `pa<i>`, `pb<i>` (bar) and `<i>` the slave (0-based).
//!
//! A port is one host's at a time, so to capture around commands sent by other
//! `host-sim` calls: `capture --arm-only …`, then the commands (`motion start`, …), then
//! `capture --read-only --csv F` (waits for the trigger and reads the rows).
//!
//! CSV: one row per tick; `t_s` is the time from the trigger (negative before it), then
//! `tick`, `master_deg`, `state`, `valve_power`, `estop`, `command`, and per slave
//! `target<i>_mm`, `actual<i>_mm`, `error<i>_mm`, `dac<i>`, `pa<i>_bar`, `pb<i>_bar`.

use super::serial::Link;
use crate::plot::{plot_panels, Panel};
use hydra_core::protocol::diag::{
    capture_row_len, take_capture_row, CaptureArmMsg, CaptureLine, CaptureMsg,
};
use hydra_core::protocol::wire::Reader;
use hydra_core::protocol::{Request, Response};
use hydra_core::runtime::{
    Channel, Trigger, FLAG_COMMAND, FLAG_END_OF_TABLE, FLAG_ESTOP, FLAG_VALVE_POWER, STATE_MASK,
};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `capture`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// now | fault | state | command | threshold:CHANNEL>VALUE | threshold:CHANNEL<VALUE
    /// (channels: master [°], target<i>, actual<i>, error<i> [mm], dac<i> [LSB], pa<i>,
    /// pb<i> [bar]).
    #[arg(long, default_value = "now")]
    pub trigger: String,
    /// Time kept before the trigger, ms [default: 500; 0 with `--trigger now`, which
    /// fires on the first tick after the arming: the ring holds nothing before it].
    #[arg(long, allow_negative_numbers = true)]
    pub pre_ms: Option<f64>,
    /// Time recorded after the trigger, ms.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1500.0)]
    pub post_ms: f64,
    /// Output CSV (one row per tick; not with --arm-only).
    #[arg(long, required_unless_present = "arm_only")]
    pub csv: Option<PathBuf>,
    /// Optional SVG plot: positions, errors, valve commands, pressures, with legends.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Give up if the trigger has not come after this long, s.
    #[arg(long, default_value_t = 60.0)]
    pub timeout_s: f64,
    /// Arm the capture and return (read it later with --read-only).
    #[arg(long, conflicts_with = "read_only")]
    pub arm_only: bool,
    /// Do not arm: wait for the capture armed before and read it.
    #[arg(long)]
    pub read_only: bool,
}

/// Parses a channel name (`error0`, `pa1`, `master`) into the channel and the factor
/// from its engineering unit to the board's stored unit.
fn channel(name: &str) -> anyhow::Result<(Channel, f64)> {
    if name == "master" {
        // Degrees → counts (0.001° per count).
        return Ok((Channel::Master, 1000.0));
    }
    let split = name
        .find(|c: char| c.is_ascii_digit())
        .ok_or_else(|| anyhow::anyhow!("channel {name:?}: needs its slave number (error0)"))?;
    let (kind, axis) = name.split_at(split);
    let axis: u8 = axis
        .parse()
        .map_err(|_| anyhow::anyhow!("channel {name:?}: {axis:?} is not a slave number"))?;
    let um = 1000.0 * 256.0; // mm → I24F8 µm
    Ok(match kind {
        "target" => (Channel::Target(axis), um),
        "actual" => (Channel::Actual(axis), um),
        "error" => (Channel::Error(axis), um),
        "dac" => (Channel::Dac(axis), 1.0),
        "pa" => (Channel::PressureA(axis), 100.0),
        "pb" => (Channel::PressureB(axis), 100.0),
        _ => anyhow::bail!(
            "channel {name:?}: not one of master, target<i>, actual<i>, error<i>, dac<i>, pa<i>, pb<i>"
        ),
    })
}

/// Parses `--trigger`.
pub fn parse_trigger(s: &str) -> anyhow::Result<Trigger> {
    Ok(match s {
        "now" => Trigger::Now,
        "fault" => Trigger::Fault,
        "state" => Trigger::StateChange,
        "command" => Trigger::Command,
        _ => {
            let spec = s.strip_prefix("threshold:").ok_or_else(|| {
                anyhow::anyhow!(
                    "--trigger {s:?}: not now, fault, state, command or threshold:CHANNEL>VALUE"
                )
            })?;
            let (name, above, value) = match (spec.split_once('>'), spec.split_once('<')) {
                (Some((n, v)), None) => (n, true, v),
                (None, Some((n, v))) => (n, false, v),
                _ => anyhow::bail!("--trigger {s:?}: write CHANNEL>VALUE or CHANNEL<VALUE"),
            };
            let (channel, per_unit) = channel(name.trim())?;
            let v: f64 = value
                .trim()
                .parse()
                .map_err(|_| anyhow::anyhow!("--trigger {s:?}: {value:?} is not a number"))?;
            let raw = (v * per_unit).round();
            anyhow::ensure!(
                raw.is_finite() && raw.abs() <= f64::from(i32::MAX),
                "--trigger {s:?}: {v} is outside the channel's range"
            );
            let value = raw as i32;
            if above {
                Trigger::Above { channel, value }
            } else {
                Trigger::Below { channel, value }
            }
        }
    })
}

/// A finished capture: its rows, the trigger row's index, the period.
pub struct Captured {
    /// Rows, oldest first.
    pub rows: Vec<CaptureLine>,
    /// Index of the trigger row.
    pub pre: usize,
    /// Tick of the trigger row.
    pub trigger_tick: u32,
    /// Period, s.
    pub period_s: f64,
}

fn get(link: &mut Link, offset: u32, count: u8) -> anyhow::Result<CaptureMsg> {
    match link.request(&Request::GetCapture { offset, count })? {
        Response::Capture(c) => Ok(c),
        r => anyhow::bail!("GetCapture answered {r:?}"),
    }
}

/// Arms the capture (`pre_ms` before the trigger, `post_ms` after it).
pub fn arm(link: &mut Link, trigger: Trigger, pre_ms: f64, post_ms: f64) -> anyhow::Result<()> {
    let period_us = f64::from(link.info.period_us.max(1));
    let ticks = |ms: f64, what: &str| -> anyhow::Result<u32> {
        anyhow::ensure!(
            ms.is_finite() && ms >= 0.0,
            "--{what}-ms {ms}: a time must be ≥ 0 ms"
        );
        Ok((ms * 1000.0 / period_us).round().min(f64::from(u32::MAX)) as u32)
    };
    let (pre, post) = (ticks(pre_ms, "pre")?, ticks(post_ms, "post")?);
    link.expect_ack(&Request::CaptureArm(CaptureArmMsg::new(trigger, pre, post)))?;
    Ok(())
}

/// Waits for the armed capture to finish and reads every row.
pub fn collect(link: &mut Link, timeout: Duration) -> anyhow::Result<Captured> {
    let period_us = f64::from(link.info.period_us.max(1));
    let start = Instant::now();
    let mut said = 0u8;
    let info = loop {
        let c = get(link, 0, 0)?;
        if c.phase == 3 {
            break c;
        }
        anyhow::ensure!(
            c.phase != 0,
            "no capture was armed on this board since it booted"
        );
        if c.phase == 2 && said < 2 {
            eprintln!("triggered at tick {}, recording the rest …", c.trigger_tick);
            said = 2;
        } else if c.phase == 1 && said < 1 {
            eprintln!(
                "armed: waiting for the trigger (up to {:.0} s) …",
                timeout.as_secs_f64()
            );
            said = 1;
        }
        anyhow::ensure!(
            start.elapsed() < timeout,
            "no trigger within {:.0} s (the capture stays armed on the board)",
            timeout.as_secs_f64()
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let axes = usize::from(link.info.axes);
    let row_len = capture_row_len(axes);
    let mut rows = Vec::with_capacity(info.rows as usize);
    while (rows.len() as u32) < info.rows {
        let c = get(link, rows.len() as u32, u8::MAX)?;
        anyhow::ensure!(
            c.phase == 3 && c.offset == rows.len() as u32,
            "the capture changed while it was read (re-armed by another host?)"
        );
        anyhow::ensure!(
            !c.data.is_empty() && c.data.len() % row_len == 0,
            "GetCapture sent {} bytes, not whole rows of {row_len}",
            c.data.len()
        );
        let mut r = Reader::new(&c.data);
        while r.remaining() > 0 {
            rows.push(
                take_capture_row(&mut r, axes)
                    .ok_or_else(|| anyhow::anyhow!("a capture row ended early"))?,
            );
        }
    }
    Ok(Captured {
        rows,
        pre: info.pre as usize,
        trigger_tick: info.trigger_tick,
        period_s: period_us * 1e-6,
    })
}

/// The state name of a flags byte's 3-bit state value (`holding_end`: holding at the
/// end of the table, 2 | [`FLAG_END_OF_TABLE`]; 4 is Manual).
fn state_name(flags: u8) -> &'static str {
    match flags & STATE_MASK {
        v if v == 2 | FLAG_END_OF_TABLE => "holding_end",
        v => super::status::state_name(v),
    }
}

/// The CSV text of a capture (module docs for the columns).
pub fn csv(c: &Captured) -> anyhow::Result<String> {
    let axes = c.rows.first().map_or(0, |r| r.axes.len());
    let mut header: Vec<String> = [
        "t_s",
        "tick",
        "master_deg",
        "state",
        "valve_power",
        "estop",
        "command",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for i in 0..axes {
        for n in ["target", "actual", "error"] {
            header.push(format!("{n}{i}_mm"));
        }
        header.extend([
            format!("dac{i}"),
            format!("pa{i}_bar"),
            format!("pb{i}_bar"),
        ]);
    }
    let mut o = crate::csvout::CsvOut::new(Vec::new(), &header)?;
    let mm = |raw: i32| f64::from(raw) / 256_000.0;
    for (k, r) in c.rows.iter().enumerate() {
        let rel = k as i64 - c.pre as i64;
        let bit = |b: u8| u8::from(r.flags & b != 0).to_string();
        let mut row = vec![
            format!("{:.4}", rel as f64 * c.period_s),
            c.trigger_tick.wrapping_add_signed(rel as i32).to_string(),
            format!("{:.3}", f64::from(r.master) / 1000.0),
            state_name(r.flags).to_string(),
            bit(FLAG_VALVE_POWER),
            bit(FLAG_ESTOP),
            bit(FLAG_COMMAND),
        ];
        for a in &r.axes {
            row.extend([
                format!("{:.6}", mm(a.target_um)),
                format!("{:.6}", mm(a.actual_um)),
                format!("{:.6}", mm(a.target_um.wrapping_sub(a.actual_um))),
                a.dac.to_string(),
                format!("{:.2}", f64::from(a.pressure_cbar[0]) / 100.0),
                format!("{:.2}", f64::from(a.pressure_cbar[1]) / 100.0),
            ]);
        }
        o.row(&row)?;
    }
    Ok(o.text())
}

/// The plot: per slave target and actual, every slave's error (µm), valve commands and
/// pressures, with the trigger marked at t = 0.
pub fn plot(c: &Captured, path: &std::path::Path, title: &str) -> anyhow::Result<()> {
    let t: Vec<f64> = (0..c.rows.len())
        .map(|k| (k as f64 - c.pre as f64) * c.period_s)
        .collect();
    let axes = c.rows.first().map_or(0, |r| r.axes.len());
    let col = |f: &dyn Fn(&CaptureLine) -> f64| c.rows.iter().map(f).collect::<Vec<f64>>();
    let mm = |raw: i32| f64::from(raw) / 256_000.0;
    let mut ps = crate::plot::slave_panels(
        axes,
        &|i| col(&|r| mm(r.axes[i].target_um)),
        &|i| col(&|r| mm(r.axes[i].actual_um)),
        &|i| col(&|r| f64::from(r.axes[i].dac)),
    );
    ps.push(Panel {
        title: "chamber pressures".into(),
        y_label: "bar".into(),
        series: (0..axes)
            .flat_map(|i| {
                [
                    (
                        format!("p_A {i}"),
                        col(&|r| f64::from(r.axes[i].pressure_cbar[0]) / 100.0),
                    ),
                    (
                        format!("p_B {i}"),
                        col(&|r| f64::from(r.axes[i].pressure_cbar[1]) / 100.0),
                    ),
                ]
            })
            .collect(),
    });
    plot_panels(path, title, ("t from the trigger (s)", &t), &ps, Some(0.0))
}

/// Time kept before an event trigger unless `--pre-ms` says otherwise, ms.
pub const DEFAULT_PRE_MS: f64 = 500.0;

/// Runs `capture`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let trigger = parse_trigger(&args.trigger)?;
    let pre_ms = match (trigger, args.pre_ms) {
        (Trigger::Now, Some(ms)) if ms > 0.0 => {
            eprintln!(
                "warning: --trigger now fires on the first tick after the arming, so nothing \
                 before it exists: --pre-ms {ms} records no ticks before the trigger"
            );
            ms
        }
        (Trigger::Now, None) => 0.0,
        (_, ms) => ms.unwrap_or(DEFAULT_PRE_MS),
    };
    anyhow::ensure!(
        args.timeout_s.is_finite() && args.timeout_s > 0.0,
        "--timeout-s {}: must be > 0",
        args.timeout_s
    );
    for (ms, what) in [(pre_ms, "pre"), (args.post_ms, "post")] {
        anyhow::ensure!(
            ms.is_finite() && ms >= 0.0,
            "--{what}-ms {ms}: a time must be ≥ 0 ms"
        );
    }
    if !args.arm_only {
        for p in args.csv.iter().chain(args.plot.iter()) {
            crate::csvout::writable(p)?;
        }
    }
    let mut link = Link::open(&args.port)?;
    if !args.read_only {
        arm(&mut link, trigger, pre_ms, args.post_ms)?;
    }
    if args.arm_only {
        eprintln!("armed (trigger {}); read it with --read-only", args.trigger);
        return Ok(());
    }
    let out = args
        .csv
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("--csv FILE: where the capture goes"))?;
    let c = collect(&mut link, Duration::from_secs_f64(args.timeout_s))?;
    crate::csvout::save(out, &csv(&c)?)?;
    eprintln!(
        "{} ticks ({} before the trigger at tick {}) → {}",
        c.rows.len(),
        c.pre,
        c.trigger_tick,
        out.display()
    );
    if let Some(p) = &args.plot {
        plot(&c, p, &format!("capture, trigger {}", args.trigger))?;
        eprintln!("plot → {}", p.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_state_value_of_a_flags_byte_has_its_name() {
        use hydra_core::runtime::FLAG_VALVE_POWER;
        let names = [(0, "idle"), (1, "following"), (2, "holding"), (3, "fault")];
        for (v, name) in names.into_iter().chain([(4, "manual"), (6, "holding_end")]) {
            assert_eq!(state_name(v | FLAG_VALVE_POWER), name, "value {v}");
        }
    }

    #[test]
    fn triggers_parse_in_engineering_units_and_nonsense_is_refused() {
        assert_eq!(parse_trigger("fault").unwrap(), Trigger::Fault);
        assert_eq!(
            parse_trigger("threshold:error0>0.05").unwrap(),
            Trigger::Above {
                channel: Channel::Error(0),
                value: 12_800
            }
        );
        assert_eq!(
            parse_trigger("threshold:pb1<-2.5").unwrap(),
            Trigger::Below {
                channel: Channel::PressureB(1),
                value: -250
            }
        );
        assert_eq!(
            parse_trigger("threshold:master>45").unwrap(),
            Trigger::Above {
                channel: Channel::Master,
                value: 45_000
            }
        );
        for bad in [
            "sometimes",
            "threshold:error0",
            "threshold:speed0>1",
            "threshold:error>1",
            "threshold:error0>x",
            "threshold:error0>1e30",
        ] {
            assert!(parse_trigger(bad).is_err(), "{bad}");
        }
    }
}
