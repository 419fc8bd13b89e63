use super::*;
use nalgebra::Complex;

/// An integrator with a pure delay, L = K·e^(−jωτ)/(jω): f_c = K/2π, PM = 90° − ω_c·τ,
/// f_180 = 1/(4τ), GM = 20·log10(ω_180/ω_c) — recovered from the grid's samples.
#[test]
fn margins_of_an_integrator_with_a_delay() {
    let (k, tau) = (std::f64::consts::TAU * 10.0, 5e-3);
    let l = |f: f64| {
        let w = std::f64::consts::TAU * f;
        Complex::from_polar(k / w, -std::f64::consts::FRAC_PI_2 - w * tau)
    };
    let resp: Vec<_> = grid(1000).into_iter().map(|f| (f, l(f))).collect();
    let m = margins_of("x", &resp);
    let fc = m.gain_crossover_hz.unwrap();
    assert!((fc - 10.0).abs() < 0.01, "{fc}");
    let pm = m.phase_margin_deg.unwrap();
    let want_pm = 90.0 - (std::f64::consts::TAU * 10.0 * tau).to_degrees();
    assert!((pm - want_pm).abs() < 0.5, "{pm} vs {want_pm}");
    let f180 = m.phase_crossover_hz.unwrap();
    assert!((f180 - 50.0).abs() < 1.0, "{f180}");
    let gm = m.gain_margin_db.unwrap();
    assert!((gm - 20.0 * 5.0f64.log10()).abs() < 0.2, "{gm}");
    // min |1 + L| against a 1 000-point sweep of the same loop (0.755, a little below
    // 1 − 1/GM = 0.8: the curve passes −1 closest just off the real axis).
    let fine = (0..1000)
        .map(|i| (l(2.0 + 0.148 * f64::from(i)) + 1.0).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(
        (m.modulus_margin - fine).abs() < 0.01,
        "{} vs {fine}",
        m.modulus_margin
    );
}

/// A loop that never crosses 0 dB has neither crossover.
#[test]
fn no_crossover_no_margin() {
    let resp: Vec<_> = grid(1000)
        .into_iter()
        .map(|f| (f, Complex::new(0.1, 0.0)))
        .collect();
    let m = margins_of("x", &resp);
    assert_eq!(
        (m.gain_crossover_hz, m.phase_margin_deg, m.gain_margin_db),
        (None, None, None)
    );
}

/// The shipped 1 ms feed-forward set on the reference machine: the probe's gain margin
/// agrees with the tuning procedure's, K_u / Kp = 2.22 / 1.1 (6.1 dB, a P step test),
/// within 2 dB; the phase margin is measured (docs/results.md, "Robustness").
#[test]
fn the_shipped_set_measured_against_the_ultimate_gain() {
    let s = Scenario::default();
    let table = s.load_table(None).unwrap();
    let m = measure(&s, &table, Controller::Feedforward, 1000, None).unwrap();
    let gm = m.gain_margin_db.unwrap();
    assert!((gm - 6.1).abs() < 2.0, "GM {gm} dB: {m:#?}");
    let pm = m.phase_margin_deg.unwrap();
    assert!(pm > 20.0, "PM {pm}°: {m:#?}");
    assert!(m.gain_crossover_hz.unwrap() < m.phase_crossover_hz.unwrap());
}

/// The shipped gains shake the softest machine (mass ×2, bulk ×0.5: a fault) and aerated
/// oil (bulk ×0.5 alone: no fault, but hundreds of velocity reversals): both refused,
/// named; so are an unknown axis and a travel too short for the sweep.
#[test]
fn an_oscillating_loop_is_refused() {
    let s = Scenario::default();
    let table = s.load_table(None).unwrap();
    for (mass, bulk, why) in [(2.0, 0.5, "without the probe"), (1.0, 0.5, "reversals")] {
        let soft = crate::robust::Variant {
            mass,
            bulk,
            ..crate::robust::Variant::nominal(&s)
        }
        .apply(&s);
        let e = measure(&soft, &table, Controller::Feedforward, 1000, None).unwrap_err();
        assert!(matches!(e, MarginError::Unstable { .. }), "{e}");
        assert!(
            e.to_string().contains("tangent") && e.to_string().contains(why),
            "{e}"
        );
    }
    let e = measure(&s, &table, Controller::Feedforward, 1000, Some("nope")).unwrap_err();
    assert!(matches!(e, MarginError::NoAxis(_)), "{e}");
    let mut short = s.clone();
    short.master.end_deg = short.master.start_deg + 9.0;
    let e = measure(&short, &table, Controller::Feedforward, 1000, None).unwrap_err();
    assert!(matches!(e, MarginError::TooShort { .. }), "{e}");
}

/// Non-finite points are dropped, not propagated into the margins.
#[test]
fn non_finite_points_are_dropped() {
    let mut resp: Vec<_> = grid(1000)
        .into_iter()
        .map(|f| (f, Complex::from_polar(10.0 / f, -2.0 - f / 50.0)))
        .collect();
    let clean = margins_of("x", &resp);
    resp.insert(5, (7.0, Complex::new(f64::NAN, 0.0)));
    let m = margins_of("x", &resp);
    assert_eq!(m.phase_margin_deg, clean.phase_margin_deg);
    assert_eq!(m.points.len(), clean.points.len());
}
