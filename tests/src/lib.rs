//! End-to-end tests live in `tests/tests/*.rs`; this library holds their shared helpers.

/// Path of the workspace root (for scenario and table files).
pub fn workspace_root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default()
}
