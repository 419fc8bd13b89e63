//! Loads and drifts during a run (`[axis.load]`, `[axis.drift]`, `[supply.drift]`): what a
//! scenario says happens to the plant, the controller not told.

use host_sim::robust::Variant;
use host_sim::scenario::{Controller, Scenario};
use host_sim::sim::{run, AxisResult, RunReport, RunSpec};
use std::path::Path;

fn scenario(extra_axis: &str, extra_top: &str) -> Scenario {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios");
    let table = dir.join("tangent_table.csv");
    let text = format!(
        "name = \"varying\"\n{extra_top}\n[table]\nfile = \"{}\"\n[[axis]]\nname = \"tangent\"\nrole = \"follower\"\n{extra_axis}\n",
        table.display()
    );
    let s = Scenario::parse(&text, &dir.join("varying.toml")).unwrap();
    s.validate().unwrap();
    s
}

fn go(s: &Scenario) -> RunReport {
    let table = s.load_table(None).unwrap();
    let spec = RunSpec {
        controller: Controller::Feedforward,
        period_us: 1000,
        trace_every_s: None,
    };
    run(s, &table, &spec, &mut |_| {}).unwrap()
}

fn max_um(r: &RunReport) -> f64 {
    match r.axes[0].result {
        AxisResult::Follower { max_error_um, .. } => max_error_um,
        _ => f64::NAN,
    }
}

#[test]
fn a_load_step_during_the_run_shows_and_is_rejected() {
    let nominal = go(&scenario("", ""));
    let stepped = go(&scenario(
        "[axis.load]\npoints = [[10, 0], [10, 5000], [20, 5000], [20, 0]]",
        "",
    ));
    // 5 kN on a 300 kg axis: the error shows the step, the loop holds it (no fault).
    assert!(stepped.faults.is_empty(), "{:?}", stepped.faults);
    assert!(
        max_um(&stepped) > 1.5 * max_um(&nominal),
        "{} vs {}",
        max_um(&stepped),
        max_um(&nominal)
    );
    assert!(max_um(&stepped) < 500.0, "{}", max_um(&stepped));
}

#[test]
fn a_drift_reached_at_once_is_the_robustness_box_machine() {
    // The valve at −20 % from the first period on (a drift of zero duration) runs as the
    // robustness box's `flow×0.8` machine within a few %.
    let base = scenario("", "");
    // The drifted run's max error within 5 % of the box machine's.
    let same = |drifted: &Scenario, machine: Variant, what: &str| {
        let (a, b) = (max_um(&go(drifted)), max_um(&go(&machine.apply(&base))));
        assert!((a / b - 1.0).abs() < 0.05, "{what} {a} vs box {b}");
    };
    let nominal = Variant::nominal(&base);
    same(
        &scenario("[axis.drift]\nvalve_flow = 0.8\nstart_s = 0\nend_s = 0", ""),
        Variant {
            flow: 0.8,
            ..nominal
        },
        "drift",
    );
    // A supply stepped to 120 bar at once is the box's 120 bar machine too (the chambers'
    // clamp follows the supply); nonsense is refused.
    same(
        &scenario("", "[supply.drift]\nto_bar = 120\nstart_s = 0\nend_s = 0"),
        Variant {
            supply_bar: 120.0,
            ..nominal
        },
        "supply drift",
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios");
    let bad = "name = \"x\"\n[[axis]]\nname = \"tangent\"\nrole = \"follower\"\n[axis.drift]\nvalve_flow = -1\n";
    let e = Scenario::parse(bad, &dir.join("bad.toml"))
        .and_then(|s| s.validate())
        .unwrap_err()
        .to_string();
    assert!(e.contains("axis.tangent.drift.valve_flow"), "{e}");
}
