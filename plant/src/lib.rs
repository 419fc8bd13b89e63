//! # hydra-plant — the simulated hydraulic machine, as a board
//!
//! Everything the simulator, the virtual board and the emulated board share about the
//! machine, with no command-line dependency:
//!
//! - [`hydraulics`]: the plant — valve, cylinder and oil, the axis' RK4 integration, the
//!   master's motion profile, encoders, edge timer and pressure transducers;
//! - [`scenario`]: the scenario file (schema, defaults, validation, gains, loads and
//!   drifts, `[events]`), and the plant it describes;
//! - [`machine`]: the plant and sensors assembled for a scenario;
//! - [`board`]: core's board traits (`EncoderInput`, `PressureInput`, `SafetyInput`,
//!   `ValveOutput`, `TickHost`) over one period's sampled machine, so the firmware's own
//!   `TickLoop::run` closes the simulated loop;
//! - [`camfile`], [`die`]: cam tables as CSV and the elliptical die's table;
//! - [`csvout`]: CSV writers; [`stats`]: the tracking-error statistics.

pub mod board;
pub mod camfile;
pub mod csvout;
pub mod die;
pub mod hydraulics;
pub mod machine;
pub mod scenario;
pub mod stats;
