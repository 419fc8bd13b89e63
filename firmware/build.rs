//! Linker setup for the firmware only (never touches host builds).
fn main() {
    // firmware/memory.x (the STM32F407's map), found by cortex-m-rt's link.x through the
    // search path. Only the firmware's search path has it: bench-m4 brings its own.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("cargo:rustc-link-search={}", dir.display());
    println!("cargo:rerun-if-changed={}", dir.join("memory.x").display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
