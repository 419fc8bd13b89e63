//! # host-sim — the hydra controller's `core` against a hydraulic plant model
//!
//! The library half of the `host-sim` tool, so the end-to-end tests in `tests/` drive the
//! same plant, scenarios and controllers as the command line.

pub mod autotune;
pub mod camfile;
pub mod cmd;
pub mod contour_truth;
pub mod csvout;
pub mod die;
pub mod fair;
pub mod identify;
pub mod machine;
pub mod margins;
pub mod plant;
pub mod plot;
pub mod robust;
pub mod scenario;
pub mod sim;
pub mod tablecheck;
pub mod vboard;
pub mod xy;
