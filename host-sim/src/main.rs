//! `host-sim`: simulate, plot, upload tables, watch a board.
use clap::{Parser, Subcommand};
use host_sim::cmd;

/// The hydra hydraulic motion controller's simulator and board tool.
///
/// Without a command it runs the main job: the reference stretch-bending machine under
/// the three control laws at 72 ms and 1 ms, a table of max / RMS tracking errors,
/// and SVG plots in `out/`.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run one scenario file with one controller.
    Run(cmd::run::Args),
    /// The robustness box: the shipped gains on the machine off nominal (mass, oil,
    /// valve, supply), max / RMS error and oscillation per case.
    Robust(cmd::robust::Args),
    /// The fair comparison: every controller tuned by the same procedure at each period.
    Fair(cmd::fair::Args),
    /// Fit an axis' valve, oil, mass and friction to the board's capture of a test move
    /// (`motion test`) or an open-loop recording; write the machine file.
    Identify(cmd::identify::Args),
    /// A follower loop's gain and phase margins, measured on the simulated machine by a
    /// sinusoidal probe at its valve.
    Margins(cmd::margins::Args),
    /// Gains for a machine file (`identify --out`) by the tuning procedure, checked on it.
    Tune(cmd::tune::Args),
    /// Drive the plant with a recorded valve command.
    OpenLoop(cmd::open_loop::Args),
    /// Plan a jerk-limited 7-phase move (N-axis straight line) and sample it.
    Scurve(cmd::scurve::Args),
    /// Compare contour-error estimators against the exact distance.
    ContourEstimate(cmd::contour_estimate::Args),
    /// Two-axis X-Y table with independent or cross-coupled control.
    Xy(cmd::xy::Args),
    /// Run the virtual board (runtime + protocol + simulated tangent axis) on a PTY.
    Serve(cmd::serve::Args),
    /// Upload a cam table (CSV) to a board over its serial port.
    Upload(cmd::upload::Args),
    /// Show a board's status.
    Status(cmd::status::Args),
    /// Record a board's telemetry to CSV (and an SVG plot).
    Trace(cmd::trace::Args),
    /// Record every tick around a trigger (fault, state change, command, threshold) to
    /// CSV and an SVG plot.
    Capture(cmd::capture::Args),
    /// Send Start / Stop / Hold / ClearFault / set-position / home to a board; move, jog
    /// and run test moves by hand.
    Motion(cmd::motion::Args),
    /// List a board's tables or activate a committed one.
    Table(cmd::table::Args),
    /// List, read, set and save a board's settings by path (`axis/0/kp_lsb_per_um`).
    Param(cmd::param::Args),
    /// The board's Modbus register map for a PLC (Markdown, or `--json`).
    ModbusMap(cmd::modbus_map::Args),
}

fn main() -> std::process::ExitCode {
    match dispatch() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => match e.downcast_ref::<cmd::run::FaultLatched>() {
            Some(f) => {
                eprintln!("{f}");
                std::process::ExitCode::from(cmd::run::FAULT_EXIT_CODE)
            }
            None => {
                // The cause chain on one line each, without a backtrace (RUST_BACKTRACE
                // is for the tool's developers, not for a machine builder).
                eprintln!("error: {e:#}");
                std::process::ExitCode::FAILURE
            }
        },
    }
}

fn dispatch() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        None => cmd::run::run_default(),
        Some(Command::Run(a)) => cmd::run::run(&a),
        Some(Command::Robust(a)) => cmd::robust::run(&a),
        Some(Command::Fair(a)) => cmd::fair::run(&a),
        Some(Command::Identify(a)) => cmd::identify::run(&a),
        Some(Command::Margins(a)) => cmd::margins::run(&a),
        Some(Command::Tune(a)) => cmd::tune::run(&a),
        Some(Command::OpenLoop(a)) => cmd::open_loop::run(&a),
        Some(Command::Scurve(a)) => cmd::scurve::run(&a),
        Some(Command::ContourEstimate(a)) => cmd::contour_estimate::run(&a),
        Some(Command::Xy(a)) => cmd::xy::run(&a),
        Some(Command::Serve(a)) => cmd::serve::run(&a),
        Some(Command::Upload(a)) => cmd::upload::run(&a),
        Some(Command::Status(a)) => cmd::status::run(&a),
        Some(Command::Trace(a)) => cmd::trace::run(&a),
        Some(Command::Capture(a)) => cmd::capture::run(&a),
        Some(Command::Motion(a)) => cmd::motion::run(&a),
        Some(Command::Table(a)) => cmd::table::run(&a),
        Some(Command::Param(a)) => cmd::param::run(&a),
        Some(Command::ModbusMap(a)) => cmd::modbus_map::run(&a),
    }
}
