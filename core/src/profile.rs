//! The reference board's profile and program: what the STM32F407 valve-controller board
//! (`firmware/`) runs, in one place, so the host (board-emu's bit-exact comparison, the
//! virtual board, host-side checks) builds exactly the same runtime.
//!
//! | item | value |
//! |---|---|
//! | slaves | [`SLAVES`] = 2 (DAC1 ch 1/2), [`PRESSURES`] = 4 chamber pressures |
//! | table rows | [`TABLE_NODES`] = 256 |
//! | period | [`PERIOD_US`] = 1000 µs (1 kHz) |
//! | analog supply | [`VDDA_MV`] = 3000 mV, DAC swing margin [`DAC_SWING_MARGIN_MV`] = 200 mV |
//! | gains | the reference machine's feed-forward set at 1 ms ([`follower_config`]) |
//! | limits | slaves 0 … 500 mm at ≤ 200 mm/s, master ≤ 10 °/s ([`table_limits`]) |

use crate::axis::{AxisConfig, ControlMode, PistonAreas, PositionGains};
use crate::dac::DacRange;
use crate::follower::FollowerConfig;
use crate::runtime::{ReferenceMode, RuntimeConfig};
use crate::table::{AxisLimits, TableLimits};
use crate::units::{MasterRate, PosUm, VelUmPerS};
use crate::valve::ValveCal;

/// Slave axes of the board (the on-chip DAC's two channels).
pub const SLAVES: usize = 2;
/// Pressure inputs: chambers A and B of each slave (slave k: inputs 2k, 2k + 1).
pub const PRESSURES: usize = 2 * SLAVES;
/// Table capacity, nodes.
pub const TABLE_NODES: usize = 256;
/// Control period, µs (1 kHz; 100 µs = 10 kHz is the fastest the runtime accepts).
pub const PERIOD_US: u32 = 1000;
/// The gain backoff's band of the shipped tuning, µm (`axis::backoff`; the 1 ms
/// feed-forward set of `host-sim/scenarios/tangent.toml` carries the same).
pub const OSC_BAND_UM: f32 = 4.0;
/// The feed-forward trim's time constant of the shipped tuning, s (`axis::ff_trim`; the
/// 1 ms feed-forward set of `host-sim/scenarios/tangent.toml` carries the same).
pub const FF_TRIM_TAU_S: f32 = 1.0;
/// Rows of the board's capture ring (`crate::runtime::capture`): 2.048 s of every tick at
/// [`PERIOD_US`], so 500 ms before a trigger and 1 500 ms after it fit with room (the
/// firmware keeps them in the F407's 64 KiB CCM RAM: 32 B per row for [`SLAVES`] = 2,
/// 65 536 B, the whole CCM).
pub const CAPTURE_ROWS: usize = 2048;
/// The board's analog supply (VDDA = VREF+), mV: 3.0 V, as on the STM32F4-Discovery.
pub const VDDA_MV: u32 = 3000;
/// How close to each rail the DAC's buffered output gets, mV (DS8626: ≈ 0.2 V).
pub const DAC_SWING_MARGIN_MV: u32 = 200;

/// The board's usable DAC range ([`VDDA_MV`] less [`DAC_SWING_MARGIN_MV`] at each rail);
/// `None` only if those two constants were inconsistent (a unit test checks they are not).
pub const fn dac_range() -> Option<DacRange> {
    match DacRange::new(VDDA_MV, DAC_SWING_MARGIN_MV) {
        Ok(r) => Some(r),
        Err(_) => None,
    }
}

/// The runtime limits (reference machine defaults at [`PERIOD_US`]).
pub fn runtime_config() -> RuntimeConfig<SLAVES> {
    RuntimeConfig::<SLAVES> {
        period_us: PERIOD_US,
        // Incremental linear encoders: each slave is referenced (set-position or
        // homing to its index / reference input) before Start.
        slave_reference: [ReferenceMode::Incremental; SLAVES],
        // The reference marks of the reference machine's cylinders sit at 20 mm (the
        // default of the setting `axis/<n>/reference/home_um`).
        home_position_um: [20_000.0; SLAVES],
        // No force axis on this board's law: stale pressures are reported, not a fault.
        pressure_required: false,
        ..RuntimeConfig::default()
    }
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

/// The reference cylinder's piston areas (PLANT.md: bore 80 mm, rod 45 mm): A = π/4·80²
/// = 5 026.5 mm² on the piston side (chamber A), π/4·(80² − 45²) = 3 436.1 mm² on the
/// rod side (B).
pub fn piston_areas() -> PistonAreas {
    PistonAreas {
        area_a_mm2: 5026.5,
        area_b_mm2: 3436.1,
    }
}

/// The follower's configuration on every slave: the reference machine's feed-forward
/// gain set at 1 ms (`host-sim/scenarios/tangent.toml`, `[[tuning]]` controller
/// `feedforward`, `period_us = 1000`: the set `host-sim run` uses), so the board runs
/// what the simulator measured (hand-set gains such as kp 0.4, ki 5, i_limit 100 LSB lag
/// 0.5 mm on the retraction of the firmware in board-emu).
/// `clamp_lsb`: the law's output clamp, the board's usable DAC range
/// (`DacRange::max_code`), so it never commands a code the pin cannot follow.
pub fn follower_config(clamp_lsb: u16) -> FollowerConfig<SLAVES> {
    let axis = AxisConfig {
        gains: PositionGains {
            kp_lsb_per_um: 1.1,
            ki_lsb_per_um_s: 18.0,
            kd_lsb_s_per_um: 0.0,
            i_zone_um: 10_000.0,
            i_limit_lsb: 630.0,
            kv_pos_lsb_per_um_s: 0.01389,
            kv_neg_lsb_per_um_s: 0.01683,
            ka_lsb_per_um_s2: 0.0,
            valve_lag_us: 4244.0,
            following_error_um: 5000.0,
            dp_gain_lsb_per_kn: 0.0,
            dp_corner_hz: 5.0,
            osc_band_um: OSC_BAND_UM,
            ff_trim_tau_s: FF_TRIM_TAU_S,
            backoff: crate::axis::BackoffSettings::DEFAULT,
        },
        mode: ControlMode::Feedforward,
        valve: ValveCal {
            clamp_lsb,
            ..ValveCal::default()
        },
        areas: piston_areas(),
    };
    FollowerConfig::<SLAVES> {
        period_us: PERIOD_US,
        axes: [axis; SLAVES],
        ..FollowerConfig::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dac_range_is_consistent() {
        let r = dac_range().map(|r| r.max_code());
        // (1500 − 200) mV of 1500 mV half-scale → ±1774 codes.
        assert_eq!(r, Some(1774));
    }
}
