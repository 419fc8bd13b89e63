//! Helpers of the command-line tests: `host-sim serve --pty` as a process and
//! `host-sim` commands against its port, each a process as a user runs it.
#![allow(dead_code)] // each test file uses its own part

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};

/// A `serve` process, killed when dropped (a restart is a drop and a new one).
pub struct Serve(pub Child, pub String);

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub fn serve(flash: &Path) -> Serve {
    serve_args(&[std::ffi::OsStr::new("--flash"), flash.as_os_str()])
}

/// A virtual board of the scenario `scenario` (its machine, the board's profile).
pub fn serve_scenario(scenario: &Path) -> Serve {
    serve_args(&[std::ffi::OsStr::new("--scenario"), scenario.as_os_str()])
}

fn serve_args(extra: &[&std::ffi::OsStr]) -> Serve {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["serve", "--pty"])
        .args(extra)
        .stdout(Stdio::piped())
        .spawn()
        .expect("serve starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("the PTY path");
    let port = line.trim().to_string();
    assert!(port.starts_with("/dev/"), "{port:?}");
    Serve(child, port)
}

pub fn cli(s: &Serve, args: &[&str]) -> Output {
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["--port", &s.1]);
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(&a)
        .output()
        .expect("host-sim runs")
}

/// Runs a command that must succeed; its stdout.
pub fn ok(s: &Serve, args: &[&str]) -> String {
    let o = cli(s, args);
    assert!(
        o.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).expect("utf-8")
}

/// Runs a command that must fail; its stderr.
pub fn refused(s: &Serve, args: &[&str]) -> String {
    let o = cli(s, args);
    assert!(!o.status.success(), "{args:?} must be refused");
    String::from_utf8(o.stderr).expect("utf-8")
}

pub fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text.trim()).expect("JSON")
}

/// Slave `axis`' position from `status --json`, mm.
pub fn pos(s: &Serve, axis: usize) -> f64 {
    json(&ok(s, &["status", "--json"]))["axes"][axis]["pos_mm"]
        .as_f64()
        .expect("pos_mm")
}

/// References both slaves where they are (`motion set-position` at their position).
pub fn reference_where_they_are(s: &Serve) {
    for k in 0..2 {
        let p = pos(s, k).to_string();
        let axis = k.to_string();
        ok(s, &["motion", "set-position", "--axis", &axis, "--mm", &p]);
    }
}
