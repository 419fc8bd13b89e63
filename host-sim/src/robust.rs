//! The robustness box: the machine as it may really be, against the machine the gains
//! were tuned on.
//!
//! Real machines are never the model. The box spans what commissioning engineers meet:
//!
//! | factor | range | why |
//! |---|---|---|
//! | moving mass (every follower axis) | ×0.5 … ×2 | tooling, workpiece, a heavier carriage |
//! | oil bulk modulus | ×0.5 … ×1.5 | aerated oil, hoses (soft) … steel pipes (stiff) |
//! | valve rated flow | ×0.8 … ×1.2 | valve tolerance, wear, another valve of the series |
//! | supply pressure | 120 … 180 bar | the power unit's setting, accumulator droop |
//!
//! Only the plant changes; the controller keeps the scenario's calibration and gains (it
//! does not know). The cases: the nominal machine, the 16 corners of the box, and its 8
//! face centres (one factor at an end, the others nominal — e.g. mass ×2 alone).
//!
//! A case **oscillates** when a follower axis' true velocity reverses (±1 mm/s
//! hysteresis, sampled every period) more often than its table does over the run
//! ([`crate::sim::Oscillation::excess`] > 0): a shake a person sees on the machine. A
//! latched fault (the following-error limit tripped by a growing oscillation) is reported
//! with the case and counts as oscillating.

use crate::camfile::CamCsv;
use crate::scenario::{Controller, Role, Scenario, ScenarioError};
use crate::sim::{run as simulate, RunSpec};
use rayon::prelude::*;

/// The box's ends: (low, high) multipliers of mass, bulk modulus and rated flow.
pub const MASS: (f64, f64) = (0.5, 2.0);
/// Bulk modulus multipliers.
pub const BULK: (f64, f64) = (0.5, 1.5);
/// Valve rated-flow multipliers.
pub const FLOW: (f64, f64) = (0.8, 1.2);
/// Supply pressure, bar.
pub const SUPPLY_BAR: (f64, f64) = (120.0, 180.0);

/// One machine of the box: multipliers applied to every follower axis, and the supply.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Variant {
    /// Moving mass ×.
    pub mass: f64,
    /// Bulk modulus ×.
    pub bulk: f64,
    /// Valve rated flow ×.
    pub flow: f64,
    /// Supply pressure, bar (absolute, not a multiplier).
    pub supply_bar: f64,
}

impl Variant {
    /// The scenario's own machine.
    pub fn nominal(s: &Scenario) -> Self {
        Self {
            mass: 1.0,
            bulk: 1.0,
            flow: 1.0,
            supply_bar: s.supply.supply_bar,
        }
    }

    /// A short name: `mass×2 bulk×0.5 flow×1.2 180bar`, only the factors off nominal
    /// (`nominal` for none).
    pub fn label(&self, nominal_supply_bar: f64) -> String {
        let mut parts = Vec::new();
        for (name, k) in [
            ("mass", self.mass),
            ("bulk", self.bulk),
            ("flow", self.flow),
        ] {
            if (k - 1.0).abs() > 1e-9 {
                parts.push(format!("{name}×{k}"));
            }
        }
        if (self.supply_bar - nominal_supply_bar).abs() > 1e-9 {
            parts.push(format!("{}bar", self.supply_bar));
        }
        if parts.is_empty() {
            "nominal".into()
        } else {
            parts.join(" ")
        }
    }

    /// The scenario with this machine's plant: every follower axis' cylinder mass and
    /// bulk modulus and valve rated flow scaled, the supply set. The controller's
    /// calibration and the gain sets are the scenario's.
    pub fn apply(&self, s: &Scenario) -> Scenario {
        let mut out = s.clone();
        out.supply.supply_bar = self.supply_bar;
        for a in out.axes.iter_mut().filter(|a| a.role == Role::Follower) {
            a.cylinder.mass_kg *= self.mass;
            a.cylinder.bulk_modulus_pa *= self.bulk;
            a.valve.rated_flow_l_per_min *= self.flow;
        }
        out
    }
}

/// The cases of the box for scenario `s`: nominal, 16 corners, 8 face centres.
pub fn cases(s: &Scenario) -> Vec<Variant> {
    let n = Variant::nominal(s);
    let mut v = vec![n];
    for bits in 0..16u32 {
        let pick = |bit: u32, (lo, hi): (f64, f64)| if bits & bit == 0 { lo } else { hi };
        v.push(Variant {
            mass: pick(1, MASS),
            bulk: pick(2, BULK),
            flow: pick(4, FLOW),
            supply_bar: pick(8, SUPPLY_BAR),
        });
    }
    for end in [0, 1] {
        let pick = |(lo, hi): (f64, f64)| if end == 0 { lo } else { hi };
        v.push(Variant {
            mass: pick(MASS),
            ..n
        });
        v.push(Variant {
            bulk: pick(BULK),
            ..n
        });
        v.push(Variant {
            flow: pick(FLOW),
            ..n
        });
        v.push(Variant {
            supply_bar: pick(SUPPLY_BAR),
            ..n
        });
    }
    v
}

/// One case's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Case {
    /// Its name ([`Variant::label`]).
    pub label: String,
    /// The machine.
    pub variant: Variant,
    /// Largest |error| of any follower axis after `sim.error_skip_s`, µm.
    pub max_um: f64,
    /// Largest RMS error of any follower axis, µm.
    pub rms_um: f64,
    /// Largest valve command of any follower axis (1 = full opening).
    pub peak_command: f64,
    /// Velocity reversals beyond the table's own, summed over the follower axes.
    pub excess_reversals: u32,
    /// The faults the runtime latched (name and time).
    pub faults: Vec<String>,
    /// Excess reversals or a fault (see the module docs).
    pub oscillating: bool,
    /// The deepest gain backoff level of any follower axis at the end (core
    /// `axis::backoff`: Kp at 0.36, 0.27, 0.20, 0.15 of the set one for levels 1 … 4; 0
    /// without a backoff).
    pub backoff_level: u8,
}

/// Runs every case of `variants` on scenario `s` (two at a time on a 2-core machine);
/// `done` is called after each with the number finished.
pub fn evaluate(
    s: &Scenario,
    table: &CamCsv,
    controller: Controller,
    period_us: u32,
    variants: &[Variant],
    done: &(dyn Fn(usize) + Sync),
) -> Result<Vec<Case>, ScenarioError> {
    let nominal_supply = s.supply.supply_bar;
    let finished = std::sync::atomic::AtomicUsize::new(0);
    variants
        .par_iter()
        .map(|v| {
            let spec = RunSpec {
                controller,
                period_us,
                trace_every_s: None,
            };
            let r = simulate(&v.apply(s), table, &spec, &mut |_| {})?;
            let (max_um, rms_um, peak) = r.followers_worst();
            let excess: u32 = r.oscillation.iter().map(|o| o.excess()).sum();
            let faults: Vec<String> = r
                .faults
                .iter()
                .map(|f| format!("{} at {:.3} s", f.name, f.t_s))
                .collect();
            let n = finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            done(n);
            Ok(Case {
                label: v.label(nominal_supply),
                variant: *v,
                max_um,
                rms_um,
                peak_command: peak,
                excess_reversals: excess,
                oscillating: excess > 0 || !faults.is_empty(),
                faults,
                backoff_level: r.backoff_levels.iter().copied().max().unwrap_or(0),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_has_nominal_16_corners_and_8_face_centres_all_distinct() {
        let s = Scenario::default();
        let c = cases(&s);
        assert_eq!(c.len(), 25);
        assert_eq!(c[0], Variant::nominal(&s));
        for (i, a) in c.iter().enumerate() {
            for b in &c[i + 1..] {
                assert_ne!(a, b);
            }
        }
        let corners = &c[1..17];
        assert!(corners
            .iter()
            .all(|v| v.mass != 1.0 && v.bulk != 1.0 && v.flow != 1.0));
        assert_eq!(c[0].label(s.supply.supply_bar), "nominal");
        assert_eq!(
            corners[15].label(s.supply.supply_bar),
            "mass×2 bulk×1.5 flow×1.2 180bar"
        );
    }

    #[test]
    fn apply_changes_the_follower_plants_and_supply_only() {
        let s = Scenario::default();
        let v = Variant {
            mass: 2.0,
            bulk: 0.5,
            flow: 0.8,
            supply_bar: 120.0,
        };
        let o = v.apply(&s);
        assert_eq!(o.supply.supply_bar, 120.0);
        for (a, b) in s.axes.iter().zip(&o.axes) {
            if a.role == Role::Follower {
                assert_eq!(b.cylinder.mass_kg, 2.0 * a.cylinder.mass_kg);
                assert_eq!(b.cylinder.bulk_modulus_pa, 0.5 * a.cylinder.bulk_modulus_pa);
                assert_eq!(
                    b.valve.rated_flow_l_per_min,
                    0.8 * a.valve.rated_flow_l_per_min
                );
            } else {
                assert_eq!(a.cylinder.mass_kg, b.cylinder.mass_kg);
            }
            assert_eq!(a.calibration, b.calibration, "the controller does not know");
        }
        assert_eq!(s.tuning, o.tuning);
    }
}
