//! CSV output on the `csv` crate: a header row, then one record per row, each field
//! formatted by the caller at the precision its unit needs. The crate quotes a field that
//! needs it (an axis named `x, left` stays one column) and ends records with `\n`.

use std::io::Write;

/// A CSV writer over any byte sink (a file, stdout, memory).
pub struct CsvOut<W: Write> {
    w: csv::Writer<W>,
    fields: usize,
}

impl<W: Write> CsvOut<W> {
    /// Starts the output with its header.
    pub fn new<I, T>(sink: W, header: I) -> csv::Result<Self>
    where
        I: IntoIterator<Item = T>,
        T: AsRef<[u8]>,
    {
        let mut w = csv::WriterBuilder::new()
            .terminator(csv::Terminator::Any(b'\n'))
            .from_writer(sink);
        let header: Vec<T> = header.into_iter().collect();
        w.write_record(&header)?;
        Ok(Self {
            w,
            fields: header.len(),
        })
    }

    /// Writes one record. Its field count must be the header's; another is refused
    /// before anything is written (the crate would detect it only after writing the
    /// record's first fields).
    pub fn row<I, T>(&mut self, fields: I) -> anyhow::Result<()>
    where
        I: IntoIterator<Item = T>,
        T: AsRef<[u8]>,
    {
        let fields: Vec<T> = fields.into_iter().collect();
        anyhow::ensure!(
            fields.len() == self.fields,
            "a CSV record of {} fields under a header of {}",
            fields.len(),
            self.fields
        );
        Ok(self.w.write_record(&fields)?)
    }

    /// Flushes and returns the sink.
    pub fn finish(self) -> anyhow::Result<W> {
        self.w
            .into_inner()
            .map_err(|e| anyhow::anyhow!("writing CSV: {}", e.error()))
    }
}

impl CsvOut<Vec<u8>> {
    /// A CSV text built in memory.
    pub fn text(self) -> String {
        // Memory writes do not fail and every field is UTF-8 text.
        let bytes = self.finish().unwrap_or_default();
        String::from_utf8(bytes).unwrap_or_default()
    }
}

/// Checks now that `path` can be written, so a command that records for a while before
/// writing fails at once, naming the path. An existing file is left as it is (opened to
/// append, nothing written); a new one is created and removed again.
pub fn writable(path: &std::path::Path) -> anyhow::Result<()> {
    let existed = path.exists();
    std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(path)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    if !existed {
        let _ = std::fs::remove_file(path);
    }
    Ok(())
}

/// Writes `text` to `path`, an error naming the path.
pub fn save(path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    std::fs::write(path, text).map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_when_needed_and_counts_checked() {
        let mut o = CsvOut::new(Vec::new(), ["master", "x, left", "say \"y\""]).unwrap();
        o.row(["0.000000", "1.5", "2"]).unwrap();
        assert!(o.row(["1", "2"]).is_err(), "a short record is refused");
        assert_eq!(
            o.text(),
            "master,\"x, left\",\"say \"\"y\"\"\"\n0.000000,1.5,2\n"
        );
    }
}
