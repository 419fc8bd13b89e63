//! One module per sub-command of the `host-sim` tool.

pub mod contour_estimate;
pub mod open_loop;
pub mod run;
pub mod scurve;
pub mod serial;
pub mod xy;
