//! What a board checks when a table is committed, checked on the host before an upload:
//! the same rules (`hydra_core::table::check_nodes`, the code the board runs) with the
//! board's profile and limits — those a connected board reports in Info, or the
//! firmware's own (`hydra_core::profile`) — each failure naming the CSV line, the value
//! and the limit.
//!
//! The CSV is converted exactly as `upload` sends it ([`nodes`]): master × counts per
//! unit in I48F16 master counts, slaves mm × 1000 in I24F8 µm.

use crate::camfile::CamCsv;
use hydra_core::profile;
use hydra_core::protocol::msg::{Info, InfoLimits};
use hydra_core::table::{
    check_nodes, AxisLimits, Node, TableError, TableLimits, MAX_SEGMENT_COUNTS,
};
use hydra_core::units::{Master, MasterRate, PosUm, VelUmPerS};

/// The rules of one board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardRules {
    /// Slave columns.
    pub axes: usize,
    /// Table capacity, rows.
    pub capacity_rows: usize,
    /// Longest segment, master counts.
    pub max_segment_counts: u32,
    /// The limits in force (raw fixed-point bits).
    pub limits: InfoLimits,
}

impl BoardRules {
    /// The rules a connected board reported.
    pub fn of_info(i: &Info) -> Self {
        Self {
            axes: usize::from(i.axes),
            capacity_rows: usize::from(i.capacity_rows),
            max_segment_counts: i.max_segment_counts,
            limits: i.limits,
        }
    }

    /// The firmware's own profile at boot (before any SetParam).
    pub fn firmware() -> Self {
        Self {
            axes: profile::SLAVES,
            capacity_rows: profile::TABLE_NODES,
            max_segment_counts: MAX_SEGMENT_COUNTS,
            limits: InfoLimits::of(&profile::table_limits()),
        }
    }

    /// The master top speed, master counts/s.
    pub fn master_speed_per_s(&self) -> f64 {
        MasterRate::from_bits(self.limits.master_speed_per_s).to_num()
    }

    fn table_limits<const S: usize>(&self) -> TableLimits<S> {
        TableLimits {
            master_speed_per_s: MasterRate::from_bits(self.limits.master_speed_per_s),
            axes: core::array::from_fn(|k| {
                let a = self.limits.axes.get(k).copied().unwrap_or_default();
                AxisLimits {
                    min_um: PosUm::from_bits(a.min_um),
                    max_um: PosUm::from_bits(a.max_um),
                    max_speed_um_per_s: VelUmPerS::from_bits(a.max_speed_um_per_s),
                }
            }),
        }
    }
}

/// Why a table would be refused: the line and the message.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{file}{}: {reason}", line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct CheckError {
    /// The file.
    pub file: String,
    /// The 1-based line of the row the board would refuse (`None`: the table as a whole).
    pub line: Option<usize>,
    /// What is wrong, with the value and the board's limit.
    pub reason: String,
}

/// The table as the board receives it (`upload` sends these): per row the master in
/// master counts ([`Master`], I48F16) and each slave in µm ([`PosUm`], I24F8), converted
/// by core's own fixed-point types (round to nearest). A value outside its format names
/// its line.
pub fn nodes<const S: usize>(
    csv: &CamCsv,
    counts_per_unit: f64,
) -> Result<Vec<Node<S>>, CheckError> {
    let err = |row: usize, reason: String| CheckError {
        file: csv.path.display().to_string(),
        line: csv.lines.get(row).copied(),
        reason,
    };
    let mut out = Vec::with_capacity(csv.master.len());
    for (i, m) in csv.master.iter().enumerate() {
        let master = Master::checked_from_num(m * counts_per_unit)
            .ok_or_else(|| err(i, format!("master {m} is out of range")))?;
        let mut slave_um = [PosUm::ZERO; S];
        for (a, x) in slave_um.iter_mut().enumerate() {
            let mm = csv
                .columns
                .get(a)
                .and_then(|c| c.get(i))
                .copied()
                .unwrap_or(0.0);
            *x = PosUm::checked_from_num(mm * 1000.0).ok_or_else(|| {
                err(
                    i,
                    format!(
                        "{} = {mm} mm is out of range (±8 388 mm)",
                        csv.axes.get(a).map_or("?", |s| s.as_str())
                    ),
                )
            })?;
        }
        out.push(Node { master, slave_um });
    }
    Ok(out)
}

/// Calls `$body` with `$S` the const slave count `$n` (1 … 8, the most a table row
/// carries), else evaluates `$other`.
#[macro_export]
macro_rules! with_slaves {
    ($n:expr, $S:ident => $body:expr, $other:expr) => {
        match $n {
            1 => {
                const $S: usize = 1;
                $body
            }
            2 => {
                const $S: usize = 2;
                $body
            }
            3 => {
                const $S: usize = 3;
                $body
            }
            4 => {
                const $S: usize = 4;
                $body
            }
            5 => {
                const $S: usize = 5;
                $body
            }
            6 => {
                const $S: usize = 6;
                $body
            }
            7 => {
                const $S: usize = 7;
                $body
            }
            8 => {
                const $S: usize = 8;
                $body
            }
            _ => $other,
        }
    };
}

/// Checks `csv` against `rules` (`counts_per_unit`: master counts per CSV master unit).
pub fn check(csv: &CamCsv, rules: &BoardRules, counts_per_unit: f64) -> Result<(), CheckError> {
    let file = csv.path.display().to_string();
    if !(counts_per_unit.is_finite() && counts_per_unit > 0.0) {
        return Err(CheckError {
            file,
            line: None,
            reason: format!("master counts per unit {counts_per_unit}: must be a positive number"),
        });
    }
    if csv.axes.len() != rules.axes {
        return Err(CheckError {
            file,
            line: Some(csv.header_line),
            reason: format!(
                "{} slave column{} ({}); the board has {} slaves, one column each",
                csv.axes.len(),
                if csv.axes.len() == 1 { "" } else { "s" },
                csv.axes.join(", "),
                rules.axes
            ),
        });
    }
    let r = with_slaves!(rules.axes, S => check_s::<S>(&nodes::<S>(csv, counts_per_unit)?, rules), {
        return Err(CheckError {
            file,
            line: None,
            reason: format!("a board of {} slaves (1 … 8 supported)", rules.axes),
        })
    });
    r.map_err(|e| explain(csv, rules, counts_per_unit, e))
}

fn check_s<const S: usize>(nodes: &[Node<S>], rules: &BoardRules) -> Result<(), TableError> {
    check_nodes(
        nodes,
        &rules.table_limits::<S>(),
        rules.capacity_rows,
        rules.max_segment_counts,
    )
}

/// The board's rule broken, in engineering units.
fn explain(csv: &CamCsv, rules: &BoardRules, cpu: f64, e: TableError) -> CheckError {
    let at = |row: usize| csv.lines.get(row).copied();
    let lim = |axis: usize| rules.limits.axes.get(axis).copied().unwrap_or_default();
    let mm = |bits: i32| f64::from(bits) / 256.0 / 1000.0;
    let vmax_master = rules.master_speed_per_s() / cpu; // master units/s
    let prev = |row: usize| -> usize {
        // The row before in increasing master order (the board's order).
        let decreasing = csv.master.len() > 1 && csv.master[1] < csv.master[0];
        if decreasing {
            row + 1
        } else {
            row.saturating_sub(1)
        }
    };
    let (line, reason) = match e {
        TableError::TooFewNodes => (None, "a table needs at least 2 rows".to_string()),
        TableError::TooManyNodes { capacity } => (
            None,
            format!("{} rows; the board holds {capacity}", csv.master.len()),
        ),
        TableError::NotMonotonic { row } => (
            at(row),
            format!(
                "master {} does not continue the master column's direction (it must be strictly monotonic)",
                csv.master[row]
            ),
        ),
        TableError::SegmentLength { row } => {
            let p = prev(row);
            let d = (csv.master[row] - csv.master[p]).abs();
            (
                at(row),
                format!(
                    "the segment from line {} is {d} master units = {:.0} master counts; the board allows 2^-15 … {} counts ({} master units) between rows",
                    at(p).unwrap_or(0),
                    d * cpu,
                    rules.max_segment_counts,
                    f64::from(rules.max_segment_counts) / cpu
                ),
            )
        }
        TableError::OutOfRange { row, axis } => {
            let l = lim(axis);
            (
                at(row),
                format!(
                    "{} = {} mm is outside the board's limits {} … {} mm",
                    csv.axes[axis],
                    csv.columns[axis][row],
                    mm(l.min_um),
                    mm(l.max_um)
                ),
            )
        }
        TableError::TooSteep { row, axis } => {
            let p = prev(row);
            let dx = csv.columns[axis][row] - csv.columns[axis][p];
            let dm = (csv.master[row] - csv.master[p]).abs();
            let v = if dm > 0.0 { dx.abs() / dm * vmax_master } else { f64::INFINITY };
            (
                at(row),
                format!(
                    "{} moves {dx:.3} mm over {dm} master units from line {}: {v:.1} mm/s at the master's top speed of {vmax_master} units/s; the board allows {} mm/s",
                    csv.axes[axis],
                    at(p).unwrap_or(0),
                    mm(lim(axis).max_speed_um_per_s)
                ),
            )
        }
        TableError::MasterSpeed => (
            None,
            "the board's master top speed is not positive".to_string(),
        ),
    };
    CheckError {
        file: csv.path.display().to_string(),
        line,
        reason,
    }
}

/// Each slave's velocity (mm/s) and acceleration (mm/s²) along the table with the master at
/// `rules`' top speed, per node: the velocity is the slope of the segment that starts at
/// the node (the last node keeps the last segment's) × the master speed; the acceleration
/// is the velocity change at the node over the shorter of its two segments' durations (a
/// cam table of straight segments changes velocity at its nodes; the follower's
/// feed-forward sees that change spread over about one segment).
pub fn kinematics(
    csv: &CamCsv,
    rules: &BoardRules,
    counts_per_unit: f64,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    // Master units per second at the top speed.
    let w = rules.master_speed_per_s() / counts_per_unit;
    let m = &csv.master;
    let n = m.len();
    csv.columns
        .iter()
        .map(|x| {
            let slope = |k: usize| {
                let dm = m[k + 1] - m[k];
                if dm > 0.0 {
                    (x[k + 1] - x[k]) / dm
                } else {
                    0.0
                }
            };
            let v: Vec<f64> = (0..n)
                .map(|k| if n < 2 { 0.0 } else { slope(k.min(n - 2)) * w })
                .collect();
            let a: Vec<f64> = (0..n)
                .map(|k| {
                    if k == 0 || k + 1 >= n {
                        return 0.0;
                    }
                    let dt = (m[k] - m[k - 1]).min(m[k + 1] - m[k]) / w;
                    if dt > 0.0 {
                        (v[k] - v[k - 1]) / dt
                    } else {
                        0.0
                    }
                })
                .collect();
            (v, a)
        })
        .collect()
}

/// `table check --plot`: per slave, position against the master with the board's range,
/// velocity at the master's top speed with the slave's speed limit, and acceleration.
pub fn plot(
    csv: &CamCsv,
    rules: &BoardRules,
    counts_per_unit: f64,
    path: &std::path::Path,
) -> anyhow::Result<()> {
    use crate::plot::{plot_panels, Panel};
    let n = csv.master.len();
    let kin = kinematics(csv, rules, counts_per_unit);
    let mut ps = Vec::new();
    for (k, (name, x)) in csv.axes.iter().zip(&csv.columns).enumerate() {
        let lim = rules.limits.axes.get(k).copied().unwrap_or_default();
        let mm = |raw: i32| f64::from(raw) / 256_000.0;
        let flat = |v: f64| vec![v; n];
        ps.push(Panel {
            title: format!("{name}: position"),
            y_label: "mm".into(),
            series: vec![
                (name.clone(), x.clone()),
                ("min".into(), flat(mm(lim.min_um))),
                ("max".into(), flat(mm(lim.max_um))),
            ],
        });
        let (v, a) = &kin[k];
        let vmax = mm(lim.max_speed_um_per_s);
        ps.push(Panel {
            title: format!(
                "{name}: velocity at the master's top speed ({} counts/s)",
                rules.master_speed_per_s()
            ),
            y_label: "mm/s".into(),
            series: vec![
                ("velocity".into(), v.clone()),
                ("+limit".into(), flat(vmax)),
                ("−limit".into(), flat(-vmax)),
            ],
        });
        ps.push(Panel {
            title: format!("{name}: acceleration at the nodes (same master speed)"),
            y_label: "mm/s²".into(),
            series: vec![("acceleration".into(), a.clone())],
        });
    }
    let title = format!("{} — {n} rows", csv.path.display());
    plot_panels(path, &title, ("master", &csv.master), &ps, None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn csv(text: &str) -> CamCsv {
        CamCsv::parse(text, Path::new("t.csv")).expect("csv")
    }

    #[test]
    fn the_board_table_passes_the_firmware_rules() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let t = CamCsv::load(&root.join("scenarios/tangent_board.csv")).expect("load");
        assert_eq!(check(&t, &BoardRules::firmware(), 1000.0), Ok(()));
        // The one-column table is refused for the two-slave board, naming the header.
        let t1 = CamCsv::load(&root.join("scenarios/tangent_table.csv")).expect("load");
        let e = check(&t1, &BoardRules::firmware(), 1000.0).unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");
        assert!(e.reason.contains("the board has 2 slaves"), "{e}");
    }

    #[test]
    fn velocity_and_acceleration_at_the_top_master_speed() {
        // 10 °/s top speed (firmware profile: 10 000 counts/s); a rises 1 mm over 1°, then
        // stays: 10 mm/s, then 0; the change at node 1 over 0.1 s is −100 mm/s².
        let r = BoardRules::firmware();
        let t = csv("master,a,b\n0,10,10\n1,11,10\n2,11,10\n");
        let k = kinematics(&t, &r, 1000.0);
        let (v, a) = &k[0];
        assert_eq!(v, &vec![10.0, 0.0, 0.0]);
        assert_eq!(a, &vec![0.0, -100.0, 0.0]);
        let dir = tempfile::tempdir().expect("tempdir");
        let svg = dir.path().join("t.svg");
        plot(&t, &r, 1000.0, &svg).expect("plot");
        let text = std::fs::read_to_string(&svg).expect("svg");
        assert!(text.contains("velocity at the master") && text.contains("+limit"));
    }

    #[test]
    fn each_rule_names_its_line_value_and_limit() {
        let r = BoardRules::firmware();
        let cases = [
            // 600 mm > 500 mm on line 4 (comment line 2 counts).
            (
                "master,a,b\n# c\n0,10,10\n1,600,10\n",
                Some(4),
                "600 mm is outside the board's limits 0 … 500 mm",
            ),
            // 30 mm in 0.1° at 10°/s = 3000 mm/s > 200 mm/s.
            ("master,a,b\n0,10,10\n0.1,40,10\n", Some(3), "3000.0 mm/s"),
            // 70° = 70 000 counts > 65 535.
            ("master,a,b\n0,10,10\n70,10,10\n", Some(3), "65535 counts"),
        ];
        for (text, line, needle) in cases {
            let e = check(&csv(text), &r, 1000.0).unwrap_err();
            assert_eq!(e.line, line, "{e}");
            assert!(e.to_string().contains(needle), "{e}");
            assert!(e.to_string().starts_with("t.csv:"), "{e}");
        }
        // The header's own line, also with a comment before the first row.
        let e = check(&csv("# cam\nmaster,a\n# units mm\n0,1\n1,2\n"), &r, 1000.0).unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
        // A master scale that is not positive is refused, not misread.
        let e = check(&csv("master,a,b\n0,10,10\n1,10,10\n"), &r, -1000.0).unwrap_err();
        assert!(e.reason.contains("must be a positive number"), "{e}");
        // Too many rows for the board: the table as a whole.
        let mut big = String::from("master,a,b\n");
        for i in 0..300 {
            big.push_str(&format!("{},10,10\n", i as f64 * 0.1));
        }
        let e = check(&csv(&big), &r, 1000.0).unwrap_err();
        assert_eq!(e.line, None);
        assert!(e.reason.contains("300 rows; the board holds 256"), "{e}");
    }

    #[test]
    fn a_board_with_other_limits_is_checked_with_them() {
        let mut i = Info {
            axes: 2,
            capacity_rows: 256,
            max_segment_counts: MAX_SEGMENT_COUNTS,
            limits: InfoLimits::of(&profile::table_limits()),
            ..Info::default()
        };
        let t = csv("master,a,b\n0,10,10\n1,300,10\n");
        // 290 mm over 1° at 10°/s = 2 900 mm/s: refused by the firmware's 200 mm/s …
        assert!(check(&t, &BoardRules::of_info(&i), 1000.0).is_err());
        // … accepted by a board whose axis 0 may move 5 m/s.
        i.limits.axes[0].max_speed_um_per_s = 5_000_000 << 8;
        assert_eq!(check(&t, &BoardRules::of_info(&i), 1000.0), Ok(()));
        // A board with shorter segments (1 000 counts = 1°) refuses a 2° one, on its line.
        i.max_segment_counts = 1000;
        let t2 = csv("master,a,b\n0,10,10\n1,10,10\n3,10,10\n");
        let e = check(&t2, &BoardRules::of_info(&i), 1000.0).unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
        assert!(e.reason.contains("2000 master counts"), "{e}");
    }
}
