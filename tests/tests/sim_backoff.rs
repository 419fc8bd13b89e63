//! The gain backoff (core's `axis::backoff`) on the simulated machine: with the shipped
//! 1 ms gains and active damping (`tangent_damped.toml`) every machine of the robustness
//! box runs without oscillation within the robustness targets, and with the shipped gains
//! alone (`tangent_alone.toml`, the gain backoff and the feed-forward trim, no damping)
//! so does every machine; the aerated-oil machine that shakes into its fault with the
//! backoff off (`sim_faults.rs`) is held.

use host_sim::robust::{cases as box_variants, evaluate, Case, Variant};
use host_sim::scenario::{Controller, Scenario};
use std::path::Path;

fn scenario(file: &str) -> Scenario {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios");
    Scenario::load(&dir.join(file)).unwrap()
}

fn cases(s: &Scenario, machines: &[Variant]) -> Vec<Case> {
    let table = s.load_table(None).unwrap();
    evaluate(s, &table, Controller::Feedforward, 1000, machines, &|_| {}).unwrap()
}

fn show(c: &[Case]) -> String {
    c.iter()
        .map(|c| {
            format!(
                "{}: {:.1} / {:.2} µm osc {} level {}",
                c.label, c.max_um, c.rms_um, c.oscillating, c.backoff_level
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The robustness targets on the whole box (measured: worst 17.9 µm, nominal 3.9 /
/// 0.46 µm; the four mass ×2 / bulk ×0.5 corners end at level 1 … 3).
#[test]
fn damped_shipped_gains_with_the_backoff_hold_every_machine_of_the_box() {
    let s = scenario("tangent_damped.toml");
    let c = cases(&s, &box_variants(&s));
    let all = show(&c);
    assert_eq!(c.len(), 25);
    let nominal = &c[0];
    assert!(
        nominal.max_um <= 5.0 && nominal.rms_um <= 1.0,
        "nominal ≤ 5 µm max, ≤ 1 µm RMS:\n{all}"
    );
    assert_eq!(
        nominal.backoff_level, 0,
        "the nominal machine keeps its gain"
    );
    for k in &c {
        assert!(!k.oscillating && k.max_um <= 30.0, "{}:\n{all}", k.label);
        if k.variant.mass == 2.0 && k.variant.bulk == 0.5 {
            assert!(k.backoff_level >= 1, "{}:\n{all}", k.label);
        }
    }
    // The machines that do not need it are not touched: at most two others — the
    // stiff-oil mass ×2 corner whose 43 Hz ringing also backs off, and aerated oil alone
    // (bulk ×0.5), whose start-up error of ≈ 5 µm rides at the 4 µm band (level 0 or 1
    // by a hair: 15.2 µm at level 1 with the feed-forward trim; measured) — never the
    // nominal.
    let touched = c
        .iter()
        .filter(|k| k.backoff_level > 0 && !(k.variant.mass == 2.0 && k.variant.bulk == 0.5))
        .count();
    assert!(touched <= 2, "{all}");
}

/// The robustness targets with the shipped gains alone, no damping (the gain
/// backoff with its growth watch and the feed-forward trim): every machine of the box
/// runs without oscillation within 30 µm, the nominal within 5 µm max and 1 µm RMS at
/// its set gain (measured: worst 25.6 µm, the mass ×2 / bulk ×0.5 / flow ×1.2 / 180 bar
/// corner at level 4, its start-up ringing; nominal 4.1 / 0.45 µm).
#[test]
fn the_shipped_gains_with_the_backoff_and_the_trim_hold_every_machine_of_the_box() {
    let s = scenario("tangent_alone.toml");
    let c = cases(&s, &box_variants(&s));
    let all = show(&c);
    assert!(
        c[0].backoff_level == 0 && c[0].max_um <= 5.0 && c[0].rms_um <= 1.0,
        "{all}"
    );
    for k in &c {
        assert!(!k.oscillating && k.max_um <= 30.0, "{}:\n{all}", k.label);
    }
}

/// The shipped gains alone on aerated oil (bulk modulus ×0.4): held without a fault or
/// a shake, at a lower gain; the nominal machine keeps the set gain.
#[test]
fn the_shipped_gains_hold_aerated_oil_by_backing_off() {
    let s = scenario("tangent_alone.toml");
    let n = Variant::nominal(&s);
    let c = cases(&s, &[n, Variant { bulk: 0.4, ..n }]);
    let all = show(&c);
    assert_eq!(c[0].backoff_level, 0, "{all}");
    assert!(c[1].faults.is_empty() && !c[1].oscillating, "{all}");
    assert!(c[1].backoff_level >= 1, "{all}");
    assert!(c[1].max_um < 100.0, "{all}");
}
