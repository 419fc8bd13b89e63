//! Cam tables as CSV files, in engineering units.
//!
//! ```text
//! # comment lines and blank lines are ignored
//! master,tangent            ← header: `master`, then one column per slave axis
//! 0.0,248.961069            ← master in degrees (or the master's unit), slaves in mm
//! 0.5,254.897310
//! ```
//!
//! The master column must be strictly monotonic (increasing or decreasing); every value
//! must be a finite number; every row has as many fields as the header. A bad file is a
//! [`TableError`] naming the file, the line (1-based) and what is wrong.

use std::path::{Path, PathBuf};

/// A problem with a cam-table CSV file.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The file cannot be read.
    #[error("cannot read table {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A problem at a line of the file.
    #[error("{path}:{line}: {reason}")]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A problem with the file as a whole.
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// A cam table: master nodes and one slave column per axis.
#[derive(Clone, Debug, PartialEq)]
pub struct CamCsv {
    /// Where it was loaded from (for messages).
    pub path: PathBuf,
    /// Slave axis names, in column order (after `master`).
    pub axes: Vec<String>,
    /// Master value of each node (degrees for the rotary table).
    pub master: Vec<f64>,
    /// `columns[axis][node]`: slave positions, mm.
    pub columns: Vec<Vec<f64>>,
    /// 1-based line number of each node (for messages about a node).
    pub lines: Vec<usize>,
    /// 1-based line number of the header (for messages about the columns).
    pub header_line: usize,
}

/// The records of a CSV text read by the `csv` crate: the header and the data rows, each
/// with its 1-based line number and its fields trimmed. `#` comment lines and blank lines
/// are skipped, quoted fields are allowed, a UTF-8 byte-order mark (which Excel writes) is
/// skipped. A header that is one field holding `;` is refused in words: the file was
/// written with `;` as the separator (a locale with decimal commas). An empty text is an
/// error naming the header it should have had (`expected`).
pub struct CsvRecords {
    /// 1-based line of the header.
    pub header_line: usize,
    /// The header's fields.
    pub header: Vec<String>,
    /// `(line, fields)` of every data row.
    pub rows: Vec<(usize, Vec<String>)>,
}

/// Reads `text` (see [`CsvRecords`]); `path` is only used in messages.
pub fn csv_records(text: &str, path: &Path, expected: &str) -> Result<CsvRecords, TableError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut r = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    // The 1-based line where a record starts. The reader's positions point at the line
    // ends and `#` comment lines it skipped before the record (and its own line count
    // skips blank lines), so the line is counted from the first byte after them.
    let line_of = |byte: u64| {
        let b = text.as_bytes();
        let mut end = usize::try_from(byte).unwrap_or(usize::MAX).min(b.len());
        loop {
            match b.get(end) {
                Some(b'\r' | b'\n') => end += 1,
                Some(b'#') => {
                    end = b[end..]
                        .iter()
                        .position(|c| *c == b'\n')
                        .map_or(b.len(), |k| end + k + 1);
                }
                _ => break,
            }
        }
        1 + b[..end].iter().filter(|c| **c == b'\n').count()
    };
    let mut recs = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| line_of(p.byte()));
            line_error(path, line, format!("not CSV: {e}"))
        })?;
        if rec.iter().all(str::is_empty) {
            continue;
        }
        let line = rec.position().map_or(0, |p| line_of(p.byte()));
        recs.push((line, rec.iter().map(str::to_string).collect::<Vec<_>>()));
    }
    let mut it = recs.into_iter();
    let (header_line, header) = it.next().ok_or_else(|| TableError::File {
        path: path.to_path_buf(),
        reason: format!("empty file: expected a header `{expected}`"),
    })?;
    if let [one] = &header[..] {
        if one.contains(';') {
            return Err(line_error(
                path,
                header_line,
                format!(
                    "the separator is `;` (`{one}`), as a spreadsheet writes it with decimal commas: save the file comma-separated with decimal points (expected `{expected}`)"
                ),
            ));
        }
    }
    Ok(CsvRecords {
        header_line,
        header,
        rows: it.collect(),
    })
}

/// An error at a line of a CSV file.
pub fn line_error(path: &Path, line: usize, reason: String) -> TableError {
    TableError::Line {
        path: path.to_path_buf(),
        line,
        reason,
    }
}

impl CamCsv {
    /// Reads and parses a CSV file.
    pub fn load(path: &Path) -> Result<Self, TableError> {
        let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses CSV text; `path` is only used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, TableError> {
        let at = |line: usize, reason: String| line_error(path, line, reason);
        let CsvRecords {
            header_line: hline,
            header: names,
            rows,
        } = csv_records(text, path, "master,<axis>,…")?;
        if names.first().map(String::as_str) != Some("master") {
            return Err(at(
                hline,
                format!(
                    "header must start with `master`, found `{}`",
                    names.join(",")
                ),
            ));
        }
        if names.len() < 2 {
            return Err(at(hline, "header has no axis column after `master`".into()));
        }
        let axes = names[1..].to_vec();
        for (i, a) in axes.iter().enumerate() {
            if a.is_empty() {
                return Err(at(hline, format!("column {} has an empty name", i + 2)));
            }
            if axes[..i].contains(a) {
                return Err(at(hline, format!("axis column `{a}` appears twice")));
            }
        }
        let mut master = Vec::new();
        let mut columns = vec![Vec::new(); axes.len()];
        let mut lines = Vec::new();
        for (line, fields) in rows {
            if fields.len() != names.len() {
                return Err(at(
                    line,
                    format!(
                        "{} fields, the header has {} ({})",
                        fields.len(),
                        names.len(),
                        names.join(",")
                    ),
                ));
            }
            let mut values = Vec::with_capacity(fields.len());
            for (f, name) in fields.iter().zip(&names) {
                let v: f64 = f
                    .parse()
                    .map_err(|_| at(line, format!("column `{name}`: `{f}` is not a number")))?;
                if !v.is_finite() {
                    return Err(at(line, format!("column `{name}`: `{f}` is not finite")));
                }
                values.push(v);
            }
            let m = values[0];
            if let [.., a, b] = master[..] {
                let rising = b > a;
                if (rising && m <= b) || (!rising && m >= b) {
                    return Err(at(
                        line,
                        format!(
                            "master {m} does not continue the strictly {} sequence (previous {b})",
                            if rising { "increasing" } else { "decreasing" }
                        ),
                    ));
                }
            } else if let [b] = master[..] {
                if m == b {
                    return Err(at(line, format!("master {m} repeats the previous node")));
                }
            }
            master.push(m);
            for (c, v) in columns.iter_mut().zip(&values[1..]) {
                c.push(*v);
            }
            lines.push(line);
        }
        if master.len() < 2 {
            return Err(TableError::File {
                path: path.to_path_buf(),
                reason: format!("{} node(s): a table needs at least 2", master.len()),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            axes,
            master,
            columns,
            lines,
            header_line: hline,
        })
    }

    /// The column of an axis, mm.
    pub fn column(&self, axis: &str) -> Option<&[f64]> {
        let i = self.axes.iter().position(|a| a == axis)?;
        self.columns.get(i).map(Vec::as_slice)
    }

    /// The CSV text (6 decimals: 1 nm, 1 µdeg).
    pub fn to_csv(&self) -> String {
        let header = std::iter::once("master").chain(self.axes.iter().map(String::as_str));
        let Ok(mut o) = crate::csvout::CsvOut::new(Vec::new(), header) else {
            return String::new();
        };
        for (i, m) in self.master.iter().enumerate() {
            let cols = self.columns.iter().map(|c| format!("{:.6}", c[i]));
            if o.row(std::iter::once(format!("{m:.6}")).chain(cols))
                .is_err()
            {
                return String::new();
            }
        }
        o.text()
    }
}

/// Linear interpolation in a node table, held at the end values outside it; `hint`
/// is the segment found last time (the search starts there: O(1) for a slowly moving
/// argument). `master` must be strictly monotonic (as [`CamCsv`] guarantees).
pub fn interpolate(master: &[f64], slave: &[f64], m: f64, hint: &mut usize) -> f64 {
    let n = master.len();
    let rising = master[n - 1] > master[0];
    let key = |v: f64| if rising { v } else { -v };
    let k = key(m);
    if k <= key(master[0]) {
        *hint = 0;
        return slave[0];
    }
    if k >= key(master[n - 1]) {
        *hint = n - 2;
        return slave[n - 1];
    }
    let mut j = (*hint).min(n - 2);
    while j > 0 && k < key(master[j]) {
        j -= 1;
    }
    while j < n - 2 && k >= key(master[j + 1]) {
        j += 1;
    }
    *hint = j;
    let f = (m - master[j]) / (master[j + 1] - master[j]);
    slave[j] + f * (slave[j + 1] - slave[j])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<CamCsv, TableError> {
        CamCsv::parse(s, Path::new("t.csv"))
    }

    #[test]
    fn parses_and_roundtrips() {
        let t = parse("# c\nmaster, a ,b\n0,1,2\n\n1,3,4\n2,5,6\n").unwrap();
        assert_eq!(t.header_line, 2);
        assert_eq!(t.axes, ["a", "b"]);
        assert_eq!(t.master, [0.0, 1.0, 2.0]);
        assert_eq!(t.column("b").unwrap(), [2.0, 4.0, 6.0]);
        assert_eq!(t.lines, [3, 5, 6]);
        let again = parse(&t.to_csv()).unwrap();
        assert_eq!(again.columns, t.columns);
    }

    #[test]
    fn errors_name_the_line() {
        let e = |s: &str| parse(s).unwrap_err().to_string();
        assert!(e("").contains("empty file"));
        assert!(e("x,a\n0,1\n").contains("t.csv:1: header must start with `master`"));
        assert!(e("master\n0\n").contains("no axis column"));
        assert!(e("master,a,a\n").contains("appears twice"));
        assert!(e("master,a\n0,1\n1,2,3\n").contains("t.csv:3: 3 fields"));
        assert!(e("master,a\n0,1\n1,zz\n").contains("t.csv:3: column `a`: `zz` is not a number"));
        assert!(e("master,a\n0,1\n1,inf\n").contains("not finite"));
        assert!(e("master,a\n0,1\n1,2\n0.5,3\n").contains("t.csv:4: master 0.5 does not continue"));
        assert!(e("master,a\n0,1\n0,2\n").contains("t.csv:3: master 0 repeats"));
        assert!(e("master,a\n0,1\n").contains("1 node(s)"));
    }

    /// What a spreadsheet writes: a UTF-8 byte-order mark, CRLF line ends, quoted fields
    /// — read; `;` separators — refused in words.
    #[test]
    fn reads_what_excel_writes_and_names_a_semicolon_separator() {
        let t = parse("\u{feff}master,\"tangent\"\r\n0,1.5\r\n\"1\",2.5\r\n").unwrap();
        assert_eq!(t.axes, ["tangent"]);
        assert_eq!(t.master, [0.0, 1.0]);
        assert_eq!(t.lines, [2, 3]);
        let e = parse("master;tangent\n0;1,5\n1;2,5\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.csv:1: the separator is `;`"), "{e}");
    }

    #[test]
    fn interpolates_both_directions() {
        let m = [0.0, 1.0, 2.0];
        let s = [0.0, 10.0, 30.0];
        let mut h = 0;
        assert_eq!(interpolate(&m, &s, 1.5, &mut h), 20.0);
        assert_eq!(h, 1);
        assert_eq!(interpolate(&m, &s, 0.25, &mut h), 2.5);
        assert_eq!(interpolate(&m, &s, -1.0, &mut h), 0.0);
        assert_eq!(interpolate(&m, &s, 9.0, &mut h), 30.0);
        let md = [2.0, 1.0, 0.0];
        let sd = [30.0, 10.0, 0.0];
        assert_eq!(interpolate(&md, &sd, 1.5, &mut h), 20.0);
        assert_eq!(interpolate(&md, &sd, 0.5, &mut h), 5.0);
    }
}
