//! The scenario's `[events]` drive the board's inputs through the firmware's tick
//! (`TickLoop::run` → `Runtime::tick_io`): an E-stop, a lost encoder and lost pressure
//! inputs fault the run by name, every valve is at null within one tick, and `host-sim
//! run` ends with exit code 3.

use host_sim::cmd::run::{run as run_cmd, Args, FaultLatched};
use host_sim::scenario::events::{EncoderLoss, EncoderLossMode};
use host_sim::scenario::{Controller, Scenario};
use host_sim::sim::{run, FaultEvent, RunReport, RunSpec};
use std::path::{Path, PathBuf};

fn scenarios() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios")
}

const PERIOD_S: f64 = 1e-3;

/// `file` (a shipped scenario) cut to 3 s, with `events` applied.
fn run_with(file: &str, events: impl FnOnce(&mut Scenario)) -> RunReport {
    let mut s = Scenario::load(&scenarios().join(file)).unwrap();
    s.sim.duration_s = Some(3.0);
    events(&mut s);
    s.validate().unwrap();
    let t = s.load_table(None).unwrap();
    let spec = RunSpec {
        controller: Controller::Feedforward,
        period_us: 1000,
        trace_every_s: Some(1e-4),
    };
    run(&s, &t, &spec, &mut |_| {}).unwrap()
}

/// The fault latched first, which must be `name`, at or after `at_s`.
fn first_fault<'a>(r: &'a RunReport, name: &str, at_s: f64) -> &'a FaultEvent {
    let f = r
        .faults
        .first()
        .unwrap_or_else(|| panic!("no fault: expected {name}"));
    assert_eq!(f.name, name, "{:?}", r.faults);
    assert!(f.t_s >= at_s - 1e-9, "{f:?} before the event at {at_s} s");
    f
}

/// Every `<axis>_u` column in `axes` is exactly 0 from one period after `t_s` on, and
/// was not before the fault.
fn valves_null_within_one_tick(r: &RunReport, axes: &[&str], t_s: f64) {
    let tr = r.trace.as_ref().expect("trace");
    let n = tr.columns.len();
    for a in axes {
        let ui = tr
            .columns
            .iter()
            .position(|c| *c == format!("{a}_u"))
            .unwrap_or_else(|| panic!("no column {a}_u"));
        let rows = || tr.data.chunks_exact(n);
        let after: Vec<f64> = rows()
            .filter(|row| row[0] > t_s + PERIOD_S + 1e-9)
            .map(|row| row[ui])
            .collect();
        assert!(
            after.len() > 1000,
            "{a}: {} rows after the fault",
            after.len()
        );
        assert!(
            after.iter().all(|&u| u == 0.0),
            "{a}: valve not at null one tick after {t_s} s"
        );
        assert!(
            rows().any(|row| row[0] < t_s && row[ui] != 0.0),
            "{a}: the valve never moved before the fault"
        );
    }
}

#[test]
fn an_estop_faults_the_run_and_nulls_every_valve_within_one_tick() {
    // The reference machine: the tangent follower and the side press.
    let r = run_with("tangent.toml", |s| s.events.estop_at_s = Some(2.0));
    let f = first_fault(&r, "estop", 2.0);
    assert!(
        f.t_s < 2.0 + PERIOD_S + 1e-9,
        "latched at the first tick that saw it: {f:?}"
    );
    assert_eq!((f.code, f.axis.as_deref()), (0x0100, None), "{f:?}");
    // The report measures it too: every valve at null at most one period after the fault.
    let null_s = r.valves_null_s.expect("valves went to null");
    assert!(
        null_s >= f.t_s && null_s <= f.t_s + PERIOD_S + 1e-9,
        "{null_s} s, fault at {}",
        f.t_s
    );
    valves_null_within_one_tick(&r, &["tangent", "side_press"], f.t_s);
}

/// `file` with `axis`' encoder reset at 2 s: `encoder_jump` on that axis within one
/// period, and every valve of `valves` at null one tick later.
fn a_reset_encoder_faults(file: &str, axis: &str, valves: &[&str]) {
    let r = run_with(file, |s| {
        s.events.encoder_lost = Some(EncoderLoss {
            axis: axis.into(),
            at_s: 2.0,
            mode: EncoderLossMode::Reset,
        })
    });
    let f = first_fault(&r, "encoder_jump", 2.0);
    assert!(f.t_s < 2.0 + PERIOD_S + 1e-9, "{f:?}");
    assert_eq!(f.axis.as_deref(), Some(axis), "{f:?}");
    valves_null_within_one_tick(&r, valves, f.t_s);
}

#[test]
fn a_reset_encoder_latches_encoder_jump_on_its_axis() {
    a_reset_encoder_faults("tangent_alone.toml", "tangent", &["tangent"]);
}

#[test]
fn a_reset_encoder_on_the_side_press_faults_it_through_the_runtime() {
    // The press runs inside the runtime: its encoder is extended and checked like a
    // follower's, and its fault nulls every valve.
    a_reset_encoder_faults("tangent.toml", "side_press", &["tangent", "side_press"]);
}

#[test]
fn a_frozen_encoder_on_a_moving_axis_trips_the_following_error() {
    let r = run_with("tangent_alone.toml", |s| {
        s.events.encoder_lost = Some(EncoderLoss {
            axis: "tangent".into(),
            at_s: 2.0,
            mode: EncoderLossMode::Freeze,
        })
    });
    let f = first_fault(&r, "following_error", 2.0);
    // The frozen count holds still while the table's target runs on (≈ 33 mm/s here):
    // the shipped 20 mm limit is reached in ≈ 0.6 s, with the valve driving all along.
    assert!(f.t_s < 3.0, "{f:?}");
    assert!(f.value.is_some_and(|v| v > 20_000.0), "{f:?}");
    assert_eq!(f.axis.as_deref(), Some("tangent"), "{f:?}");
    valves_null_within_one_tick(&r, &["tangent"], f.t_s);
}

#[test]
fn lost_pressures_fault_a_machine_with_a_force_axis_only() {
    let r = run_with("tangent.toml", |s| s.events.pressure_lost_at_s = Some(2.0));
    let f = first_fault(&r, "pressure_input", 2.0);
    assert!(f.t_s < 2.0 + PERIOD_S + 1e-9, "{f:?}");
    valves_null_within_one_tick(&r, &["tangent", "side_press"], f.t_s);
    // Without a force axis the law holds the last live pressures and the run goes on.
    let r = run_with("tangent_alone.toml", |s| {
        s.events.pressure_lost_at_s = Some(2.0)
    });
    assert!(r.faults.is_empty(), "{:?}", r.faults);
}

#[test]
fn host_sim_run_with_an_estop_event_exits_3() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("estop.toml");
    let text = std::fs::read_to_string(scenarios().join("tangent_alone.toml")).unwrap();
    let table = scenarios().join("tangent_table.csv");
    let text = text.replace(
        "file = \"tangent_table.csv\"",
        &format!("file = {:?}", table.display().to_string()),
    );
    std::fs::write(
        &p,
        format!("{text}\n[sim]\nduration_s = 2.5\n[events]\nestop_at_s = 2.0\n"),
    )
    .unwrap();
    let args = |allow_fault| Args {
        scenario: p.clone(),
        controller: Some(Controller::Feedforward),
        period_us: Some(1000),
        table: None,
        csv: None,
        plot: None,
        json: true,
        allow_fault,
        tune: false,
        margins: host_sim::autotune::Margins::Nominal,
    };
    let e = run_cmd(&args(false)).expect_err("an E-stop is a latched fault");
    let f = e
        .downcast_ref::<FaultLatched>()
        .expect("FaultLatched (exit 3)");
    assert!(e.to_string().contains("estop"), "{e}: {f:?}");
    assert_eq!(host_sim::cmd::run::FAULT_EXIT_CODE, 3);
    run_cmd(&args(true)).expect("--allow-fault: exit 0");
}

#[test]
fn an_event_naming_no_axis_is_refused_with_its_key() {
    let mut s = Scenario::load(&scenarios().join("tangent.toml")).unwrap();
    s.events.encoder_lost = Some(EncoderLoss {
        axis: "side_pres".into(),
        at_s: 1.0,
        mode: EncoderLossMode::Freeze,
    });
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("events.encoder_lost.axis"), "{e}");
    assert!(e.contains("side_press"), "the axes are listed: {e}");
}

#[test]
fn the_shipped_estop_scenario_faults_at_its_event() {
    // host-sim/scenarios/tangent_estop.toml, as the README runs it (whole, 12 s E-stop).
    let s = Scenario::load(&scenarios().join("tangent_estop.toml")).unwrap();
    assert_eq!(s.events.estop_at_s, Some(12.0));
    let t = s.load_table(None).unwrap();
    let spec = RunSpec {
        controller: Controller::Feedforward,
        period_us: 1000,
        trace_every_s: Some(1e-3),
    };
    let r = run(&s, &t, &spec, &mut |_| {}).unwrap();
    let f = first_fault(&r, "estop", 12.0);
    assert!(f.t_s < 12.0 + PERIOD_S + 1e-9, "{f:?}");
    let null = r.valves_null_s.expect("valves at null after the fault");
    assert!(null - f.t_s <= PERIOD_S + 1e-9, "{null} s vs {f:?}");
}
