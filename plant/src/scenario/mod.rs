//! Scenario files (TOML): the machine, its master motion, its table and its controllers.
//!
//! Every key has a default, and the defaults are the reference machine of
//! `shared/PLANT.md`: an empty file simulates the tangent cylinder following the
//! elliptical-die table plus the side press. Unknown keys are errors (serde
//! `deny_unknown_fields`, reported by the TOML parser with their line), and impossible
//! values are [`ScenarioError::Invalid`] naming the key, e.g.
//! `axis.tangent.cylinder.rod_mm = 90: must be smaller than cylinder.bore_mm (80)`.
//!
//! Units are in the key names: `_mm`, `_um`, `_bar`, `_deg`, `_s`, `_hz`, `_l`
//! (litres), `_l_per_min`, `_n` (newtons), `_kg`, SI elsewhere (`bulk_modulus_pa`,
//! `leakage_m3_per_s_pa`, `viscous_n_s_per_m`, `stiffness_n_per_m`).

//!
//! Layout: this file is the schema (the structs a file deserialises into) and loading;
//! [`defaults`] the reference values, [`validate`] the checks, [`physics`] the plant and
//! sensors the data describe, [`gains`] the core configurations the gain sets become.
//! Nothing here runs the simulator or the tuning procedure.

mod defaults;
pub mod events;
pub mod gains;
mod physics;
mod validate;
pub mod varying;

pub use defaults::reference_tuning;
/// The gain sets of `[tuning.axes.<name>]` and `[tuning.press.<name>]` are core's own
/// (deserialised with `hydra_core`'s `serde` feature).
pub use hydra_core::axis::{PositionGains, PressGains};

use crate::camfile::{CamCsv, TableError};
use crate::die::DieTable;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A problem with a scenario file.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file cannot be read.
    #[error("cannot read scenario {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not valid TOML, a wrong type, or an unknown key.
    #[error("scenario {path}: {source}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message (names the key and the line).
        source: Box<toml::de::Error>,
    },
    /// A value that cannot describe a real machine.
    #[error("scenario: `{key}` = {value}: {reason}")]
    Invalid {
        /// Dotted path of the key, e.g. `axis.tangent.cylinder.rod_mm`.
        key: String,
        /// The offending value.
        value: String,
        /// Why it is impossible.
        reason: String,
    },
    /// The cam table cannot be loaded.
    #[error(transparent)]
    Table(#[from] TableError),
}

pub(crate) fn invalid(
    key: impl Into<String>,
    value: impl ToString,
    reason: impl Into<String>,
) -> ScenarioError {
    ScenarioError::Invalid {
        key: key.into(),
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// A scenario.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Name shown in reports (default: the file's stem; see [`Scenario::name`]).
    #[serde(default)]
    pub name: String,
    /// Integration and control timing.
    pub sim: SimCfg,
    /// The hydraulic power unit.
    pub supply: SupplyCfg,
    /// The master motion.
    pub master: MasterCfg,
    /// The cam table.
    pub table: TableCfg,
    /// The axes (`[[axis]]`).
    #[serde(rename = "axis")]
    pub axes: Vec<AxisCfg>,
    /// Controller gains, one set per (controller, period) (`[[tuning]]`). A file without
    /// any gets the reference machine's sets, restricted to the axes of the file that
    /// share a reference axis' name and role (other axes run on the core's default gains).
    #[serde(default)]
    pub tuning: Vec<Tuning>,
    /// What happens to the board's inputs during a run ([`events`]).
    pub events: events::EventsCfg,
    /// Directory that relative paths in the file are resolved against.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

/// `[sim]`: integration and control timing.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SimCfg {
    /// RK4 step, µs (PLANT.md: 10). The control period must be a whole number of steps.
    pub step_us: f64,
    /// Control period, µs.
    pub period_us: u32,
    /// Errors are measured after this time, s (PLANT.md: 1.5).
    pub error_skip_s: f64,
    /// Simulated time, s (default: the master's motion and hold).
    pub duration_s: Option<f64>,
    /// Follower law used when the command line names none.
    pub controller: Controller,
}

/// `[supply]`: the hydraulic power unit (an ideal constant-pressure source).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SupplyCfg {
    /// Supply pressure p_s, bar (PLANT.md: 160).
    pub supply_bar: f64,
    /// Tank pressure, bar (PLANT.md: 0).
    pub tank_bar: f64,
    /// Chamber pressures are clamped to `[0, clamp_factor·p_s]` (PLANT.md: 1.1).
    pub clamp_factor: f64,
    /// The supply moving during the run.
    pub drift: Option<varying::SupplyDrift>,
}

/// `[master]`: the rotary table's motion and encoder.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MasterCfg {
    /// Start angle, degrees.
    pub start_deg: f64,
    /// End angle, degrees (reached exactly).
    pub end_deg: f64,
    /// Nominal speed, °/s.
    pub speed_deg_per_s: f64,
    /// Duration of each cosine speed ramp, s.
    pub ramp_s: f64,
    /// Relative speed ripple (0.03 = ±3 %).
    pub ripple: f64,
    /// Ripple frequency, Hz.
    pub ripple_hz: f64,
    /// Ripple phase at the start of the motion, degrees.
    pub ripple_phase_deg: f64,
    /// Rest before the motion starts, s.
    pub start_s: f64,
    /// Rest at the end angle after the motion, s.
    pub hold_s: f64,
    /// Master encoder resolution, degrees per count (PLANT.md: 0.001).
    pub resolution_deg: f64,
    /// The board's edge timer, Hz: it timestamps the master encoder's rising A edges and
    /// the runtime estimates the master below one count from them
    /// (`hydra_core::master::EdgeEstimator`). Default 1 MHz, the firmware's; 0 = no edge
    /// timer (the master is the count alone).
    pub edge_timer_hz: f64,
}

/// `[table]`: where the cam table comes from.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct TableCfg {
    /// CSV file (relative to the scenario file). Default: the elliptical-die table of
    /// PLANT.md, generated.
    pub file: Option<PathBuf>,
}

/// What an axis does.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Follows its column of the cam table (column name = axis name).
    #[default]
    Follower,
    /// Approaches under position control, then holds a force (the side press).
    Force,
}

/// `[[axis]]`: one hydraulic axis.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AxisCfg {
    /// Name (a follower's table column has the same name).
    pub name: String,
    /// What the axis does.
    pub role: Role,
    /// Initial position, mm (default: a follower's table value at the start angle; a
    /// force axis' 10 mm).
    pub x0_mm: Option<f64>,
    /// The valve.
    pub valve: ValveCfg,
    /// The cylinder and its load.
    pub cylinder: CylinderCfg,
    /// An optional spring contact (the workpiece).
    pub contact: Option<ContactCfg>,
    /// The sensors.
    pub sensors: SensorCfg,
    /// Valve output calibration in the controller (null, overlap, gains).
    pub calibration: hydra_core::valve::ValveCal,
    /// The press process of a force axis (`role = "force"`).
    pub press: Option<PressCfg>,
    /// An external load over time (adds to `cylinder.load_n`).
    pub load: Option<varying::LoadProfile>,
    /// The valve and oil drifting during the run.
    pub drift: Option<varying::AxisDrift>,
}

/// `[axis.press]`: the press process of a force axis (PLANT.md's side press).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PressCfg {
    /// End of the approach ramp, beyond the expected contact, mm.
    pub approach_end_mm: f64,
    /// Approach speed, mm/s.
    pub approach_speed_mm_per_s: f64,
    /// Force at which contact is declared and force control takes over, N.
    pub contact_force_n: f64,
    /// Force set-point, N (PLANT.md: 20 kN).
    pub force_set_n: f64,
    /// Time to ramp the force from contact to the set-point, s (PLANT.md: 1).
    pub force_ramp_s: f64,
}

/// The follower law (`--controller`).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Controller {
    /// PID toward the table node at the far end of the current segment (core `NextNode`).
    Traditional,
    /// The published method exactly: 3-point master prediction, incremental PID with
    /// integral separation.
    Paper,
    /// Feedback at the sampling instant + feed-forward aimed at the interval in which the
    /// command acts (core `Feedforward`, the default).
    #[default]
    Feedforward,
}

impl Controller {
    /// All three, in the order of the comparison table.
    pub const ALL: [Controller; 3] = [
        Controller::Traditional,
        Controller::Paper,
        Controller::Feedforward,
    ];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Controller::Traditional => "traditional",
            Controller::Paper => "paper",
            Controller::Feedforward => "feedforward",
        }
    }

    /// The core's control mode.
    pub fn mode(self) -> hydra_core::axis::ControlMode {
        match self {
            Controller::Traditional => hydra_core::axis::ControlMode::NextNode,
            Controller::Paper => hydra_core::axis::ControlMode::Paper,
            Controller::Feedforward => hydra_core::axis::ControlMode::Feedforward,
        }
    }
}

/// The paper mode's master extrapolation.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum PredictorCfg {
    /// The published 3-point extrapolation as printed (short by ½·θ̈·T² on an
    /// accelerating master).
    #[default]
    Eq4,
    /// Exact quadratic extrapolation.
    Quadratic,
}

/// `[[tuning]]`: the gains of every axis for one controller at one control period.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Tuning {
    /// The follower law these gains are for.
    pub controller: Controller,
    /// The control period they were tuned at, µs. A run at another period uses the set
    /// of the shortest tuned period at or above it (gains tuned for a longer period are
    /// the conservative choice), else the longest.
    pub period_us: u32,
    /// Master tracking-filter bandwidth, Hz (≤ 0.2/T).
    #[serde(default = "default_master_filter_hz")]
    pub master_filter_hz: f64,
    /// The paper mode's predictor.
    #[serde(default)]
    pub predictor: PredictorCfg,
    /// Gains of each follower axis, by axis name (`[tuning.axes.<name>]`).
    #[serde(default)]
    pub axes: std::collections::BTreeMap<String, PositionGains>,
    /// Gains of each force axis, by axis name (`[tuning.press.<name>]`).
    #[serde(default)]
    pub press: std::collections::BTreeMap<String, PressGains>,
}

fn default_master_filter_hz() -> f64 {
    8.0
}

/// `[axis.valve]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ValveCfg {
    /// Spool natural frequency, Hz (PLANT.md: 60).
    pub bandwidth_hz: f64,
    /// Spool damping ratio (PLANT.md: 0.8).
    pub damping: f64,
    /// Rated flow per land at full opening, L/min (PLANT.md: 24).
    pub rated_flow_l_per_min: f64,
    /// Pressure drop per land at the rated flow, bar (PLANT.md: 35).
    pub rated_dp_bar: f64,
    /// Laminar leakage per land, m³/(s·Pa) (PLANT.md: 1e−13).
    pub leakage_m3_per_s_pa: f64,
    /// Below this |Δp| the orifice flow is laminar (linear, see `plant::valve`), bar.
    pub transition_bar: f64,
}

/// `[axis.cylinder]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CylinderCfg {
    /// Bore, mm (PLANT.md: 80).
    pub bore_mm: f64,
    /// Rod diameter, mm (PLANT.md: 45).
    pub rod_mm: f64,
    /// Stroke, mm (PLANT.md: 500; the side press 100).
    pub stroke_mm: f64,
    /// Dead volume on the piston side, L (PLANT.md: 0.3).
    pub dead_volume_a_l: f64,
    /// Dead volume on the rod side, L (PLANT.md: 0.3).
    pub dead_volume_b_l: f64,
    /// Effective bulk modulus, Pa (PLANT.md: 1.4e9).
    pub bulk_modulus_pa: f64,
    /// Moving mass, kg (PLANT.md: 300).
    pub mass_kg: f64,
    /// Viscous friction, N·s/m (PLANT.md: 3000).
    pub viscous_n_s_per_m: f64,
    /// Coulomb friction, N (PLANT.md: 400).
    pub coulomb_n: f64,
    /// Speed of the tanh smoothing of the Coulomb friction, mm/s (PLANT.md: 1).
    pub coulomb_smoothing_mm_per_s: f64,
    /// External load, N, positive opposes extension (PLANT.md: optional, 0).
    pub load_n: f64,
    /// Stiffness of the mechanical end stops, N/m.
    pub stop_stiffness_n_per_m: f64,
    /// Damping ratio of the end stops against the moving mass.
    pub stop_damping_ratio: f64,
}

/// `[axis.contact]`: a spring beyond a position.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ContactCfg {
    /// Contact position, mm (PLANT.md side press: 50).
    pub position_mm: f64,
    /// Stiffness beyond it, N/m (PLANT.md side press: 5e6).
    pub stiffness_n_per_m: f64,
}

/// `[axis.sensors]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SensorCfg {
    /// Linear encoder resolution, µm per count (PLANT.md: 1).
    pub encoder_um: f64,
    /// Pressure transducer full scale, bar (PLANT.md: 250).
    pub pressure_full_scale_bar: f64,
    /// Pressure ADC resolution, bits (PLANT.md: 12).
    pub pressure_adc_bits: u32,
}

impl Scenario {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut s = Self::parse(&text, path)?;
        s.base_dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        if s.name.is_empty() {
            s.name = path
                .file_stem()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into());
        }
        s.validate()?;
        Ok(s)
    }

    /// Parses TOML text (not yet validated); `path` is only used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let mut s: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: path.to_path_buf(),
            source: Box::new(e),
        })?;
        if s.tuning.is_empty() {
            s.tuning = reference_tuning();
            let has =
                |name: &str, role: Role| s.axes.iter().any(|a| a.name == name && a.role == role);
            let keep: Vec<Tuning> = s
                .tuning
                .iter()
                .map(|t| {
                    let mut t = t.clone();
                    t.axes.retain(|n, _| has(n, Role::Follower));
                    t.press.retain(|n, _| has(n, Role::Force));
                    t
                })
                .collect();
            s.tuning = keep;
        }
        Ok(s)
    }

    /// The name shown in reports: `name`, else `reference` (PLANT.md's machine).
    pub fn name(&self) -> &str {
        if self.name.is_empty() {
            "reference"
        } else {
            &self.name
        }
    }

    /// RK4 step, s.
    pub fn step_s(&self) -> f64 {
        self.sim.step_us * 1e-6
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        f64::from(self.sim.period_us) * 1e-6
    }

    /// RK4 steps per control period (validated to be a whole number).
    pub fn steps_per_period(&self) -> u32 {
        (f64::from(self.sim.period_us) / self.sim.step_us).round() as u32
    }

    /// Simulated time, s.
    pub fn duration_s(&self) -> Result<f64, ScenarioError> {
        match self.sim.duration_s {
            Some(d) => Ok(d),
            None => Ok(self.master_profile()?.duration_s()),
        }
    }

    /// The cam table: the CSV file of `[table]` (or `override_file`), or the generated
    /// elliptical-die table. Checks that every follower axis has its column.
    pub fn load_table(&self, override_file: Option<&Path>) -> Result<CamCsv, ScenarioError> {
        let table = match (override_file, &self.table.file) {
            (Some(f), _) => CamCsv::load(f)?,
            (None, Some(f)) => CamCsv::load(&self.base_dir.join(f))?,
            (None, None) => DieTable::default().table(),
        };
        for a in self.axes.iter().filter(|a| a.role == Role::Follower) {
            if table.column(&a.name).is_none() {
                return Err(invalid(
                    format!("axis.{}.name", a.name),
                    &a.name,
                    format!(
                        "a follower needs a column of that name in the table {} (columns: {})",
                        table.path.display(),
                        table.axes.join(", ")
                    ),
                ));
            }
        }
        Ok(table)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Scenario, ScenarioError> {
        let sc = Scenario::parse(s, Path::new("s.toml"))?;
        sc.validate()?;
        Ok(sc)
    }

    #[test]
    fn empty_file_is_the_reference_machine() {
        let s = parse("").unwrap();
        assert_eq!(s, Scenario::default());
        assert_eq!(s.axes.len(), 2);
        let c = s.axes[0].cylinder_si();
        let f = c.natural_frequency_hz(0.25);
        assert!((f - 56.0).abs() < 0.5, "{f}");
        assert_eq!(s.steps_per_period(), 100);
    }

    #[test]
    fn the_calibration_table_is_cores_valve_calibration() {
        let s =
            parse("[[axis]]\nname = \"a\"\n[axis.calibration]\nnull_lsb = 12\ngain_neg = 0.9\n")
                .unwrap();
        let c = s.axes[0].calibration;
        assert_eq!((c.null_lsb, c.gain_neg), (12.0, 0.9));
        assert_eq!(
            c.clamp_lsb,
            hydra_core::valve::ValveCal::default().clamp_lsb
        );
        let e = parse("[[axis]]\nname = \"a\"\n[axis.calibration]\nnul_lsb = 1\n").unwrap_err();
        assert!(e.to_string().contains("unknown field `nul_lsb`"), "{e}");
    }

    #[test]
    fn unknown_keys_and_bad_values_name_the_key() {
        let e = |s: &str| parse(s).unwrap_err().to_string();
        assert!(e("[sim]\nstep_uss = 5\n").contains("unknown field `step_uss`"));
        assert!(e("[[axis]]\nname = \"a\"\n[axis.cylinder]\nbore = 3\n")
            .contains("unknown field `bore`"));
        assert!(e("[[axis]]\nname = \"a\"\n[axis.cylinder]\nrod_mm = 90\n")
            .contains("`axis.a.cylinder.rod_mm` = 90: must be smaller than cylinder.bore_mm"));
        assert!(
            e("[sim]\nperiod_us = 15\n").contains("`sim.period_us` = 15: must be a whole number")
        );
        assert!(e("[sim]\nstep_us = 500\nperiod_us = 1000\n").contains("`sim.step_us` = 500"));
        assert!(e("[master]\nripple = 1.5\n").contains("`master.ripple`"));
        assert!(e("[master]\nend_deg = 1\n").contains("`master.end_deg` = 1: master travel"));
        assert!(e("[supply]\nsupply_bar = nan\n")
            .contains("`supply.supply_bar` = NaN: must be a finite"));
        assert!(e("[[axis]]\nname = \"a b\"\n").contains("axis[0].name"));
        assert!(e("[[axis]]\nname = \"a\"\n[[axis]]\nname = \"a\"\n").contains("two axes"));
        assert!(e("[[axis]]\nname = \"a\"\nx0_mm = 600\n").contains("`axis.a.x0_mm` = 600"));
        assert!(e("[sim]\nperiod_us = \"x\"\n").contains("period_us"));
        for bad in ["-1", "10", "2e9", "nan"] {
            let msg = e(&format!("[master]\nedge_timer_hz = {bad}\n"));
            assert!(msg.contains("`master.edge_timer_hz`"), "{bad}: {msg}");
        }
        assert!(
            parse("[master]\nedge_timer_hz = 0\n").is_ok(),
            "0: no edge timer"
        );
    }

    #[test]
    fn follower_needs_a_column() {
        let s = parse("[[axis]]\nname = \"lift\"\n").unwrap();
        let e = s.load_table(None).unwrap_err().to_string();
        assert!(e.contains("`axis.lift.name`"), "{e}");
    }
}
