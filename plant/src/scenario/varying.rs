//! What changes during a run: an axis' external load over time (`[axis.load]`) and the
//! machine drifting from what it was at the start (`[axis.drift]`, `[supply.drift]`).
//!
//! ```toml
//! [axis.load]           # force opposing extension, N: linear between (t_s, N) points,
//! points = [[0, 0], [10, 0], [10, 2000], [20, 2000], [25, -1000]]   # a repeated t is a step
//!
//! [axis.drift]          # multipliers, 1 at start_s, linearly to these at end_s, held after
//! valve_flow = 0.8      # worn valve, another valve of the series
//! bulk_modulus = 0.7    # oil warming, air entrained
//! start_s = 2
//! end_s = 30
//!
//! [supply.drift]        # the supply moving to to_bar between start_s and end_s
//! to_bar = 140
//! start_s = 5
//! end_s = 25
//! ```
//!
//! The simulator applies them at every control period (piecewise constant over a period);
//! the controller is not told. The load adds to the axis' constant `cylinder.load_n`.

use super::{invalid, ScenarioError};
use serde::Deserialize;

/// `[axis.load]`: external force over time, N (positive opposes extension).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadProfile {
    /// `(t_s, force_n)` points, times non-decreasing; held before the first and after the
    /// last; two points at one time are a step.
    pub points: Vec<[f64; 2]>,
}

impl LoadProfile {
    /// The force at `t`, N.
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.points;
        let Some(first) = p.first() else {
            return 0.0;
        };
        if t < first[0] {
            return first[1];
        }
        // The last segment whose start is at or before t (a step takes the later value).
        let k = p.partition_point(|q| q[0] <= t);
        match (p.get(k.wrapping_sub(1)), p.get(k)) {
            (Some(a), Some(b)) if b[0] > a[0] => a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0]),
            (Some(a), _) => a[1],
            (None, _) => first[1],
        }
    }

    /// Checks the points; errors name `key`.
    pub fn validate(&self, key: &str) -> Result<(), ScenarioError> {
        if self.points.is_empty() {
            return Err(invalid(
                key,
                "[]",
                "needs at least one (t_s, force_n) point",
            ));
        }
        let mut prev = f64::NEG_INFINITY;
        for (i, [t, f]) in self.points.iter().enumerate() {
            if !(t.is_finite() && *t >= 0.0 && f.is_finite() && f.abs() <= 1e6) {
                return Err(invalid(
                    format!("{key}.points[{i}]"),
                    format!("[{t}, {f}]"),
                    "must be a time ≥ 0 s and a force within ±1 MN",
                ));
            }
            if *t < prev {
                return Err(invalid(
                    format!("{key}.points[{i}]"),
                    t,
                    format!("times must not decrease (previous {prev} s)"),
                ));
            }
            prev = *t;
        }
        Ok(())
    }
}

/// The ramp 0 → 1 between `start_s` and `end_s` (a step at `start_s` when they are equal).
fn ramp(t: f64, start_s: f64, end_s: f64) -> f64 {
    if t >= end_s {
        1.0
    } else if t <= start_s {
        0.0
    } else {
        (t - start_s) / (end_s - start_s)
    }
}

fn check_window(key: &str, start_s: f64, end_s: f64) -> Result<(), ScenarioError> {
    if !(start_s.is_finite() && start_s >= 0.0 && end_s.is_finite() && end_s >= start_s) {
        return Err(invalid(
            format!("{key}.start_s / end_s"),
            format!("{start_s} / {end_s}"),
            "must be 0 ≤ start_s ≤ end_s (s)",
        ));
    }
    Ok(())
}

/// `[axis.drift]`: the axis' valve and oil changing during the run.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisDrift {
    /// Valve flow gain × at `end_s` (1 at `start_s`).
    pub valve_flow: f64,
    /// Bulk modulus × at `end_s`.
    pub bulk_modulus: f64,
    /// Where the drift starts, s.
    pub start_s: f64,
    /// Where it is complete, s.
    pub end_s: f64,
}

impl Default for AxisDrift {
    fn default() -> Self {
        Self {
            valve_flow: 1.0,
            bulk_modulus: 1.0,
            start_s: 0.0,
            end_s: 0.0,
        }
    }
}

impl AxisDrift {
    /// (valve flow ×, bulk modulus ×) at `t`.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let r = ramp(t, self.start_s, self.end_s);
        (
            1.0 + (self.valve_flow - 1.0) * r,
            1.0 + (self.bulk_modulus - 1.0) * r,
        )
    }

    /// Checks the values; errors name `key`.
    pub fn validate(&self, key: &str) -> Result<(), ScenarioError> {
        for (name, k) in [
            ("valve_flow", self.valve_flow),
            ("bulk_modulus", self.bulk_modulus),
        ] {
            if !(k.is_finite() && (0.25..=4.0).contains(&k)) {
                return Err(invalid(
                    format!("{key}.{name}"),
                    k,
                    "must be a multiplier in [0.25, 4]",
                ));
            }
        }
        check_window(key, self.start_s, self.end_s)
    }
}

/// `[supply.drift]`: the supply pressure moving during the run.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SupplyDrift {
    /// The pressure at `end_s`, bar.
    pub to_bar: f64,
    /// Where the drift starts, s.
    #[serde(default)]
    pub start_s: f64,
    /// Where it is complete, s.
    #[serde(default)]
    pub end_s: f64,
}

impl SupplyDrift {
    /// The supply at `t` from `from_bar`, bar.
    pub fn at(&self, t: f64, from_bar: f64) -> f64 {
        from_bar + (self.to_bar - from_bar) * ramp(t, self.start_s, self.end_s)
    }

    /// Checks the values against the tank pressure (the chambers' clamp follows the
    /// supply: `clamp_factor · p_s(t)`).
    pub fn validate(&self, tank_bar: f64) -> Result<(), ScenarioError> {
        if !(self.to_bar.is_finite() && self.to_bar > tank_bar && self.to_bar <= 1000.0) {
            return Err(invalid(
                "supply.drift.to_bar",
                self.to_bar,
                format!("must be above the tank ({tank_bar} bar) and at most 1000 bar"),
            ));
        }
        check_window("supply.drift", self.start_s, self.end_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_load_profile_interpolates_holds_and_steps() {
        let l = LoadProfile {
            points: vec![[1.0, 0.0], [2.0, 1000.0], [2.0, 3000.0], [4.0, -1000.0]],
        };
        assert_eq!(l.at(0.0), 0.0);
        assert_eq!(l.at(1.5), 500.0);
        assert_eq!(l.at(1.999), 999.0000000000001);
        assert_eq!(
            l.at(2.0),
            3000.0,
            "the step takes the later value at its time"
        );
        assert_eq!(l.at(3.0), 1000.0);
        assert_eq!(l.at(9.0), -1000.0);
        assert_eq!(LoadProfile::default().at(1.0), 0.0);
        assert!(l.validate("axis.tangent.load").is_ok());
        let back = LoadProfile {
            points: vec![[2.0, 0.0], [1.0, 0.0]],
        };
        let e = back.validate("axis.tangent.load").unwrap_err().to_string();
        assert!(
            e.contains("points[1]") && e.contains("must not decrease"),
            "{e}"
        );
        assert!(LoadProfile::default().validate("k").is_err());
    }

    #[test]
    fn drifts_ramp_from_one_and_refuse_nonsense() {
        let d = AxisDrift {
            valve_flow: 0.8,
            bulk_modulus: 0.5,
            start_s: 10.0,
            end_s: 20.0,
        };
        assert_eq!(d.at(5.0), (1.0, 1.0));
        assert_eq!(d.at(15.0), (0.9, 0.75));
        assert_eq!(d.at(30.0), (0.8, 0.5));
        assert!(d.validate("axis.t.drift").is_ok());
        let bad = AxisDrift {
            valve_flow: 0.0,
            ..d
        };
        assert!(bad
            .validate("axis.t.drift")
            .unwrap_err()
            .to_string()
            .contains("valve_flow"));
        let bad = AxisDrift { end_s: 1.0, ..d };
        assert!(bad.validate("axis.t.drift").is_err());
        let s = SupplyDrift {
            to_bar: 140.0,
            start_s: 0.0,
            end_s: 10.0,
        };
        assert_eq!(s.at(5.0, 160.0), 150.0);
        assert!(s.validate(0.0).is_ok());
        assert!(SupplyDrift {
            to_bar: 2000.0,
            ..s
        }
        .validate(0.0)
        .is_err());
        assert!(SupplyDrift { to_bar: -1.0, ..s }.validate(0.0).is_err());
        // A drift of no duration is a step at its time (the later value, like a load step).
        assert_eq!(ramp(3.0, 3.0, 3.0), 1.0);
        assert_eq!(ramp(2.999, 3.0, 3.0), 0.0);
    }
}
