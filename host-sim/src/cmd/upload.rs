//! `host-sim upload --port PORT TABLE.csv [--activate] [--save]`.
//!
//! The CSV (`master,<axis>…`, master in degrees, slaves in mm, see [`crate::camfile`]) is
//! converted to core's fixed point ([`crate::tablecheck::nodes`]) — master counts = mdeg
//! (the rotary table's encoder: 0.001° per count) in I48F16, slaves µm in I24F8 — sent in
//! chunks of the board's `max_chunk_rows` by core's upload sequence, committed with its
//! CRC-32, then optionally activated and saved. First the table is checked against every rule the board applies, with the
//! limits the board reports in Info ([`crate::tablecheck`]): a table it would refuse is
//! refused before anything is sent, naming the CSV line. Any Nak stops the upload with
//! the board's typed reason.

use super::serial::Link;
use crate::camfile::CamCsv;
use hydra_core::protocol::handler::ACK_DEFERRED;
use hydra_core::protocol::upload::TableUpload;
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

/// Runs the upload.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let csv = CamCsv::load(&args.table)?;
    let mut link = Link::open(&args.port)?;
    let info = link.info;
    // Every rule the board applies at commit, with the limits it reported: a table it
    // would refuse is refused here, naming the CSV line, before anything is sent.
    crate::tablecheck::check(
        &csv,
        &crate::tablecheck::BoardRules::of_info(&info),
        args.master_counts_per_unit,
    )?;
    let per = usize::from(info.max_chunk_rows.max(1));
    let id = crate::with_slaves!(csv.axes.len(), S => send::<S>(&mut link, &csv, args, per)?, {
        anyhow::bail!("{} slave columns: a table row carries 1 … 8", csv.axes.len())
    });
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

/// Sends the table (core's [`TableUpload`] sequence, each request acknowledged) and
/// returns its id.
fn send<const S: usize>(
    link: &mut Link,
    csv: &CamCsv,
    args: &Args,
    per: usize,
) -> anyhow::Result<u32> {
    let nodes = crate::tablecheck::nodes::<S>(csv, args.master_counts_per_unit)?;
    let up = TableUpload::new(0, &nodes, per).map_err(|e| anyhow::anyhow!("upload: {e:?}"))?;
    let crc = up.crc();
    let id = args.id.unwrap_or(crc & 0x7FFF_FFFF);
    let mut up = up.with_id(id);
    let bar = indicatif::ProgressBar::new(nodes.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} rows")?
            .progress_chars("=> "),
    );
    bar.set_message("upload");
    let mut buf = vec![0u8; up.chunk_bytes()];
    while let Some(q) = up
        .next_request(&mut buf)
        .map_err(|e| anyhow::anyhow!("upload: {e:?}"))?
    {
        link.expect_ack(&q)?;
        bar.set_position(up.rows_sent() as u64);
    }
    bar.finish_with_message("committed");
    eprintln!(
        "table {id} ({} rows, CRC-32 {crc:08x}) committed",
        nodes.len()
    );
    Ok(id)
}
