//! `host-sim table list|activate --port PORT [--id N] [--json]`: the board's tables — the
//! active one, the committed one waiting for Activate, the saved one — and activating a
//! committed table (`upload` commits without activating unless `--activate`).
//! `host-sim table check FILE.csv [--port PORT] [--json]`: every rule the board applies
//! at commit ([`crate::tablecheck`]), with the connected board's profile and limits, or
//! the firmware's own without `--port`; a failure names the CSV line and exits non-zero.

use super::serial::Link;
use super::status;
use hydra_core::protocol::handler::ACK_DEFERRED;
use hydra_core::protocol::{Request, Response};

/// What to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum What {
    /// The active, committed and saved table ids.
    List,
    /// Activate the committed table `--id` (now if idle or at the table's end, else at
    /// the next such point).
    Activate,
    /// Check a CSV table against the board's rules (no upload).
    Check,
}

/// Arguments of `table`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port (list, activate; check: the board whose rules apply).
    #[arg(long)]
    pub port: Option<String>,
    /// What to do.
    #[arg(value_enum)]
    pub what: What,
    /// The table (check).
    pub file: Option<std::path::PathBuf>,
    /// Master counts per master unit of the CSV (check; default 1000: degrees → mdeg).
    #[arg(long, default_value_t = 1000.0)]
    pub master_counts_per_unit: f64,
    /// Table id (activate).
    #[arg(long)]
    pub id: Option<u32>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Check: an SVG plot of each slave's position, velocity and acceleration against the
    /// master (at the master's top speed) with the board's limits.
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
}

/// The tables of a status report as JSON: `{"active", "committed", "saved"}` (null: none).
pub fn tables_json(r: &status::Report) -> serde_json::Value {
    serde_json::json!({
        "active": r.active_id,
        "committed": r.committed_id,
        "saved": r.saved_id,
    })
}

/// Runs `table`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.what == What::Check {
        return check(args);
    }
    let port = args
        .port
        .as_deref()
        .ok_or_else(|| anyhow::anyhow!("table {:?} needs --port PORT", args.what))?;
    let mut link = Link::open(port)?;
    match args.what {
        What::Check => unreachable!("handled above"),
        What::List => {
            let r = match link.request(&Request::GetStatus)? {
                Response::Status(s) => status::report_with(
                    &s,
                    &hydra_core::protocol::diag::FaultsMsg::default(),
                    link.info.period_us,
                    0.0,
                ),
                r => anyhow::bail!("GetStatus answered {r:?}"),
            };
            if args.json {
                println!("{}", tables_json(&r));
            } else {
                let show = |t: Option<u32>| t.map_or_else(|| "none".to_string(), |v| v.to_string());
                println!("active     {}", show(r.active_id));
                println!("committed  {}", show(r.committed_id));
                println!("saved      {}", show(r.saved_id));
            }
        }
        What::Activate => {
            let id = args
                .id
                .ok_or_else(|| anyhow::anyhow!("table activate needs --id N (see `table list`)"))?;
            let f = link.expect_ack(&Request::Activate { id })?;
            let deferred = f & ACK_DEFERRED != 0;
            if args.json {
                println!("{}", serde_json::json!({"id": id, "deferred": deferred}));
            } else if deferred {
                println!("activation of table {id} armed: it takes effect at the next safe point");
            } else {
                println!("table {id} active");
            }
        }
    }
    Ok(())
}

/// `table check`.
fn check(args: &Args) -> anyhow::Result<()> {
    use crate::tablecheck::{check, BoardRules};
    let file = args
        .file
        .as_deref()
        .ok_or_else(|| anyhow::anyhow!("table check needs the table: table check FILE.csv"))?;
    let csv = crate::camfile::CamCsv::load(file)?;
    let (rules, of) = match &args.port {
        Some(p) => (
            BoardRules::of_info(&Link::open(p)?.info),
            "the connected board",
        ),
        None => (BoardRules::firmware(), "the firmware's profile"),
    };
    let r = check(&csv, &rules, args.master_counts_per_unit);
    if let Some(p) = &args.plot {
        crate::tablecheck::plot(&csv, &rules, args.master_counts_per_unit, p)?;
        eprintln!("plot → {}", p.display());
    }
    if args.json {
        let e = r.as_ref().err();
        println!(
            "{}",
            serde_json::json!({
                "file": file.display().to_string(),
                "rules": of,
                "rows": csv.master.len(),
                "ok": e.is_none(),
                "line": e.and_then(|e| e.line),
                "error": e.map(|e| e.reason.clone()),
            })
        );
    } else if r.is_ok() {
        println!(
            "{}: {} rows pass every rule of {of} ({} slaves, ≤ {} rows, segments ≤ {} counts, master ≤ {} counts/s)",
            file.display(),
            csv.master.len(),
            rules.axes,
            rules.capacity_rows,
            rules.max_segment_counts,
            rules.master_speed_per_s()
        );
    }
    r.map_err(Into::into)
}
