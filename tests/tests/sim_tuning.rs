//! The shipped gain sets are the output of the documented tuning procedure.

use host_sim::autotune::{master_filter_hz, position_gains, press_gains};
use host_sim::scenario::{Controller, Scenario};
use std::path::Path;

/// The position gains of `tangent.toml` are exactly what the procedure computes today
/// (`host-sim run host-sim/scenarios/tangent.toml --period-us N --tune`), and the three
/// controllers share the feedback gains (one procedure, one loop).
#[test]
fn shipped_position_gains_are_the_procedure_output() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/tangent.toml");
    let s = Scenario::load(&path).unwrap();
    let axis = &s.axes[0];
    for period in [1000, 10_000, 72_000] {
        let set = |c: Controller| {
            s.tuning
                .iter()
                .find(|t| t.controller == c && t.period_us == period)
                .unwrap_or_else(|| panic!("no {c:?} set at {period} µs"))
        };
        let ff = set(Controller::Feedforward);
        let (want, ku) = position_gains(&s, axis, Controller::Feedforward, period).unwrap();
        assert_eq!(
            ff.axes["tangent"], want,
            "feedforward @ {period} µs (K_u = {ku})"
        );
        assert_eq!(ff.master_filter_hz, master_filter_hz(period));
        for c in [Controller::Paper, Controller::Traditional] {
            let g = &set(c).axes["tangent"];
            assert_eq!(
                (g.kp_lsb_per_um, g.ki_lsb_per_um_s, g.kd_lsb_s_per_um),
                (
                    want.kp_lsb_per_um,
                    want.ki_lsb_per_um_s,
                    want.kd_lsb_s_per_um
                ),
                "{c:?} @ {period} µs"
            );
            assert_eq!(g.kv_pos_lsb_per_um_s, 0.0);
        }
    }
}

/// The side press's force gains of `tangent.toml` are the procedure's output at every
/// tuned period (the same for every controller: the press law is one).
#[test]
fn shipped_press_gains_are_the_procedure_output() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/tangent.toml");
    let s = Scenario::load(&path).unwrap();
    let press = s.axes.iter().find(|a| a.name == "side_press").unwrap();
    for period in [1000, 10_000, 72_000] {
        let (want, ku) = press_gains(&s, press, period).unwrap();
        let sets: Vec<_> = s.tuning.iter().filter(|t| t.period_us == period).collect();
        assert_eq!(sets.len(), 3, "a set per controller at {period} µs");
        for t in sets {
            assert_eq!(
                t.press["side_press"], want,
                "{:?} @ {period} µs (K_u = {ku})",
                t.controller
            );
        }
    }
}
