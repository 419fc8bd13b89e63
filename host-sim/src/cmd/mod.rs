//! One module per sub-command of the `host-sim` tool.

pub mod capture;
pub mod contour_estimate;
pub mod fair;
pub mod identify;
pub mod manual;
pub mod margins;
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
pub mod test_move;
pub mod trace;
pub mod tune;
pub mod upload;
pub mod xy;

/// A scenario shipped in `host-sim/scenarios/`: from the working directory (the project
/// root or `host-sim/`) if it is there, else from the source tree.
pub(crate) fn shipped_scenario(file: &str) -> std::path::PathBuf {
    use std::path::PathBuf;
    [
        PathBuf::from("host-sim/scenarios").join(file),
        PathBuf::from("scenarios").join(file),
    ]
    .into_iter()
    .find(|p| p.is_file())
    .unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(file)
    })
}
