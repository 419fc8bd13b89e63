//! # host-sim — the hydra controller's `core` against a hydraulic plant model
//!
//! The library half of the `host-sim` tool, so the end-to-end tests in `tests/` drive the
//! same plant, scenarios and controllers as the command line.

// The machine, its scenarios and cam files are the plant crate's; host-sim's modules
// and the tests name them here as before.
pub use hydra_plant::hydraulics as plant;
pub use hydra_plant::{camfile, csvout, die, machine, scenario};

pub mod autotune;
pub mod cmd;
pub mod contour_truth;
pub mod fair;
pub mod identify;
pub mod margins;
pub mod modbus_tcp;
pub mod plot;
pub mod robust;
pub mod sim;
pub mod tablecheck;
pub mod vboard;
pub mod xy;
