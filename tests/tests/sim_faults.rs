//! `host-sim run` through the runtime: its fault rules are live in a simulation, a
//! latched fault is reported (JSON `faults`, exit code 3) and the valves go to null, and
//! oscillation is counted against the table's own reversals.

use host_sim::autotune::to_toml;
use host_sim::cmd::run::{run as run_cmd, to_json, Args, FaultLatched};
use host_sim::scenario::{reference_tuning, Controller, Scenario};
use host_sim::sim::{run, RunSpec};
use std::path::{Path, PathBuf};

fn scenarios() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios")
}

fn spec(period_us: u32) -> RunSpec {
    RunSpec {
        controller: Controller::Feedforward,
        period_us,
        trace_every_s: Some(1e-3),
    }
}

/// The shipped 1 ms feed-forward set (`tangent.toml`, as host-sim compiles it in) with
/// the gain backoff and the feed-forward trim off, as `[[tuning]]` TOML: the fault path
/// needs a machine the loop cannot hold (with the backoff it holds this one,
/// `sim_backoff.rs`).
fn shipped_without_backoff() -> String {
    let mut t = reference_tuning()
        .into_iter()
        .find(|t| t.controller == Controller::Feedforward && t.period_us == 1000)
        .expect("the shipped 1 ms feed-forward set");
    for g in t.axes.values_mut() {
        g.osc_band_um = 0.0;
        g.ff_trim_tau_s = 0.0;
    }
    // This machine has the tangent axis alone.
    t.press.clear();
    to_toml(&t)
}

/// The reference machine with its oil's bulk modulus × 0.4 (aerated oil): the shipped
/// gains without the backoff make it oscillate.
fn soft_oil() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("soft.toml");
    let table = scenarios().join("tangent_table.csv");
    std::fs::write(
        &p,
        format!(
            "name = \"soft_oil\"\n[table]\nfile = \"{}\"\n[[axis]]\nname = \"tangent\"\nrole = \"follower\"\n[axis.cylinder]\nbulk_modulus_pa = 0.56e9\n{}",
            table.display(),
            shipped_without_backoff()
        ),
    )
    .unwrap();
    (dir, p)
}

fn args(scenario: PathBuf, allow_fault: bool) -> Args {
    Args {
        scenario,
        controller: None,
        period_us: None,
        table: None,
        csv: None,
        plot: None,
        json: true,
        allow_fault,
        tune: false,
        margins: host_sim::autotune::Margins::Nominal,
    }
}

#[test]
fn the_nominal_run_latches_nothing_and_reverses_only_where_the_table_does() {
    let s = Scenario::load(&scenarios().join("tangent_alone.toml")).unwrap();
    let t = s.load_table(None).unwrap();
    let r = run(&s, &t, &spec(1000), &mut |_| {}).unwrap();
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let o = &r.oscillation[0];
    assert_eq!((o.reversals, o.table_reversals, o.excess()), (1, 1, 0));
    let j = to_json(&r);
    assert_eq!(j["faults"], serde_json::json!([]));
    assert_eq!(j["oscillation"]["tangent"]["excess"], 0);
    run_cmd(&args(scenarios().join("tangent_alone.toml"), false)).expect("exit code 0");
}

#[test]
fn aerated_oil_oscillates_faults_and_the_valve_goes_to_null() {
    let (_dir, p) = soft_oil();
    let s = Scenario::load(&p).unwrap();
    let t = s.load_table(None).unwrap();
    let r = run(&s, &t, &spec(1000), &mut |_| {}).unwrap();
    let f = r.faults.first().expect("a fault latched");
    assert!(
        f.code >> 8 == 5 || f.code >> 8 == 6,
        "encoder jump or following error: {f:?}"
    );
    assert_eq!(f.axis.as_deref(), Some("tangent"));
    assert!(f.t_s > 0.0 && f.t_s < 5.0, "{f:?}");
    assert!(r.oscillation[0].excess() > 10, "{:?}", r.oscillation);
    // From the fault on, the valve command applied is zero (valves unpowered).
    let tr = r.trace.as_ref().unwrap();
    let cols = tr.columns.len();
    let (ti, ui) = (0, tr.columns.iter().position(|c| c == "tangent_u").unwrap());
    let after: Vec<f64> = tr
        .data
        .chunks(cols)
        .filter(|row| row[ti] > f.t_s + 0.01)
        .map(|row| row[ui])
        .collect();
    assert!(after.len() > 1000 && after.iter().all(|&u| u == 0.0));
    let j = to_json(&r);
    let jf = &j["faults"][0];
    for k in ["code", "name", "axis", "tick", "t_s", "value"] {
        assert!(jf.get(k).is_some(), "faults[0] lacks {k}: {jf}");
    }
    // The command: an error that host-sim turns into exit code 3; --allow-fault: Ok.
    let e = run_cmd(&args(p.clone(), false)).expect_err("a latched fault is an error");
    assert!(e.downcast_ref::<FaultLatched>().is_some(), "{e:?}");
    run_cmd(&args(p, true)).expect("--allow-fault");
}

#[test]
fn a_following_error_fault_reports_the_error_that_tripped_it() {
    let mut s = Scenario::load(&scenarios().join("tangent_alone.toml")).unwrap();
    for t in &mut s.tuning {
        for g in t.axes.values_mut() {
            g.following_error_um = 5.0;
        }
    }
    let t = s.load_table(None).unwrap();
    let r = run(&s, &t, &spec(1000), &mut |_| {}).unwrap();
    let f = r.faults.first().expect("a 5 µm limit trips");
    assert_eq!((f.code, f.name), (0x0600, "following_error"), "{f:?}");
    let v = f.value.expect("the error that tripped it");
    assert!(v > 5.0 && v < 100.0, "{v} µm");
}

#[test]
fn a_period_far_too_long_does_not_run_with_no_word() {
    let s = Scenario::load(&scenarios().join("tangent_alone.toml")).unwrap();
    let t = s.load_table(None).unwrap();
    let r = run(&s, &t, &spec(200_000), &mut |_| {}).unwrap();
    assert!(!r.faults.is_empty(), "200 ms: a fault latches");
}
