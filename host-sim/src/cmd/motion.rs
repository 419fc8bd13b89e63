//! `host-sim motion --port PORT start|stop|hold|clear-fault|set-position|home`: one motion
//! command. A board with incremental slaves refuses Start until every slave is
//! referenced: `set-position --axis N --mm X` (the slave is at X mm now) or `home --axis N`
//! (referenced at its next index / reference-switch edge).
//!
//! `host-sim motion --port PORT jog --axis N --speed-mm-s V [--seconds S]`, `motion move
//! --axis N --to-mm X`, `motion start --approach`: moving slaves by hand (`manual`).
//! `motion test --axis N --profile step|chirp|prbs --csv REC.csv`: the identification
//! test move, recorded by the capture (`test_move`).
//!
//! `host-sim motion --port PORT master start|stop|rewind|status [--speed-scale K]`: the
//! virtual board's simulated master (`serve`), so a run can be repeated without
//! restarting it; prints where the master is and whether it reached its end (a real
//! board's master is an encoder: refused in words).

use super::serial::Link;
use hydra_core::protocol::{Request, Response};

/// The command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum What {
    /// Idle → Following.
    Start,
    /// → Idle.
    Stop,
    /// Following → Holding.
    Hold,
    /// Clear a latched fault.
    ClearFault,
    /// Idle or Fault: slave `--axis` is at `--mm` now.
    SetPosition,
    /// Idle or Fault: arm homing of slave `--axis` (its next reference edge).
    Home,
    /// The virtual board's master: start, stop, rewind or status.
    Master,
    /// Jog slave `--axis` at `--speed-mm-s` (renewed every 100 ms; stops when the host
    /// stops sending).
    Jog,
    /// Move slave `--axis` to `--to-mm` by the S-curve; returns when it is there.
    Move,
    /// The identification test move on slave `--axis` (`--profile`), recorded to `--csv`.
    Test,
}

/// What to do with a virtual board's master.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MasterOp {
    /// Run from where it is.
    Start,
    /// Stand still where it is.
    Stop,
    /// Back to the start of its profile, standing still.
    Rewind,
    /// Only say where it is.
    Status,
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
    /// Slave axis (0-based) of set-position and home.
    #[arg(long)]
    pub axis: Option<u8>,
    /// Set-position: where the slave is, mm (|x| ≤ 8 000 mm).
    #[arg(long, allow_negative_numbers = true)]
    pub mm: Option<f64>,
    /// Master: the operation.
    #[arg(value_enum)]
    pub master_op: Option<MasterOp>,
    /// Master: its speed relative to the scenario's profile (0.01 … 100).
    #[arg(long)]
    pub speed_scale: Option<f64>,
    /// Manual motion limits and options (jog, move, start --approach).
    #[command(flatten)]
    pub manual: super::manual::ManualArgs,
    /// The test move's options.
    #[command(flatten)]
    pub test: super::test_move::TestArgs,
}

/// The request of `args`, or why it cannot be sent.
pub fn request(args: &Args) -> anyhow::Result<Request<'static>> {
    let axis = || {
        args.axis
            .ok_or_else(|| anyhow::anyhow!("{:?} needs --axis N (the slave, 0-based)", args.what))
    };
    super::manual::check_args(args.what, &args.manual)?;
    anyhow::ensure!(
        args.what == What::Test || !args.test.any(),
        "{:?} does not take the test's options (--profile --amplitude-mm --dwell-ms --f0-hz \
         --f1-hz --csv --plot)",
        args.what
    );
    anyhow::ensure!(
        args.what == What::Master || (args.master_op.is_none() && args.speed_scale.is_none()),
        "{:?} takes no master operation or --speed-scale (those are `motion master …`)",
        args.what
    );
    anyhow::ensure!(
        !(args.master_op == Some(MasterOp::Status) && args.speed_scale.is_some()),
        "motion master status only reads: set --speed-scale with start"
    );
    Ok(match args.what {
        What::Start if args.manual.approach => Request::Approach {
            limits: args.manual.limits()?,
        },
        What::Jog => super::manual::jog_request(axis()?, &args.manual, args.manual.speed()?)?,
        What::Move => super::manual::move_request(axis()?, &args.manual)?,
        What::Test => Request::TestMove {
            axis: axis()?,
            test: hydra_core::protocol::msg::TestMoveMsg::of(&args.test.spec(args.manual.seconds)?),
        },
        What::Start => Request::Start,
        What::Stop => Request::Stop,
        What::Hold => Request::Hold,
        What::ClearFault => Request::ClearFault,
        What::Home => Request::Home { axis: axis()? },
        What::Master => {
            use hydra_core::protocol::diag::master_op as m;
            let op = match args.master_op {
                None => anyhow::bail!("motion master needs start, stop, rewind or status"),
                Some(MasterOp::Start) => m::START,
                Some(MasterOp::Stop) => m::STOP,
                Some(MasterOp::Rewind) => m::REWIND,
                Some(MasterOp::Status) => m::QUERY,
            };
            let speed_scale = match args.speed_scale {
                None => 0.0,
                Some(k) if (0.01..=100.0).contains(&k) => k as f32,
                Some(k) => anyhow::bail!("--speed-scale {k}: must be 0.01 … 100"),
            };
            Request::VirtualMaster { op, speed_scale }
        }
        What::SetPosition => {
            let axis = axis()?;
            let mm = args.mm.ok_or_else(|| {
                anyhow::anyhow!("set-position needs --mm X (where the slave is now)")
            })?;
            anyhow::ensure!(
                mm.is_finite() && mm.abs() <= 8000.0,
                "--mm {mm}: a position must be within ±8000 mm"
            );
            // I24F8 µm on the wire.
            Request::SetPosition {
                axis,
                pos_um: (mm * 1000.0 * 256.0).round() as i32,
            }
        }
    })
}

/// Sends the command; a refusal is an error naming the board's reason.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let q = request(args)?;
    let mut link = Link::open(&args.port)?;
    match q {
        Request::Jog { axis, .. } => return super::manual::jog(&mut link, axis, &args.manual),
        Request::MoveTo { axis, to_um, .. } => {
            link.expect_ack(&q)?;
            return super::manual::wait_in_position(&mut link, axis, to_um, &args.manual);
        }
        Request::Approach { .. } => {
            link.expect_ack(&q)?;
            return super::manual::wait_following(&mut link, &args.manual);
        }
        Request::TestMove { axis, .. } => {
            return super::test_move::run(&mut link, axis, &args.test, args.manual.seconds);
        }
        _ => {}
    }
    if let Request::VirtualMaster { .. } = q {
        return match link.request(&q)? {
            Response::MasterState(m) => {
                println!(
                    "master {}, {:.3} s of {:.3} s, at {:.3}, speed ×{}{}",
                    if m.running { "running" } else { "stopped" },
                    m.time_s,
                    m.end_s,
                    m.position,
                    m.speed_scale,
                    if m.at_end {
                        "; at the end of its profile (it stands there: rewind to repeat)"
                    } else {
                        ""
                    }
                );
                Ok(())
            }
            Response::Nak { nak, .. } => Err(super::serial::Refused {
                req: "VirtualMaster".into(),
                nak,
            }
            .into()),
            r => anyhow::bail!("VirtualMaster answered {r:?}"),
        };
    }
    link.expect_ack(&q)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(what: What, axis: Option<u8>, mm: Option<f64>) -> Args {
        Args {
            port: String::new(),
            what,
            axis,
            mm,
            master_op: None,
            speed_scale: None,
            manual: Default::default(),
            test: Default::default(),
        }
    }

    #[test]
    fn set_position_and_home_need_their_axis_and_position() {
        assert!(matches!(
            request(&a(What::SetPosition, Some(1), Some(-20.5))).unwrap(),
            Request::SetPosition { axis: 1, pos_um } if pos_um == -20_500 * 256
        ));
        assert!(matches!(
            request(&a(What::Home, Some(0), None)).unwrap(),
            Request::Home { axis: 0 }
        ));
        assert!(request(&a(What::SetPosition, None, Some(1.0))).is_err());
        assert!(request(&a(What::SetPosition, Some(0), None)).is_err());
        assert!(request(&a(What::SetPosition, Some(0), Some(f64::NAN))).is_err());
        assert!(request(&a(What::SetPosition, Some(0), Some(9000.0))).is_err());
        assert!(request(&a(What::Home, None, None)).is_err());
    }
}
