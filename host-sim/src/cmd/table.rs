//! `host-sim table list|activate --port PORT [--id N] [--json]`: the board's tables — the
//! active one, the committed one waiting for Activate, the saved one — and activating a
//! committed table (`upload` commits without activating unless `--activate`).

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
}

/// Arguments of `table`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// What to do.
    #[arg(value_enum)]
    pub what: What,
    /// Table id (activate).
    #[arg(long)]
    pub id: Option<u32>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
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
    let mut link = Link::open(&args.port)?;
    match args.what {
        What::List => {
            let r = match link.request(&Request::GetStatus)? {
                Response::Status(s) => status::report(&s),
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
