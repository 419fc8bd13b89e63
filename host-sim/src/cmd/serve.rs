//! `host-sim serve --pty`: the virtual board ([`crate::vboard`]) on a pseudo-terminal.
//!
//! Prints the PTY path on the first line of stdout, then runs until killed: the
//! simulated machine advances in real time (one control period per period of wall
//! clock, counted by the board's own ticks; if the host falls behind it catches up by at
//! most 100 periods at once and the rest is dropped from the timeline).

use crate::scenario::Scenario;
use crate::vboard::VBoard;
use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serve on a new pseudo-terminal (the only transport of the virtual board).
    #[arg(long)]
    pub pty: bool,
    /// Scenario file (default: the reference tangent machine).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Keep the board's flash (its two table slots) in this file: created erased if
    /// missing, written after every request that changed it, so restarting `serve` with
    /// the same file is a power cycle (without it the flash lives in memory only).
    #[arg(long)]
    pub flash: Option<PathBuf>,
    /// Also serve Modbus TCP on this address (e.g. 127.0.0.1:1502; port 0 picks a free
    /// one): prints `modbus-tcp: ADDR` on the second line. Answers only while the
    /// board's `plc/enable` is 1 (docs/plc.md).
    #[arg(long)]
    pub modbus_tcp: Option<String>,
}

/// Output bytes the virtual board keeps for a host that is not reading (≈ 2.8 s of
/// 921 600 Bd); beyond it new output is dropped.
pub const PENDING_MAX: usize = 256 * 1024;

/// Runs the virtual board.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if !args.pty {
        anyhow::bail!("serve needs --pty (the virtual board runs on a pseudo-terminal)");
    }
    let scn = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let mut tcp = match &args.modbus_tcp {
        Some(a) => Some(crate::modbus_tcp::TcpServer::bind(a)?),
        None => None,
    };
    let tcp_addr = tcp.as_ref().map(|t| t.local_addr()).transpose()?;
    serve_loop(
        &scn,
        args.flash.as_deref(),
        |path| {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{path}");
            if let Some(a) = tcp_addr {
                let _ = writeln!(out, "modbus-tcp: {a}");
            }
            let _ = out.flush();
        },
        |board| {
            if let Some(t) = tcp.as_mut() {
                t.poll(board);
            }
        },
    )
}

/// Runs the virtual board of `scn` on a new PTY until an I/O error; `on_path` gets the
/// PTY's path once it exists.
pub fn serve(scn: &Scenario, on_path: impl FnOnce(&str)) -> anyhow::Result<()> {
    serve_with(scn, None, on_path)
}

/// [`serve`] with the board's flash in `flash_file` (see [`Args::flash`]).
pub fn serve_with(
    scn: &Scenario,
    flash_file: Option<&std::path::Path>,
    on_path: impl FnOnce(&str),
) -> anyhow::Result<()> {
    serve_loop(scn, flash_file, on_path, |_| {})
}

/// [`serve_with`], calling `other` (another transport: Modbus TCP) once per loop.
fn serve_loop(
    scn: &Scenario,
    flash_file: Option<&std::path::Path>,
    on_path: impl FnOnce(&str),
    mut other: impl FnMut(&mut VBoard),
) -> anyhow::Result<()> {
    let mut board = match flash_file {
        Some(f) => VBoard::with_flash_file(scn, f)?,
        None => VBoard::new(scn)?,
    };
    let mut seen_ops = board.flash.ops;
    let (mut master, slave) = serialport::TTYPort::pair()
        .map_err(|e| anyhow::anyhow!("cannot create a pseudo-terminal: {e}"))?;
    let path = serialport::SerialPort::name(&slave)
        .ok_or_else(|| anyhow::anyhow!("the pseudo-terminal has no name"))?;
    on_path(&path);
    serialport::SerialPort::set_timeout(&mut master, Duration::from_millis(1))?;
    let period = Duration::from_secs_f64(board.machine.period_s());
    let t0 = Instant::now();
    // Periods the host fell behind by more than 100 at once: dropped from the timeline.
    let mut lost: u64 = 0;
    let mut buf = [0u8; 1024];
    let mut pending: Vec<u8> = Vec::new();
    let mut dropped: u64 = 0;
    // Keep the slave end open so the master never sees a hang-up between clients.
    let _slave = slave;
    loop {
        let mut tx: Vec<u8> = Vec::new();
        match master.read(&mut buf) {
            Ok(n) => {
                board.on_bytes(&buf[..n], &mut |f| tx.extend_from_slice(f));
                if let Some(f) = flash_file {
                    board.persist(f, &mut seen_ops)?;
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
        other(&mut board);
        if let Some(f) = flash_file {
            board.persist(f, &mut seen_ops)?;
        }
        // Paced on the board's own tick count, which includes the tick that answered a
        // command: the command's tick is the next period of the timeline, not an extra.
        let due = (t0.elapsed().as_nanos() / period.as_nanos().max(1)) as u64;
        let behind = due.saturating_sub(lost).saturating_sub(board.ticks());
        if behind > 100 {
            lost += behind - 100;
        }
        for _ in 0..behind.min(100) {
            board.tick(&mut |f| tx.extend_from_slice(f));
        }
        // A host that does not read must never stop the board: what the PTY will not take
        // now waits in `pending` (written as far as the PTY accepts each loop, partial
        // writes kept); beyond PENDING_MAX new output is dropped whole, as the board drops
        // frames its TX batch cannot hold (the host times out and retries).
        if pending.len() + tx.len() <= PENDING_MAX {
            pending.extend_from_slice(&tx);
        } else {
            if dropped == 0 {
                eprintln!("serve: the host is not reading; dropping output beyond {PENDING_MAX} B");
            }
            dropped = dropped.saturating_add(tx.len() as u64);
        }
        while !pending.is_empty() {
            match master.write(&pending) {
                Ok(0) => break,
                Ok(k) => {
                    pending.drain(..k);
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    break
                }
                Err(e) => return Err(e.into()),
            }
        }
    }
}
