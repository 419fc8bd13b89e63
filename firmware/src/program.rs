//! The configuration the board boots with: runtime limits, the follower's gains and the
//! limits every table is validated against.
//!
//! With the framed protocol (the default build) the cam table comes from flash (the
//! newest valid slot) or over the host link; an empty flash boots without a law (Start
//! is refused until a table is activated). The bring-up build (`--features console`)
//! boots with the reference machine's program (PLANT.md) instead:
//! slave 0 is the tangent cylinder following the die's cam table — the support point of a 900 × 600 mm ellipse centred 250 mm off the rotation axis, nodes
//! every 0.5° from 0° to 90° (181 nodes), scaled to 20…480 mm — and slave 1 holds 20 mm
//! over the whole table. The table is computed once at boot (f64, `libm`); the tick
//! never touches a float.

#[cfg(feature = "console")]
use heapless::Vec;
use hydra_core::axis::{AxisConfig, ControlMode};
use hydra_core::follower::{Follower, FollowerConfig};
use hydra_core::runtime::{ReferenceMode, RuntimeCoeffs, RuntimeConfig};
#[cfg(feature = "console")]
use hydra_core::table::Node;
use hydra_core::table::{AxisLimits, TableLimits};
#[cfg(feature = "console")]
use hydra_core::units::Master;
use hydra_core::units::{MasterRate, PosUm, VelUmPerS};

use crate::board::{DAC_RANGE, SLAVES};
use hydra_core::valve::ValveCal;

/// Table capacity (nodes).
pub const TABLE_NODES: usize = 256;
/// The control law of this board.
pub type Law = Follower<SLAVES, TABLE_NODES>;
/// Control period, µs (1 kHz; 100 µs = 10 kHz is the fastest the runtime accepts).
pub const PERIOD_US: u32 = 1000;

/// Why the boot program could not be built.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum ProgramError {
    /// The runtime configuration.
    Runtime(hydra_core::runtime::RuntimeConfigError),
    /// The cam table.
    #[cfg(feature = "console")]
    Table(hydra_core::table::TableError),
    /// The follower configuration.
    #[cfg(feature = "console")]
    Follower(hydra_core::follower::FollowerError),
    /// The law buffers were taken already.
    #[cfg(feature = "console")]
    Taken,
}

/// The runtime limits (reference machine defaults at [`PERIOD_US`]).
pub fn runtime_coeffs() -> Result<RuntimeCoeffs<SLAVES>, ProgramError> {
    RuntimeConfig::<SLAVES> {
        period_us: PERIOD_US,
        // Incremental linear encoders: each slave is referenced (set-position or
        // homing to its index / reference input) before Start.
        slave_reference: [ReferenceMode::Incremental; SLAVES],
        // The reference marks of the reference machine's cylinders sit at 20 mm.
        home_position_um: [20_000.0; SLAVES],
        // No force axis on this board's law: stale pressures are reported, not a fault.
        pressure_required: false,
        ..RuntimeConfig::default()
    }
    .build()
    .map_err(ProgramError::Runtime)
}

/// x_raw(θ) of PLANT.md, mm.
#[cfg(feature = "console")]
fn x_raw_mm(theta_deg: f64) -> f64 {
    let (a, b, e) = (900.0f64, 600.0f64, 250.0f64);
    let t = theta_deg.to_radians();
    let (s, c) = (libm::sin(t), libm::cos(t));
    e * c + (a * a - b * b) * s * c / libm::sqrt(a * a * s * s + b * b * c * c)
}

/// The limits every table is validated against (at upload, at boot from flash): slaves
/// 0 … 500 mm at up to 200 mm/s, master up to 10 °/s (three times the nominal table
/// speed; 1 master count = 0.001°).
pub fn table_limits() -> TableLimits<SLAVES> {
    let axis = AxisLimits {
        min_um: PosUm::from_num(0),
        max_um: PosUm::from_num(500_000),
        max_speed_um_per_s: VelUmPerS::from_num(200_000),
    };
    TableLimits {
        master_speed_per_s: MasterRate::from_num(10_000),
        axes: [axis; SLAVES],
    }
}

/// The follower's configuration on every slave: the reference machine's feed-forward
/// gain set at 1 ms (`host-sim/scenarios/tangent.toml`, `[[tuning]]` controller
/// `feedforward`, `period_us = 1000`: the set `host-sim run` uses), so the board runs
/// what the simulator measured. (The earlier hand-set gains — kp 0.4, ki 5, i_limit 100
/// LSB — lagged 0.5 mm on the retraction; found by running this firmware in board-emu.)
pub fn follower_config() -> FollowerConfig<SLAVES> {
    let axis = AxisConfig {
        mode: ControlMode::Feedforward,
        kp_lsb_per_um: 1.1,
        ki_lsb_per_um_s: 18.0,
        kd_lsb_s_per_um: 0.0,
        i_zone_um: 10_000.0,
        i_limit_lsb: 200.0,
        kv_pos_lsb_per_um_s: 0.01389,
        kv_neg_lsb_per_um_s: 0.01683,
        ka_lsb_per_um_s2: 0.0,
        valve_lag_us: 4244.0,
        following_error_um: 5000.0,
        valve: ValveCal {
            // The law's own output clamp is the board's usable DAC range, so it never
            // commands a code the pin cannot follow (its integrator then sees the real
            // limit).
            clamp_lsb: DAC_RANGE.max_code().unsigned_abs(),
            ..ValveCal::default()
        },
    };
    FollowerConfig::<SLAVES> {
        period_us: PERIOD_US,
        axes: [axis; SLAVES],
        ..FollowerConfig::default()
    }
}

/// The reference cam table's nodes (see the module docs): 181 nodes of 16 bytes, two
/// passes over x_raw(θ) (range, then nodes) so no array of raw values sits beside them.
#[cfg(feature = "console")]
fn reference_nodes() -> Vec<Node<SLAVES>, 181> {
    const ROWS: usize = 181;
    let theta = |j: usize| j as f64 * 0.5;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for j in 0..ROWS {
        let r = x_raw_mm(theta(j));
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let mut nodes: Vec<Node<SLAVES>, ROWS> = Vec::new();
    for j in 0..ROWS {
        let r = x_raw_mm(theta(j));
        let x_um = 1000.0 * (20.0 + (r - lo) * (480.0 - 20.0) / (hi - lo));
        let node = Node {
            // 0.5° = 500 master counts of 0.001°.
            master: Master::from_num(j as i64 * 500),
            slave_um: [PosUm::saturating_from_num(x_um), PosUm::from_num(20_000)],
        };
        // ROWS ≤ capacity: cannot fail.
        let _ = nodes.push(node);
    }
    nodes
}

/// The follower with the reference table and gains for the reference valve/cylinder,
/// built in place in the first law buffer.
#[cfg(feature = "console")]
pub fn boot_law() -> Result<crate::laws::LawRef, ProgramError> {
    let [law, _spare] = crate::laws::take().ok_or(ProgramError::Taken)?;
    law.configure(&follower_config())
        .map_err(ProgramError::Follower)?;
    law.rebuild_table_from_nodes(&reference_nodes(), &table_limits())
        .map_err(ProgramError::Table)?;
    Ok(law)
}
