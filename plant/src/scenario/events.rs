//! `[events]`: what happens to the board's inputs during a run — the E-stop chain
//! opening, an encoder lost, the pressure inputs lost. The run feeds them to the
//! runtime through core's board traits (`SafetyInput`, `EncoderInput`,
//! `PressureInput`), so the firmware's reaction is what the run shows: the fault by
//! name, the valves at null from the next period on, `host-sim run` exiting 3.
//!
//! ```toml
//! [events]
//! estop_at_s = 12.0                                     # the E-stop chain opens, s
//! pressure_lost_at_s = 5.0                              # the pressure inputs stop updating, s
//! encoder_lost = { axis = "tangent", at_s = 3.0, mode = "freeze" }
//! ```

use super::{invalid, ScenarioError};
use serde::Deserialize;

/// `[events]`: times are simulated seconds from the start of the run.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct EventsCfg {
    /// From this time on the E-stop input is active (the chain is open), s.
    pub estop_at_s: Option<f64>,
    /// From this time on the board reports its pressure inputs stale
    /// (`PressureInput::healthy` false), s. A runtime that needs them (the scenario has a
    /// force axis) latches `pressure_input`; otherwise the law keeps the last live
    /// pressures and the run goes on.
    pub pressure_lost_at_s: Option<f64>,
    /// An axis' encoder lost (a follower's or a force axis').
    pub encoder_lost: Option<EncoderLoss>,
}

/// `events.encoder_lost`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EncoderLoss {
    /// The axis (its `name`): a follower or a force axis.
    pub axis: String,
    /// From this time on, s.
    pub at_s: f64,
    /// How the count fails (default `freeze`).
    #[serde(default)]
    pub mode: EncoderLossMode,
}

/// How a lost encoder's count fails.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EncoderLossMode {
    /// A broken cable: no more edges, the count stays where it was while the axis moves
    /// on (the runtime sees it as a following error once the axis moves).
    #[default]
    Freeze,
    /// The counter restarts from 0 (an encoder supply dropout resetting the interface):
    /// one step far beyond the plausible speed (`encoder_jump`).
    Reset,
}

impl EventsCfg {
    /// Checks the times and that the encoder names an axis of the scenario (`axes`).
    pub fn validate(&self, axes: &[&str]) -> Result<(), ScenarioError> {
        let time = |key: &str, t: f64| {
            if t.is_finite() && (0.0..=1e6).contains(&t) {
                Ok(())
            } else {
                Err(invalid(key, t, "must be in [0, 1000000] s"))
            }
        };
        if let Some(t) = self.estop_at_s {
            time("events.estop_at_s", t)?;
        }
        if let Some(t) = self.pressure_lost_at_s {
            time("events.pressure_lost_at_s", t)?;
        }
        if let Some(e) = &self.encoder_lost {
            time("events.encoder_lost.at_s", e.at_s)?;
            if !axes.contains(&e.axis.as_str()) {
                return Err(invalid(
                    "events.encoder_lost.axis",
                    &e.axis,
                    format!("no axis of that name (axes: {axes:?})"),
                ));
            }
        }
        Ok(())
    }

    /// The E-stop input at time `t`, s.
    pub fn estop(&self, t: f64) -> bool {
        self.estop_at_s.is_some_and(|at| t >= at)
    }

    /// Whether the pressure inputs are live at time `t`, s.
    pub fn pressure_live(&self, t: f64) -> bool {
        !self.pressure_lost_at_s.is_some_and(|at| t >= at)
    }

    /// The count follower `axis` reads at time `t` given its true count `count` and the
    /// count it read at the period before (`last`).
    pub fn encoder_count(&self, axis: &str, t: f64, count: i64, last: i64) -> i64 {
        match &self.encoder_lost {
            Some(e) if e.axis == axis && t >= e.at_s => match e.mode {
                EncoderLossMode::Freeze => last,
                EncoderLossMode::Reset => 0,
            },
            _ => count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_act_from_their_time_on() {
        let e: EventsCfg = toml::from_str(
            "estop_at_s = 2.0\npressure_lost_at_s = 1.0\n\
             encoder_lost = { axis = \"x\", at_s = 3.0, mode = \"reset\" }",
        )
        .unwrap();
        e.validate(&["x"]).unwrap();
        assert!(!e.estop(1.999) && e.estop(2.0));
        assert!(e.pressure_live(0.5) && !e.pressure_live(1.0));
        assert_eq!(e.encoder_count("x", 2.9, 500, 400), 500);
        assert_eq!(e.encoder_count("x", 3.0, 500, 400), 0);
        assert_eq!(e.encoder_count("y", 3.0, 500, 400), 500);
        let freeze: EventsCfg =
            toml::from_str("encoder_lost = { axis = \"x\", at_s = 0.0 }").unwrap();
        assert_eq!(freeze.encoder_count("x", 1.0, 500, 400), 400);
        assert_eq!(EventsCfg::default().encoder_count("x", 9.0, 7, 3), 7);
    }

    #[test]
    fn bad_events_name_the_key() {
        let e: EventsCfg = toml::from_str("estop_at_s = -1.0").unwrap();
        let msg = e.validate(&[]).unwrap_err().to_string();
        assert!(msg.contains("events.estop_at_s"), "{msg}");
        let e: EventsCfg = toml::from_str("encoder_lost = { axis = \"q\", at_s = 1.0 }").unwrap();
        let msg = e.validate(&["x"]).unwrap_err().to_string();
        assert!(
            msg.contains("events.encoder_lost.axis") && msg.contains("q"),
            "{msg}"
        );
        assert!(toml::from_str::<EventsCfg>("estop_at = 1.0").is_err());
        assert!(toml::from_str::<EventsCfg>(
            "encoder_lost = { axis = \"x\", at_s = 1.0, mode = \"melt\" }"
        )
        .is_err());
    }
}
