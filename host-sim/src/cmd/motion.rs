//! `host-sim motion --port PORT start|stop|hold|clear-fault`: one motion command.

use super::serial::Link;
use hydra_core::protocol::Request;

/// The command.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum What {
    /// Idle → Following.
    Start,
    /// → Idle.
    Stop,
    /// Following → Holding.
    Hold,
    /// Clear a latched fault.
    ClearFault,
}

/// Arguments of `motion`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// What to do.
    #[arg(value_enum)]
    pub what: What,
}

/// Sends the command; a refusal is an error naming the board's reason.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let mut link = Link::open(&args.port)?;
    link.expect_ack(&match args.what {
        What::Start => Request::Start,
        What::Stop => Request::Stop,
        What::Hold => Request::Hold,
        What::ClearFault => Request::ClearFault,
    })?;
    Ok(())
}
