//! `host-sim open-loop` on a machine off nominal, then `host-sim identify` on its
//! recording: the fit recovers the machine within 4 % and writes a machine file that
//! `host-sim run` reads; a recording that is not one is refused naming what is wrong.

use std::path::Path;
use std::process::{Command, Output};

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("host-sim runs")
}

fn ok(args: &[&str]) -> String {
    let o = host_sim(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).expect("utf-8")
}

/// Pulses of alternating sign and growing amplitude, each followed by a rest.
fn write_command(p: &Path) {
    let mut s = String::from("t,u\n0,0\n");
    let mut t = 0.05;
    for k in 0..24 {
        let amp = 0.05 + 0.35 * f64::from(k % 8) / 7.0;
        let (u, len) = if k % 2 == 0 {
            (amp, 0.12)
        } else {
            (-amp, 0.085)
        };
        s.push_str(&format!("{t:.4},{u:.5}\n"));
        t += len;
        s.push_str(&format!("{t:.4},0\n"));
        t += 0.08;
    }
    s.push_str(&format!("{:.4},0\n", t + 0.2));
    std::fs::write(p, s).expect("command");
}

#[test]
fn identify_recovers_an_off_nominal_machine_from_its_open_loop_recording() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = |n: &str| dir.path().join(n).display().to_string();
    write_command(Path::new(&path("cmd.csv")));
    std::fs::write(
        path("variant.toml"),
        "name = \"variant\"\n[[axis]]\nname = \"tangent\"\nrole = \"follower\"\n\
         [axis.valve]\nbandwidth_hz = 48\nrated_flow_l_per_min = 20.4\n\
         [axis.cylinder]\nmass_kg = 480\nbulk_modulus_pa = 0.98e9\n\
         viscous_n_s_per_m = 6000\ncoulomb_n = 600\n",
    )
    .expect("variant");
    ok(&[
        "open-loop",
        "--command-csv",
        &path("cmd.csv"),
        "--scenario",
        &path("variant.toml"),
        "--csv",
        &path("rec.csv"),
    ]);
    let out = ok(&[
        "identify",
        "--trace",
        &path("rec.csv"),
        "--command-csv",
        &path("cmd.csv"),
        "--out",
        &path("machine.toml"),
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_str(out.trim()).expect("JSON");
    let fit = |name: &str| -> (f64, f64) {
        let p = j["fit"]["params"]
            .as_array()
            .expect("params")
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("no {name}"));
        (
            p["value"].as_f64().expect("value"),
            p["std"].as_f64().expect("std"),
        )
    };
    for (name, truth) in [
        ("mass_kg", 480.0),
        ("bulk_modulus_pa", 0.98e9),
        ("rated_flow_extend_l_per_min", 20.4),
        ("rated_flow_retract_l_per_min", 20.4),
        ("viscous_n_s_per_m", 6000.0),
        ("coulomb_n", 600.0),
        ("valve_bandwidth_hz", 48.0),
        ("valve_damping", 0.8),
    ] {
        let (v, sd) = fit(name);
        assert!(
            (v / truth - 1.0).abs() < 0.04,
            "{name}: {v} ± {sd}, true {truth}"
        );
        assert!(sd.is_finite() && sd >= 0.0);
    }
    // The machine file holds the fitted values (what it says is what was fitted)…
    let machine = std::fs::read_to_string(path("machine.toml")).expect("machine");
    let line = machine
        .lines()
        .find(|l| l.starts_with("mass_kg = "))
        .expect("mass line");
    let written: f64 = line["mass_kg = ".len()..]
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .expect("a number");
    assert!((written / fit("mass_kg").0 - 1.0).abs() < 1e-5, "{line}");
    // …and is a scenario: `run` follows the reference table on it.
    let run = ok(&["run", &path("machine.toml"), "--json"]);
    let r: serde_json::Value = serde_json::from_str(run.trim()).expect("JSON");
    assert_eq!(r["faults"].as_array().map(Vec::len), Some(0), "{run}");

    // Not a recording: refused, naming the column or the line.
    std::fs::write(path("bad.csv"), "t,x_mm\n0,1\n").expect("bad");
    let o = host_sim(&[
        "identify",
        "--trace",
        &path("bad.csv"),
        "--command-csv",
        &path("cmd.csv"),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("no `v_mm_s` column"), "{e}");
    std::fs::write(
        path("back.csv"),
        "t,u,x_mm,v_mm_s,pA_bar,pB_bar,spool\n0,0,250,0,80,80,0\n0,0,250,0,80,80,0\n",
    )
    .expect("back");
    let o = host_sim(&["identify", "--trace", &path("back.csv")]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("back.csv:3: time 0 s does not increase"),
        "{e}"
    );
}
