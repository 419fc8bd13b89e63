//! The board's constants, in one leaf module every other one may use: how many slaves
//! and pressure inputs, the table capacity, the control period, the core clock, the
//! valve DAC's usable range, the valve-power enable pin and the control law's type.
//! Nothing here depends on another firmware module.

use embassy_stm32::pac;
use hydra_core::dac::DacRange;
use hydra_core::follower::Follower;
use hydra_core::profile;

/// Slave axes driven by this board (the on-chip DAC's two channels).
pub const SLAVES: usize = hydra_core::profile::SLAVES;
/// Pressure channels.
pub const PRESSURES: usize = hydra_core::profile::PRESSURES;

/// Table capacity (nodes).
pub const TABLE_NODES: usize = profile::TABLE_NODES;
/// The control law of this board.
pub type Law = Follower<SLAVES, TABLE_NODES>;
/// Control period, µs (`hydra_core::profile::PERIOD_US`).
pub const PERIOD_US: u32 = profile::PERIOD_US;

/// The valve-power enable's port and pin (PE7), for the panic handler's direct write.
pub const ENABLE_PORT: pac::gpio::Gpio = pac::GPIOE;
/// See [`ENABLE_PORT`].
pub const ENABLE_PIN: usize = 7;

/// The usable valve-DAC code range on this board (`hydra_core::profile::dac_range`: the
/// analog supply VDDA = 3.0 V, as on the STM32F4-Discovery — the valve amplifiers' null
/// must be set to VDDA/2 = 1.500 V — less the buffered output's 0.2 V swing margin at
/// each rail): ±1774 LSB around mid-scale (273 codes lost at each end). Every code written is clamped to it (`crate::valves`), and the
/// valve calibration's clamp is set to it (`crate::boot_config`).
pub const DAC_RANGE: DacRange = match hydra_core::profile::dac_range() {
    Some(r) => r,
    None => panic!("hydra_core::profile::VDDA_MV / DAC_SWING_MARGIN_MV"),
};

/// Core clock, Hz (DWT cycles per second).
pub const SYSCLK_HZ: u32 = 168_000_000;
