//! `host-sim upload --port PORT TABLE.csv [--activate] [--save]`.
//!
//! The CSV (`master,<axis>…`, master in degrees, slaves in mm, see [`crate::camfile`]) is
//! converted to the wire's fixed point — master counts = mdeg (the rotary table's
//! encoder: 0.001° per count) in I48F16, slaves µm in I24F8 — sent in chunks of the
//! board's `max_chunk_rows`, committed with its CRC-32, then optionally activated and
//! saved. First the table is checked against every rule the board applies, with the
//! limits the board reports in Info ([`crate::tablecheck`]): a table it would refuse is
//! refused before anything is sent, naming the CSV line. Any Nak stops the upload with
//! the board's typed reason.

use super::serial::Link;
use crate::camfile::CamCsv;
use hydra_core::protocol::crc::Crc32;
use hydra_core::protocol::handler::ACK_DEFERRED;
use hydra_core::protocol::msg::row_len;
use hydra_core::protocol::Request;
use std::path::PathBuf;

/// Arguments of `upload`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port (or the path `serve --pty` printed).
    #[arg(long)]
    pub port: String,
    /// The table (CSV).
    pub table: PathBuf,
    /// Activate it (now if the board is idle or at the end of its table, else at the next such point).
    #[arg(long)]
    pub activate: bool,
    /// Persist the active table to flash afterwards (the board must be idle).
    #[arg(long)]
    pub save: bool,
    /// Table id (default: CRC-32 of the rows, so the same table keeps its id).
    #[arg(long)]
    pub id: Option<u32>,
    /// Master counts per master unit of the CSV (default 1000: degrees → mdeg).
    #[arg(long, default_value_t = 1000.0)]
    pub master_counts_per_unit: f64,
}

/// Rows of a CSV in wire format: master I48F16 raw, then each slave µm I24F8 raw
/// ([`crate::tablecheck::wire_rows`]).
pub fn rows_bytes(csv: &CamCsv, counts_per_unit: f64) -> anyhow::Result<Vec<u8>> {
    let rows = crate::tablecheck::wire_rows(csv, counts_per_unit)?;
    let mut out = Vec::with_capacity(rows.len() * row_len(csv.axes.len()));
    for (m, xs) in rows {
        out.extend_from_slice(&m.to_le_bytes());
        for x in xs {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    Ok(out)
}

/// Runs the upload.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let csv = CamCsv::load(&args.table)?;
    let cols = csv.axes.len();
    let rows = csv.master.len();
    let data = rows_bytes(&csv, args.master_counts_per_unit)?;
    let crc = {
        let mut c = Crc32::new();
        c.update(&data);
        c.finish()
    };
    let id = args.id.unwrap_or(crc & 0x7FFF_FFFF);
    let mut link = Link::open(&args.port)?;
    let info = link.info;
    // Every rule the board applies at commit, with the limits it reported: a table it
    // would refuse is refused here, naming the CSV line, before anything is sent.
    crate::tablecheck::check(
        &csv,
        &crate::tablecheck::BoardRules::of_info(&info),
        args.master_counts_per_unit,
    )?;
    link.expect_ack(&Request::TableBegin {
        id,
        columns: cols as u8,
        rows: rows as u16,
    })?;
    let per = usize::from(info.max_chunk_rows.max(1));
    let rl = row_len(cols);
    let bar = indicatif::ProgressBar::new(rows as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} rows")?
            .progress_chars("=> "),
    );
    bar.set_message("upload");
    let mut off = 0usize;
    while off < rows {
        let n = per.min(rows - off);
        link.expect_ack(&Request::TableChunk {
            offset: off as u16,
            count: n as u8,
            data: &data[off * rl..(off + n) * rl],
        })?;
        off += n;
        bar.set_position(off as u64);
    }
    link.expect_ack(&Request::TableCommit { crc })?;
    bar.finish_with_message("committed");
    eprintln!("table {id} ({rows} rows, CRC-32 {crc:08x}) committed");
    if args.activate {
        let f = link.expect_ack(&Request::Activate { id })?;
        if f & ACK_DEFERRED != 0 {
            eprintln!("activation armed: takes effect at the next safe point");
        } else {
            eprintln!("table {id} active");
        }
    }
    if args.save {
        eprintln!(
            "saving to flash: the board erases a sector (up to 2 s, its tick paused, axes idle) …"
        );
        link.expect_ack(&Request::Save)?;
        eprintln!("saved to flash");
    }
    println!("{id}");
    Ok(())
}
