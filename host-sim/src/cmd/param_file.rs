//! Settings files: `host-sim param load --port P FILE.toml` and `param dump`.
//!
//! A file maps settings-tree paths to values in the path's unit. Nested tables and
//! quoted paths are the same thing — a key's path is its table names and key joined by
//! `/`:
//!
//! ```toml
//! [axis.0]
//! kp_lsb_per_um = 1.5
//! [axis.0.valve]
//! null_lsb = -12
//! "axis/1/following_error_um" = 2500   # the same as [axis.1] following_error_um = 2500
//! ```
//!
//! `load` checks every entry before anything is sent — the path exists on this board,
//! is writable, and its value is a number (or boolean) inside the path's range; every
//! problem is reported, each naming its path, and the board is not touched. Then it
//! reads the values in force, sets the new ones (a value the board refuses because of
//! another one still to come — a minimum above the old maximum — is retried after the
//! others), and if the board still refuses one, puts back every value it changed: a set
//! is taken whole or not at all. The values live until the next boot unless `param
//! save` persists them.

use super::param::{get, parse_value, resolve, set};
use super::serial::Link;
use crate::scenario::{Scenario, Tuning};
use hydra_core::protocol::settings::{all_paths, ParamPath, Scope};
use std::path::Path;

/// One entry of a settings file, checked: the path and the value to send.
pub type Entry = (ParamPath, f32);

/// Reads a settings file and checks every entry against a board of `axes` slaves: all
/// problems together (one line each, naming the path), or the entries in file order.
pub fn read(path: &Path, axes: u8) -> anyhow::Result<Vec<Entry>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    parse(&text, axes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// [`read`] of a file's text.
pub fn parse(text: &str, axes: u8) -> anyhow::Result<Vec<Entry>> {
    let doc: toml::Table = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut flat = Vec::new();
    flatten("", &doc, &mut flat);
    let mut out = Vec::new();
    let mut problems = Vec::new();
    for (key, value) in flat {
        match entry(&key, &value, axes) {
            Ok(e) if out.iter().any(|(pp, _): &Entry| *pp == e.0) => {
                problems.push(format!("{key}: given twice"));
            }
            Ok(e) => out.push(e),
            Err(e) => problems.push(e.to_string()),
        }
    }
    if out.is_empty() && problems.is_empty() {
        problems.push("no settings in the file".into());
    }
    if !problems.is_empty() {
        anyhow::bail!(
            "{} problem(s), nothing sent:\n  {}",
            problems.len(),
            problems.join("\n  ")
        );
    }
    Ok(out)
}

/// Every leaf of `t` with its `/`-joined path, in file order.
fn flatten(prefix: &str, t: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in t {
        let key = if prefix.is_empty() {
            k.trim_matches('/').to_string()
        } else {
            format!("{prefix}/{}", k.trim_matches('/'))
        };
        match v {
            toml::Value::Table(sub) => flatten(&key, sub, out),
            leaf => out.push((key, leaf.clone())),
        }
    }
}

fn entry(key: &str, value: &toml::Value, axes: u8) -> anyhow::Result<Entry> {
    let pp = resolve(key, axes)?;
    anyhow::ensure!(
        !pp.id.info().read_only,
        "{pp}: read-only (the board sets it itself)"
    );
    let text = match value {
        toml::Value::Integer(i) => i.to_string(),
        toml::Value::Float(f) => f.to_string(),
        toml::Value::Boolean(b) => b.to_string(),
        other => anyhow::bail!("{pp}: {other} is not a number ({})", pp.id.info().unit),
    };
    Ok((pp, parse_value(pp, &text)?))
}

/// Sends a checked set whole: on a refusal that retrying after the others does not
/// clear, every value changed is put back and the error names the refused path.
/// Returns the values in force before, per entry.
pub fn apply(link: &mut Link, entries: &[Entry]) -> anyhow::Result<Vec<f32>> {
    let before = entries
        .iter()
        .map(|&(pp, _)| get(link, pp))
        .collect::<anyhow::Result<Vec<f32>>>()?;
    let mut pending: Vec<usize> = (0..entries.len()).collect();
    let mut changed: Vec<usize> = Vec::new();
    loop {
        let mut refused = Vec::new();
        let mut last_error = None;
        for &i in &pending {
            let (pp, v) = entries[i];
            match set(link, pp, v) {
                Ok(()) => changed.push(i),
                Err(e) => {
                    refused.push(i);
                    last_error = Some(e);
                }
            }
        }
        match last_error {
            None => return Ok(before),
            // Progress: what was refused may have waited for a value set since.
            Some(_) if refused.len() < pending.len() => pending = refused,
            Some(e) => {
                let restore = rollback(link, entries, &before, &changed);
                return Err(match restore {
                    Ok(()) => e.context("the board refused the set: nothing changed"),
                    Err(r) => e.context(format!(
                        "the board refused the set, and putting the old values back failed: {r:#}"
                    )),
                });
            }
        }
    }
}

/// Puts back the values in force before, last changed first.
fn rollback(
    link: &mut Link,
    entries: &[Entry],
    before: &[f32],
    changed: &[usize],
) -> anyhow::Result<()> {
    for &i in changed.iter().rev() {
        set(link, entries[i].0, before[i])?;
    }
    Ok(())
}

/// Every writable setting of the board with its value in force, as a file `load` takes
/// back (`[axis.N]` tables, then the board-wide ones; units in comments).
pub fn dump(link: &mut Link) -> anyhow::Result<String> {
    let axes = link.info.axes;
    let mut axis_lines: Vec<Vec<String>> = vec![Vec::new(); usize::from(axes)];
    let mut board_lines = Vec::new();
    for pp in all_paths(axes).filter(|pp| !pp.id.info().read_only) {
        let v = get(link, pp)?;
        let i = pp.id.info();
        // Per slave under `[axis.N]` by the path after `axis/N/`; board-wide ones whole.
        let line = format!("{:?} = {v} # {}", i.path, i.unit);
        match i.scope {
            Scope::Axis => {
                if let Some(l) = axis_lines.get_mut(usize::from(pp.axis)) {
                    l.push(line);
                }
            }
            Scope::Board => board_lines.push(line),
        }
    }
    let mut out = String::from("# host-sim param dump: `param load` takes it back.\n");
    for l in &board_lines {
        out.push_str(l);
        out.push('\n');
    }
    for (n, lines) in axis_lines.iter().enumerate() {
        out.push_str(&format!("\n[axis.{n}]\n"));
        for l in lines {
            out.push_str(l);
            out.push('\n');
        }
    }
    Ok(out)
}

/// A tuned gain set (`host-sim tune`) as a settings file for the board: each follower
/// axis of `s`, in file order, is slave `first_slave`, `first_slave + 1`, …; each key of
/// its `[tuning.axes.<name>]` is the board's `axis/<n>/<key>`, and the master filter's
/// bandwidth is `master/filter_bandwidth_hz`. Force axes' gains are not board settings
/// and are left out (named in a comment). The text is checked as `param load` checks a
/// file before it is returned.
pub fn from_tuning(s: &Scenario, t: &Tuning, first_slave: u8) -> anyhow::Result<String> {
    let followers: Vec<&str> = crate::sim::control::followers(s)
        .into_iter()
        .map(|a| a.name.as_str())
        .collect();
    let mut out = format!(
        "# {} gains for a {} µs board period (`host-sim param load --port P FILE` sends them;\n\
         # the board's period_us must be {}).\n\"master/filter_bandwidth_hz\" = {}\n",
        t.controller.name(),
        t.period_us,
        t.period_us,
        t.master_filter_hz
    );
    for (k, name) in followers.iter().enumerate() {
        let g = t
            .axes
            .get(*name)
            .ok_or_else(|| anyhow::anyhow!("the gain set has no axis {name}"))?;
        let slave = u8::try_from(k)
            .ok()
            .and_then(|k| k.checked_add(first_slave))
            .ok_or_else(|| anyhow::anyhow!("too many follower axes for slave {first_slave} on"))?;
        out.push_str(&format!("\n# axis {slave}: {name}\n"));
        out.push_str(&crate::autotune::gains_table(&format!("axis.{slave}"), g));
    }
    for name in t.press.keys() {
        out.push_str(&format!(
            "\n# {name}: a force axis; its gains are not board settings\n"
        ));
    }
    let slaves = u8::try_from(followers.len())
        .ok()
        .and_then(|n| n.checked_add(first_slave))
        .ok_or_else(|| anyhow::anyhow!("too many follower axes"))?;
    parse(&out, slaves)
        .map_err(|e| anyhow::anyhow!("the tuned set is not a settings file: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tuned_set_is_a_settings_file_of_board_paths() {
        let s = Scenario::default();
        let t = s
            .tuning
            .iter()
            .find(|t| {
                t.period_us == 1000 && t.controller == crate::scenario::Controller::Feedforward
            })
            .unwrap();
        let text = from_tuning(&s, t, 0).unwrap();
        let e = parse(&text, 1).unwrap();
        let kp = e
            .iter()
            .find(|(pp, _)| pp.to_string() == "axis/0/kp_lsb_per_um")
            .unwrap();
        assert_eq!(kp.1, t.axes["tangent"].kp_lsb_per_um);
        // f32 in its shortest decimal form.
        assert!(text.contains("kp_lsb_per_um = 1.1\n"), "{text}");
        // The backoff's thresholds are board paths too.
        assert!(e
            .iter()
            .any(|(pp, _)| pp.to_string() == "axis/0/backoff/max_level"));
        assert!(e
            .iter()
            .any(|(pp, _)| pp.to_string() == "master/filter_bandwidth_hz"));
        // The side press's force gains are named, not sent.
        assert!(text.contains("# side_press: a force axis"), "{text}");
        // On slave 1 instead: the paths move with it.
        let text1 = from_tuning(&s, t, 1).unwrap();
        assert!(parse(&text1, 2)
            .unwrap()
            .iter()
            .any(|(pp, _)| pp.to_string() == "axis/1/kp_lsb_per_um"));
    }

    #[test]
    fn nested_tables_and_quoted_paths_are_the_same_paths() {
        let e = parse(
            "\"axis/1/valve/null_lsb\" = -3\n[axis.0]\nkp_lsb_per_um = 1.5\n[axis.0.valve]\ninvert = true\n",
            2,
        )
        .unwrap();
        let paths: Vec<String> = e.iter().map(|(pp, _)| pp.to_string()).collect();
        assert_eq!(
            paths,
            [
                "axis/1/valve/null_lsb",
                "axis/0/kp_lsb_per_um",
                "axis/0/valve/invert"
            ]
        );
        assert_eq!(e.iter().map(|e| e.1).collect::<Vec<_>>(), [-3.0, 1.5, 1.0]);
    }

    #[test]
    fn every_problem_is_named_and_nothing_is_returned() {
        let e = parse(
            "[axis.0]\nkp_lsb_per_um = \"fast\"\n[axis.0.valve]\nnull_lsb = -600\n[axis.5]\nkp_lsb_per_um = 1\n[axis.1]\nnonsense = 2\n",
            2,
        )
        .unwrap_err()
        .to_string();
        for p in [
            "4 problem(s)",
            "axis/0/kp_lsb_per_um",
            "axis/0/valve/null_lsb",
            "axis/5/kp_lsb_per_um",
            "axis/1/nonsense",
            "nothing sent",
        ] {
            assert!(e.contains(p), "{p} missing from: {e}");
        }
        let twice = parse(
            "\"axis/0/kp_lsb_per_um\" = 1\n[axis.0]\nkp_lsb_per_um = 2\n",
            2,
        );
        assert!(twice.unwrap_err().to_string().contains("given twice"));
        assert!(parse("", 2)
            .unwrap_err()
            .to_string()
            .contains("no settings"));
        assert!(parse("[axis.0\n", 2).is_err());
    }
}
