//! The configuration the board boots with: runtime limits, the follower's gains and the
//! limits every table is validated against — `hydra_core::profile` (shared with the
//! host's bit-exact comparison in board-emu), with this board's DAC range.
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
use hydra_core::follower::FollowerConfig;
use hydra_core::profile;
use hydra_core::runtime::RuntimeCoeffs;
#[cfg(feature = "console")]
use hydra_core::table::Node;
use hydra_core::table::TableLimits;
#[cfg(feature = "console")]
use hydra_core::units::{Master, PosUm};

use crate::consts::{DAC_RANGE, SLAVES};

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

/// The runtime limits (`hydra_core::profile::runtime_config`), built.
pub fn runtime_coeffs() -> Result<RuntimeCoeffs<SLAVES>, ProgramError> {
    profile::runtime_config()
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

/// The limits every table is validated against (`hydra_core::profile::table_limits`).
pub fn table_limits() -> TableLimits<SLAVES> {
    profile::table_limits()
}

/// The follower's configuration (`hydra_core::profile::follower_config`) with this
/// board's DAC range as the law's output clamp (its integrator then sees the real limit).
pub fn follower_config() -> FollowerConfig<SLAVES> {
    profile::follower_config(DAC_RANGE.max_code().unsigned_abs())
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
pub fn boot_law() -> Result<crate::law_buffers::LawRef, ProgramError> {
    let [law, _spare] = crate::law_buffers::take().ok_or(ProgramError::Taken)?;
    law.configure(&follower_config())
        .map_err(ProgramError::Follower)?;
    law.rebuild_table_from_nodes(&reference_nodes(), &table_limits())
        .map_err(ProgramError::Table)?;
    Ok(law)
}
