//! `board-emu`: the firmware's release ELF on the emulated board, in the loop with
//! host-sim's plant (see the crate docs and docs/board-emu.md).

use anyhow::{Context, Result};
use board_emu::elf::Image;
use board_emu::flash::Flash;
use board_emu::session::Session;
use clap::Parser;
use hydra_plant::scenario::Scenario;
use std::io::Write;
use std::path::PathBuf;
use std::rc::Rc;

/// Runs the firmware's release ELF on an emulated STM32F407 wired to the plant.
#[derive(Parser, Debug)]
#[command(name = "board-emu", version)]
struct Args {
    /// The firmware ELF (default: the release build).
    #[arg(long, default_value = "target/thumbv7em-none-eabihf/release/firmware")]
    elf: PathBuf,
    /// The machine (default: host-sim's reference machine, tangent_alone.toml).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Upload, commit and activate this table over the emulated UART, reference the
    /// slaves and Start (as a host would).
    #[arg(long)]
    table: Option<PathBuf>,
    /// Emulated seconds to run (default: 0.1 s, or the scenario's duration with --table).
    #[arg(long)]
    seconds: Option<f64>,
    /// The firmware's USART6 on a pseudo-terminal (its path is the first line printed);
    /// runs in real time until killed.
    #[arg(long)]
    pty: bool,
    /// One JSON object with the run's figures.
    #[arg(long)]
    json: bool,
    /// A trace every millisecond: t_s, master_deg, then per slave target_mm, x_mm, u,
    /// enable.
    #[arg(long)]
    csv: Option<PathBuf>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let image = Rc::new(Image::load(&args.elf)?);
    let scn_path = args.scenario.clone().unwrap_or_else(|| {
        PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../host-sim/scenarios/tangent_alone.toml"
        ))
    });
    let scn =
        Scenario::load(&scn_path).with_context(|| format!("scenario {}", scn_path.display()))?;
    let table = scn.load_table(args.table.as_deref())?;
    let mut s = Session::new(image, Flash::new(), &scn, table)?;
    s.plant.borrow_mut().record = args.csv.is_some();
    if args.pty {
        return pty(&mut s);
    }
    s.m.run_for(0.05)?;
    let seconds = if args.table.is_some() {
        s.upload_activate(1)?;
        s.reference_and_start()?;
        args.seconds.unwrap_or(scn.duration_s()?)
    } else {
        args.seconds.unwrap_or(0.1)
    };
    s.m.run_for(seconds)?;
    let report = s.report()?;
    if let Some(p) = &args.csv {
        let mut f = std::io::BufWriter::new(std::fs::File::create(p)?);
        let mut head = vec!["t_s".to_string(), "master_deg".to_string()];
        for n in &s.names {
            for c in ["target_mm", "x_mm", "u", "enable"] {
                head.push(format!("{n}_{c}"));
            }
        }
        writeln!(f, "{}", head.join(","))?;
        for row in &s.plant.borrow().trace {
            let r: Vec<String> = row.iter().map(|v| format!("{v:.6}")).collect();
            writeln!(f, "{}", r.join(","))?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

/// The board on a pseudo-terminal, paced to the wall clock.
fn pty(s: &mut Session) -> Result<()> {
    use std::io::Read;
    let (mut master, slave) = serialport::TTYPort::pair().context("pseudo-terminal")?;
    let path = serialport::SerialPort::name(&slave).context("the pseudo-terminal has no name")?;
    println!("{path}");
    std::io::stdout().flush()?;
    serialport::SerialPort::set_timeout(&mut master, std::time::Duration::from_millis(1))?;
    let _slave = slave;
    let t0 = std::time::Instant::now();
    let mut buf = [0u8; 1024];
    let mut pending: Vec<u8> = Vec::new();
    loop {
        match master.read(&mut buf) {
            Ok(n) => {
                let now = s.m.cycles();
                s.m.state_mut().bus.usart6.host_send(&buf[..n], now);
            }
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e.into()),
        }
        let target = t0.elapsed().as_secs_f64();
        if s.m.seconds() < target {
            s.m.run_for((target - s.m.seconds()).min(0.01))?;
        }
        pending.extend(std::mem::take(&mut s.m.state_mut().bus.usart6.to_host));
        while !pending.is_empty() {
            match master.write(&pending) {
                Ok(0) => break,
                Ok(k) => {
                    pending.drain(..k);
                }
                Err(_) => break,
            }
        }
        pending.truncate(256 * 1024);
    }
}
