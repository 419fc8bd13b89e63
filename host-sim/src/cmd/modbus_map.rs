//! `host-sim modbus-map [--axes N] [--json]`: the board's Modbus register map
//! (`hydra_core::plc::map`), as the Markdown tables of docs/plc.md or as JSON
//! (`[{"name","table","address","type","unit","access","description"}]`, one entry per
//! register, axis registers once per axis as `axis<n>.<name>`).

use hydra_core::plc::{AxisCount, CommandBit, Register, Scope, StatusBit, MAP};
use hydra_core::profile::SLAVES;
use std::fmt::Write as _;

/// Arguments of `host-sim modbus-map`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Axes of the board (1 … 8; default: the board's 2).
    #[arg(long, default_value_t = SLAVES as u8)]
    pub axes: u8,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
}

/// One register of the export.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Entry {
    /// `name` or `axis<n>.name`.
    pub name: String,
    /// `coil`, `discrete`, `input` or `holding`.
    pub table: &'static str,
    /// 0-based register address (the first of two for a 32-bit value).
    pub address: u16,
    /// `u16`, `i16`, `u32`, `i32` or `f32` (32-bit: high word first).
    #[serde(rename = "type")]
    pub ty: &'static str,
    /// Unit ("" for codes and bit fields).
    pub unit: &'static str,
    /// `r` or `rw`.
    pub access: &'static str,
    /// What it is.
    pub description: &'static str,
}

/// Every register of a board with `axes` axes, board registers first, then each axis'
/// block, each in address order within its table (holding, then input).
pub fn entries(axes: AxisCount) -> Vec<Entry> {
    let entry = |r: &Register, axis: Option<u8>| Entry {
        name: axis.map_or_else(|| r.name.to_string(), |n| format!("axis{n}.{}", r.name)),
        table: r.table.name(),
        address: r.address_of(axis.unwrap_or(0)),
        ty: r.ty.name(),
        unit: r.unit,
        access: r.access.name(),
        description: r.description,
    };
    let mut out: Vec<Entry> = MAP
        .iter()
        .filter(|r| r.scope == Scope::Board)
        .map(|r| entry(r, None))
        .collect();
    for n in 0..axes.get() {
        out.extend(
            MAP.iter()
                .filter(|r| r.scope == Scope::Axis)
                .map(|r| entry(r, Some(n))),
        );
    }
    out.sort_by_key(|e| (e.table != "holding", e.address));
    out
}

/// The Markdown of docs/plc.md's generated part: the register table, the command bits
/// and the status bits.
pub fn markdown(axes: AxisCount) -> String {
    let mut s = String::from(
        "| name | table | address | type | unit | access | description |\n|---|---|---|---|---|---|---|\n",
    );
    for e in entries(axes) {
        let _ = writeln!(
            s,
            "| `{}` | {} | {} | {} | {} | {} | {} |",
            e.name, e.table, e.address, e.ty, e.unit, e.access, e.description
        );
    }
    s.push_str("\n| `command` bit | name | acts |\n|---|---|---|\n");
    for b in CommandBit::ALL {
        let acts = if b.is_level() {
            "while set"
        } else {
            "on 0 → 1"
        };
        let _ = writeln!(s, "| {} | `{}` | {acts} |", b as u8, b.name());
    }
    s.push_str("\n| `status` bit | name |\n|---|---|\n");
    for b in StatusBit::ALL {
        let _ = writeln!(s, "| {} | `{}` |", b as u8, b.name());
    }
    s
}

/// Runs `host-sim modbus-map`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let axes = AxisCount::new(args.axes)
        .ok_or_else(|| anyhow::anyhow!("--axes {}: must be 1 … 8", args.axes))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&entries(axes))?);
    } else {
        print!("{}", markdown(axes));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_export_names_every_register_the_plc_needs() {
        let e = entries(AxisCount::new(2).unwrap());
        let has = |name: &str, table: &str, ty: &str| {
            assert!(
                e.iter()
                    .any(|x| x.name == name && x.table == table && x.ty == ty),
                "{name} ({table} {ty})"
            )
        };
        for (n, t, ty) in [
            ("command", "holding", "u16"),
            ("command_ack", "input", "u16"),
            ("status", "input", "u16"),
            ("state", "input", "u16"),
            ("fault_code", "input", "u16"),
            ("fault_axis", "input", "u16"),
            ("master.position", "input", "i32"),
            ("master.speed", "input", "i32"),
            ("table.select_id", "holding", "u16"),
            ("table.active_id", "input", "u16"),
            ("heartbeat", "holding", "u16"),
            ("owner", "holding", "u16"),
            ("param.id", "holding", "u16"),
            ("param.value", "holding", "f32"),
            ("param.op", "holding", "u16"),
            ("param.result", "input", "u16"),
        ] {
            has(n, t, ty);
        }
        for a in 0..2 {
            for (n, t, ty) in [
                ("actual_um", "input", "i32"),
                ("target_um", "input", "i32"),
                ("error_um", "input", "i32"),
                ("pressure_a_bar", "input", "f32"),
                ("pressure_b_bar", "input", "f32"),
                ("move_to_um", "holding", "i32"),
                ("move_speed_um_s", "holding", "i32"),
            ] {
                has(&format!("axis{a}.{n}"), t, ty);
            }
        }
        assert!(!e.iter().any(|x| x.name.starts_with("axis2.")));
        let json = serde_json::to_value(&e).unwrap();
        let first = json[0].as_object().unwrap();
        let keys: Vec<&str> = first.keys().map(String::as_str).collect();
        for k in [
            "name",
            "table",
            "address",
            "type",
            "unit",
            "access",
            "description",
        ] {
            assert!(keys.contains(&k), "{k}: {keys:?}");
        }
    }

    #[test]
    fn docs_plc_md_holds_the_generated_map() {
        let doc = include_str!("../../../docs/plc.md");
        let gen = markdown(AxisCount::new(2).unwrap());
        assert!(
            doc.contains(&gen),
            "docs/plc.md is stale: paste `host-sim modbus-map` between its markers"
        );
    }
}
