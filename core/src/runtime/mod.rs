//! The runtime: states, fault rules and board I/O around the control law.
//!
//! Everything the controller board does between the drivers and the maths lives here,
//! host-tested, so the firmware is only drivers and scheduling and the host simulator's
//! virtual board runs exactly the same code:
//!
//! - [`machine`]: the state machine Idle / Following / Holding / Fault, commands and
//!   the per-tick order of operations;
//! - [`fault`]: fault causes and their 16-bit codes (table there);
//! - [`config`]: limits in engineering units → per-tick integers;
//! - [`controller`]: the trait the control law implements; [`follower_law`]: the SPEC §A
//!   follower behind it; [`press_law`]: force axes beside it;
//! - [`io`]: the traits a board implements (encoders, pressures, E-stop, valves);
//! - [`encoder`]: 16 → 32-bit counter extension and the plausibility check;
//! - [`tick`]: the board's per-period entry point ([`TickLoop::run`]) both boards call;
//! - [`stall`]: master-stall detection; [`timing`]: tick execution-time statistics;
//! - [`pressure`]: transducer scaling;
//! - [`reference`]: where each slave is (set-position, homing, absolute encoders);
//! - [`manual`]: moving slaves by hand (jog with a deadman, S-curve moves, the approach);
//!   [`test_move`]: the identification test move.

pub mod capture;
pub mod config;
pub mod controller;
pub mod encoder;
pub mod fault;
pub mod follower_law;
pub mod io;
pub mod machine;
pub mod manual;
pub mod press_law;
pub mod pressure;
pub mod reference;
pub mod stall;
pub mod test_move;
pub mod tick;
pub mod timing;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_manual;
#[cfg(test)]
mod tests_reference;

pub use capture::{Capture, CaptureError, CaptureInfo, CaptureRow, Channel, Phase, Trigger};
pub use config::{
    MasterSource, RuntimeCoeffs, RuntimeConfig, RuntimeConfigError, MAX_STEP_LIMIT_COUNTS,
    PERIOD_MAX_US, PERIOD_MIN_US,
};
pub use controller::{ControlInputs, ControlOutputs, Controller, LawFault, Learned};
pub use fault::{
    Fault, FaultEvent, FaultHistory, FaultKind, FaultRecord, FaultSet, FAULT_HISTORY_LEN,
};
pub use io::{Board, EncoderInput, EncoderSample, PressureInput, SafetyInput, ValveOutput};
pub use machine::{
    BootCause, Command, CommandError, HoldReason, Runtime, Sample, State, Status, TickOutputs,
};
pub use manual::{ManualKind, MotionError, MotionLimits, JOG_DEADMAN_US};
pub use press_law::{NoSuchSlave, PressAxes};
pub use reference::{RefState, ReferenceMode, References};
pub use test_move::{TestError, TestMove, TestProfile, TestSpec};
pub use tick::{
    Reply, TickCommand, TickHost, TickLoop, TickSample, FLAG_COMMAND, FLAG_END_OF_TABLE,
    FLAG_ESTOP, FLAG_VALVE_POWER, STATE_MASK, STATUS_PERIOD_US,
};
