//! The fit on host-sim's own plant: a machine off nominal in every parameter the fit
//! claims, recovered within 4 %.

use super::*;
use crate::cmd::open_loop::simulate;
use crate::scenario::Scenario;

/// An excitation that stays in mid-stroke: pulses of alternating sign and growing
/// amplitude (0.05 … 0.4 of the valve), each followed by a rest, so the axis moves both
/// ways at several speeds and accelerates and brakes often.
pub(crate) fn excitation() -> Vec<(f64, f64)> {
    let mut cmd = vec![(0.0, 0.0)];
    let mut t = 0.05;
    for k in 0..24 {
        let amp = 0.05 + 0.35 * f64::from(k % 8) / 7.0;
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        // Retracting is faster (smaller area): shorter pulses keep the axis centred.
        let len = if sign > 0.0 { 0.12 } else { 0.085 };
        cmd.push((t, sign * amp));
        t += len;
        cmd.push((t, 0.0));
        t += 0.08;
    }
    cmd.push((t + 0.2, 0.0));
    cmd
}

fn record(axis: &mut HydraulicAxis, step_s: f64) -> Vec<Sample> {
    let cmd = excitation();
    let out = simulate(axis, &cmd, step_s, 1e-3);
    let u_at = |t: f64| {
        cmd.iter()
            .take_while(|(tc, _)| *tc <= t + 1e-9)
            .last()
            .map_or(0.0, |c| c.1)
    };
    out.iter()
        .map(|s| Sample {
            t: s.t,
            u: u_at(s.t),
            x_m: s.x_mm * 1e-3,
            v_m_s: s.v_mm_s * 1e-3,
            pa_pa: s.pa_bar * 1e5,
            pb_pa: s.pb_bar * 1e5,
            spool: s.spool,
        })
        .collect()
}

/// The reference machine off nominal in every parameter the fits claim (mass ×1.6, bulk
/// modulus ×0.7, valve flow ×0.85, viscous ×2, Coulomb ×1.5, valve bandwidth ×0.8).
pub(crate) fn off_nominal() -> Scenario {
    let mut truth = Scenario::default();
    let a = &mut truth.axes[0];
    a.cylinder.mass_kg *= 1.6;
    a.cylinder.bulk_modulus_pa *= 0.7;
    a.valve.rated_flow_l_per_min *= 0.85;
    a.cylinder.viscous_n_s_per_m *= 2.0;
    a.cylinder.coulomb_n *= 1.5;
    a.valve.bandwidth_hz *= 0.8;
    truth
}

#[test]
fn an_off_nominal_machine_is_recovered_within_four_percent() {
    let nominal = Scenario::default();
    let truth = off_nominal();
    let t = &truth.axes[0];
    let mut plant = t.plant(truth.supply(), 0.25);
    let rec = record(&mut plant, truth.step_s());
    let span = rec
        .iter()
        .map(|s| s.x_m)
        .fold((f64::MAX, f64::MIN), |m, x| (m.0.min(x), m.1.max(x)));
    assert!(
        span.0 > 0.05 && span.1 < 0.45,
        "stays in mid-stroke: {span:?}"
    );

    // The fit only knows the nominal machine's geometry and supply.
    let known = nominal.axes[0].plant(nominal.supply(), 0.25);
    let id = identify(&known, &rec).unwrap();
    let want = [
        ("mass_kg", t.cylinder.mass_kg),
        ("bulk_modulus_pa", t.cylinder.bulk_modulus_pa),
        ("rated_flow_extend_l_per_min", t.valve.rated_flow_l_per_min),
        ("rated_flow_retract_l_per_min", t.valve.rated_flow_l_per_min),
        ("viscous_n_s_per_m", t.cylinder.viscous_n_s_per_m),
        ("coulomb_n", t.cylinder.coulomb_n),
        ("valve_bandwidth_hz", t.valve.bandwidth_hz),
        ("valve_damping", t.valve.damping),
    ];
    for (name, truth) in want {
        let p = id.get(name).unwrap();
        let err = (p.value / truth - 1.0).abs();
        assert!(
            err < 0.04,
            "{name}: fitted {} ± {}, true {truth} ({:.1} %)",
            p.value,
            p.std,
            100.0 * err
        );
        assert!(p.std.is_finite() && p.std >= 0.0, "{name}: σ {}", p.std);
    }
    assert!(
        id.get("overlap").unwrap().value <= 0.005,
        "no overlap in the model"
    );
    assert!(id.get("load_n").unwrap().value.abs() < 200.0);
}

#[test]
fn a_recording_that_does_not_move_is_refused_with_a_reason() {
    let s = Scenario::default();
    let known = s.axes[0].plant(s.supply(), 0.25);
    let still: Vec<Sample> = (0..2000)
        .map(|k| Sample {
            t: f64::from(k) * 1e-3,
            u: 0.0,
            x_m: 0.25,
            v_m_s: 0.0,
            pa_pa: 80e5,
            pb_pa: 80e5,
            spool: 0.0,
        })
        .collect();
    assert!(matches!(
        identify(&known, &still),
        Err(IdentifyError::NotExcited { .. })
    ));
    assert!(matches!(
        identify(&known, &still[..5]),
        Err(IdentifyError::TooFewSamples { .. })
    ));
}
