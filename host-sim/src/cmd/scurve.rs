//! `host-sim` sub-command (in progress: filled by its issue).

/// Arguments of the sub-command.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the sub-command.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("this sub-command is not built yet")
}
