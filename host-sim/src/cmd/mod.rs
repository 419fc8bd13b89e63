//! One module per sub-command of the `host-sim` tool.

pub mod capture;
pub mod contour_estimate;
pub mod fair;
pub mod identify;
pub mod manual;
pub mod margins;
pub mod modbus_map;
pub mod motion;
pub mod open_loop;
pub mod param;
pub mod param_file;
pub mod robust;
pub mod run;
pub mod scurve;
pub mod serial;
pub mod serve;
pub mod status;
pub mod table;
pub mod test_move;
pub mod trace;
pub mod tune;
pub mod upload;
pub mod xy;

/// A scenario shipped in `host-sim/scenarios/`: from the working directory (the project
/// root or `host-sim/`) if it is there, else from the source tree.
pub(crate) fn shipped_scenario(file: &str) -> std::path::PathBuf {
    use std::path::PathBuf;
    [
        PathBuf::from("host-sim/scenarios").join(file),
        PathBuf::from("scenarios").join(file),
    ]
    .into_iter()
    .find(|p| p.is_file())
    .unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(file)
    })
}

/// The scenario, law and period of a command that simulates one scenario on the
/// robustness box or with a probe (`robust`, `margins`); default the tangent axis alone.
#[derive(Debug, clap::Args)]
pub struct SimTarget {
    /// Scenario or machine file (default: host-sim/scenarios/tangent_alone.toml, the
    /// tangent axis alone).
    pub scenario: Option<std::path::PathBuf>,
    /// Follower law (default: the scenario's `sim.controller`).
    #[arg(long, value_enum)]
    pub controller: Option<crate::scenario::Controller>,
    /// Control period, µs (default: the scenario's `sim.period_us`).
    #[arg(long, value_name = "N")]
    pub period_us: Option<u32>,
}

/// A [`SimTarget`] loaded: the scenario, its table, the law and the period.
pub struct Loaded {
    /// The scenario.
    pub s: crate::scenario::Scenario,
    /// Its cam table.
    pub table: crate::camfile::CamCsv,
    /// The follower law.
    pub controller: crate::scenario::Controller,
    /// The control period, µs.
    pub period_us: u32,
}

impl SimTarget {
    /// Loads the scenario (or the shipped `tangent_alone.toml`) and its table.
    pub fn load(&self) -> anyhow::Result<Loaded> {
        let path = self
            .scenario
            .clone()
            .unwrap_or_else(|| shipped_scenario("tangent_alone.toml"));
        let s = crate::scenario::Scenario::load(&path)?;
        let table = s.load_table(None)?;
        Ok(Loaded {
            controller: self.controller.unwrap_or(s.sim.controller),
            period_us: self.period_us.unwrap_or(s.sim.period_us),
            table,
            s,
        })
    }
}
