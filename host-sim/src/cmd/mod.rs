//! One module per sub-command of the `host-sim` tool.

pub mod capture;
pub mod contour_estimate;
pub mod fair;
pub mod identify;
pub mod manual;
pub mod motion;
pub mod open_loop;
pub mod param;
pub mod robust;
pub mod run;
pub mod scurve;
pub mod serial;
pub mod serve;
pub mod status;
pub mod table;
pub mod trace;
pub mod upload;
pub mod xy;
