//! `host-sim param list|get|set|save|load|dump --port PORT [PATH|FILE] [VALUE] [--json]`:
//! the board's settings tree ([`hydra_core::protocol::settings`]) by path, with units and
//! ranges.
//!
//! - `list`: every path with its value in force, unit and range (`--json`:
//!   `[{"path", "value", "unit", "min", "max"}]`);
//! - `get PATH`: one value (`--json`: `{"path", "value"}`);
//! - `set PATH VALUE`: sets it (the board validates the value, then the whole set with
//!   the active table; nothing changes on a refusal) and prints the value read back;
//! - `save`: persists the settings with the active table (both, validated together, are
//!   what the next boot runs), or the settings alone before any table;
//! - `load FILE`: a settings file, checked whole before anything is sent and taken whole
//!   or not at all ([`super::param_file`]);
//! - `dump`: every writable setting in force, as a file `load` takes back.
//!
//! A value is a number in the path's unit; a boolean may be written `true` / `false`.

use super::serial::Link;
use hydra_core::protocol::settings::{all_paths, parse_path, ParamId, ParamPath};
use hydra_core::protocol::{Request, Response};

/// What to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum What {
    /// Every setting with its value, unit and range.
    List,
    /// One setting's value.
    Get,
    /// Set one setting (validated by the board as a whole set).
    Set,
    /// Persist the settings (with the active table, if any) to flash.
    Save,
    /// Send a settings file (TOML, `path = value`): every entry checked before anything
    /// is sent; a refused set changes nothing.
    Load,
    /// Print every writable setting in force as a file `load` takes back.
    Dump,
}

/// Arguments of `param`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port (or the path `serve --pty` printed).
    #[arg(long)]
    pub port: String,
    /// What to do.
    #[arg(value_enum)]
    pub what: What,
    /// The setting's path (get, set), e.g. `axis/0/kp_lsb_per_um` (see `param list`); the
    /// settings file (load).
    pub path: Option<String>,
    /// The value (set), in the path's unit.
    #[arg(allow_negative_numbers = true)]
    pub value: Option<String>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// The parameter a path names on this board, or an error naming the path.
pub fn resolve(path: &str, axes: u8) -> anyhow::Result<ParamPath> {
    parse_path(path, axes)
        .map(|(axis, id)| ParamPath { id, axis })
        .map_err(|e| anyhow::anyhow!("{path}: {e} (see `param list`)"))
}

/// A value typed by a person: a number, or `true` / `false` for a boolean.
pub fn parse_value(pp: ParamPath, s: &str) -> anyhow::Result<f32> {
    let i = pp.id.info();
    let v = match s.trim() {
        "true" if i.unit == "bool" => 1.0,
        "false" if i.unit == "bool" => 0.0,
        t => t
            .parse::<f32>()
            .map_err(|_| anyhow::anyhow!("{pp}: {s:?} is not a number ({})", i.unit))?,
    };
    // The board checks it too; said here with the range before anything is sent.
    pp.id
        .check(pp.axis, v)
        .map_err(|_| anyhow::anyhow!("{pp}: {s} is outside {} ({})", range(pp.id), i.unit))
}

/// `min … max` of a parameter, as printed.
pub fn range(id: ParamId) -> String {
    let i = id.info();
    let kind = if i.integer { ", integer" } else { "" };
    let ro = if i.read_only { ", read-only" } else { "" };
    format!("{} … {}{kind}{ro}", i.min, i.max)
}

/// A board value (`f32`) as JSON, in its shortest decimal form (0.0125, not the
/// 0.012500000186264517 of its conversion to `f64`): what `param set` accepts back.
pub fn json_value(v: f32) -> serde_json::Value {
    let shortest: f64 = v.to_string().parse().unwrap_or(f64::from(v));
    serde_json::Number::from_f64(shortest).map_or(serde_json::Value::Null, Into::into)
}

/// Reads one parameter.
pub fn get(link: &mut Link, pp: ParamPath) -> anyhow::Result<f32> {
    match link.request(&Request::GetParam {
        axis: pp.axis,
        param: pp.id as u8,
    })? {
        Response::Param { value, .. } => Ok(value),
        Response::Nak { nak, .. } => anyhow::bail!(
            "{pp}: the board refused GetParam: {}",
            super::serial::explain(&nak)
        ),
        r => anyhow::bail!("GetParam answered {r:?}"),
    }
}

/// Sets one parameter; a refusal is an error naming the path and the board's reason.
pub fn set(link: &mut Link, pp: ParamPath, value: f32) -> anyhow::Result<()> {
    link.expect_ack(&Request::SetParam {
        axis: pp.axis,
        param: pp.id as u8,
        value,
    })
    .map(drop)
    .map_err(|e| anyhow::anyhow!("{pp} = {value}: {e}"))
}

/// Prints one value: `PATH = VALUE UNIT`, or `{"path", "value"}` with `json`.
fn show(pp: ParamPath, v: f32, json: bool) {
    if json {
        let j = serde_json::json!({"path": pp.to_string(), "value": json_value(v)});
        println!("{j}");
    } else {
        println!("{pp} = {v} {}", pp.id.info().unit);
    }
}

/// Runs `param`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let mut link = Link::open(&args.port)?;
    let axes = link.info.axes;
    let path = || {
        args.path
            .as_deref()
            .ok_or_else(|| anyhow::anyhow!("param {:?} needs a PATH (see `param list`)", args.what))
    };
    match args.what {
        What::List => {
            let mut rows = Vec::new();
            for pp in all_paths(axes) {
                rows.push((pp, get(&mut link, pp)?));
            }
            if args.json {
                let j: Vec<_> = rows
                    .iter()
                    .map(|(pp, v)| {
                        let i = pp.id.info();
                        serde_json::json!({
                            "path": pp.to_string(), "value": json_value(*v), "unit": i.unit,
                            "min": json_value(i.min), "max": json_value(i.max),
                        })
                    })
                    .collect();
                println!("{}", serde_json::Value::Array(j));
            } else {
                for (pp, v) in rows {
                    let i = pp.id.info();
                    println!(
                        "{:<34} {:>14} {:<11} {}",
                        pp.to_string(),
                        v,
                        i.unit,
                        range(pp.id)
                    );
                }
            }
        }
        What::Get => {
            let pp = resolve(path()?, axes)?;
            show(pp, get(&mut link, pp)?, args.json);
        }
        What::Set => {
            let pp = resolve(path()?, axes)?;
            anyhow::ensure!(
                !pp.id.info().read_only,
                "{pp} is read-only: the board sets it itself{}",
                if pp.id == ParamId::SlaveOffsetUm {
                    " (motion set-position or home)"
                } else {
                    ""
                }
            );
            let text = args.value.as_deref().ok_or_else(|| {
                anyhow::anyhow!("param set {pp} needs a VALUE ({})", pp.id.info().unit)
            })?;
            let v = parse_value(pp, text)?;
            set(&mut link, pp, v)?;
            show(pp, get(&mut link, pp)?, args.json);
        }
        What::Load => {
            let file = std::path::PathBuf::from(args.path.as_deref().ok_or_else(|| {
                anyhow::anyhow!("param load needs a FILE (TOML, `path = value`)")
            })?);
            let entries = super::param_file::read(&file, axes)?;
            let before = super::param_file::apply(&mut link, &entries)?;
            for ((pp, _), old) in entries.iter().zip(before) {
                let now = get(&mut link, *pp)?;
                if args.json {
                    let j = serde_json::json!({
                        "path": pp.to_string(), "value": json_value(now), "was": json_value(old),
                    });
                    println!("{j}");
                } else {
                    println!("{pp} = {now} {} (was {old})", pp.id.info().unit);
                }
            }
            eprintln!(
                "{} setting(s) in force until the next boot; `param save` persists them",
                entries.len()
            );
        }
        What::Dump => print!("{}", super::param_file::dump(&mut link)?),
        What::Save => {
            eprintln!(
                "saving to flash: the board erases a sector (up to 2 s, its tick paused, axes idle) …"
            );
            link.expect_ack(&Request::Save)?;
            eprintln!("saved to flash");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_read_in_the_paths_unit_and_range() {
        let pp = resolve("axis/1/valve/invert", 2).unwrap();
        assert_eq!(parse_value(pp, "true").unwrap(), 1.0);
        assert_eq!(parse_value(pp, "0").unwrap(), 0.0);
        assert!(parse_value(pp, "0.5").is_err());
        let pp = resolve("axis/0/valve/null_lsb", 2).unwrap();
        assert_eq!(parse_value(pp, "-12.5").unwrap(), -12.5);
        let e = parse_value(pp, "-600").unwrap_err().to_string();
        assert!(
            e.contains("axis/0/valve/null_lsb") && e.contains("-500"),
            "{e}"
        );
        assert!(parse_value(pp, "true").is_err());
        assert!(parse_value(pp, "1e").is_err());
        let e = resolve("axis/2/kp_lsb_per_um", 2).unwrap_err().to_string();
        assert!(
            e.contains("axis/2/kp_lsb_per_um") && e.contains("2 slave"),
            "{e}"
        );
        assert!(resolve("axis/0/kp", 2).is_err());
    }
}
