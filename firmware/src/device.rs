//! The board as the protocol handler sees it: core's one `Device`
//! (`hydra_core::protocol::device`, the same adapter the host's virtual board uses) with
//! this board's glue ([`FwGlue`]).
//!
//! The runtime lives in the tick (priority 0); this side runs in the thread-mode link
//! task. Reads (state, status, safe point) and law installs go through
//! [`crate::tick::with_runtime`], a short critical section. Motion commands go through
//! the tick's command queue and are answered after the tick that applied them
//! ([`LinkIo::command_wait`]), so a command never races the tick. A law installed
//! publishes its valve nulls for the panic handler ([`ValveBank::publish_safe_codes`]).
//!
//! The law buffers are the two statics of `crate::law_buffers`, the copy of the active table a
//! third static ([`ACTIVE`]): no law or table is moved by value, every frame of this
//! module is small (the CI's stack check, `scripts/stack-check.py`).

use hydra_core::protocol::device::{BoardDevice, DeviceGlue, LawDevice};
use hydra_core::runtime::{Command, CommandError};
use hydra_core::table::CamTable;
use hydra_core::units::DacCode;

use crate::consts::TABLE_NODES;
use crate::consts::{PRESSURES, SLAVES, SYSCLK_HZ};
use crate::law_buffers::{self, LawRef};
use crate::link::LinkIo;
use crate::tick::{self, BoardRuntime};
use crate::valves::ValveBank;
use static_cell::ConstStaticCell;

/// The board's table type.
pub type Table = CamTable<SLAVES, TABLE_NODES>;

const fn parse_u8(s: &str) -> u8 {
    let b = s.as_bytes();
    let mut v: u8 = 0;
    let mut i = 0;
    while i < b.len() {
        v = v
            .saturating_mul(10)
            .saturating_add(b[i].saturating_sub(b'0'));
        i += 1;
    }
    v
}

/// Firmware version reported by Info (the crate's version).
pub const FIRMWARE: [u8; 3] = [
    parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
];

/// The link side's copy of the running law's table: a static buffer (all-zero start,
/// `.bss`), rewritten in place at each installation.
static ACTIVE: ConstStaticCell<Table> = ConstStaticCell::new(Table::empty());

/// What the link side keeps about the machine (core's [`LawDevice`] over this board's
/// static buffers): gains, limits, the copy of the active table, the free law buffers.
pub type DeviceState = LawDevice<LawRef, &'static mut Table, SLAVES, TABLE_NODES>;

/// The handler's device for one call.
pub type Dev<'a, 'b> =
    BoardDevice<'a, LawRef, &'static mut Table, FwGlue<'a, 'b>, SLAVES, TABLE_NODES, PRESSURES>;

/// The boot configuration (`crate::boot_config`), no table, both law buffers free. `None` if
/// called twice (the static buffers are taken once).
pub fn device_state() -> Option<DeviceState> {
    let laws = law_buffers::take()?;
    Some(LawDevice::new(
        crate::boot_config::follower_config(),
        crate::boot_config::table_limits(),
        ACTIVE.try_take()?,
        laws,
        FIRMWARE,
    ))
}

/// This board's glue: the tick's runtime behind a critical section, the link's command
/// queue (`None` at boot, before the link runs: commands are then refused).
pub struct FwGlue<'a, 'b> {
    /// The link's queues to the tick.
    pub io: Option<&'a mut LinkIo<'b>>,
}

impl DeviceGlue<LawRef, SLAVES, PRESSURES> for FwGlue<'_, '_> {
    fn read<R>(&self, f: impl FnOnce(&BoardRuntime) -> R) -> Option<R> {
        tick::with_runtime(|rt| f(rt))
    }
    fn write<R>(&mut self, f: impl FnOnce(&mut BoardRuntime) -> R) -> Option<R> {
        tick::with_runtime(f)
    }
    fn command(&mut self, cmd: Command) -> Option<Result<(), CommandError>> {
        let r = self.io.as_mut()?.command_wait(cmd);
        if let Some(Err(e)) = r {
            defmt::info!("command {} refused: {}", cmd, e);
        }
        r
    }
    fn publish_nulls(nulls: &[DacCode; SLAVES]) {
        ValveBank::publish_safe_codes(nulls);
    }
    fn cycles_to_ns(&self, c: u32) -> u32 {
        let ns = u64::from(c).saturating_mul(1_000_000_000) / u64::from(SYSCLK_HZ);
        u32::try_from(ns).unwrap_or(u32::MAX)
    }
    fn capture<R>(
        &mut self,
        f: impl FnOnce(&mut hydra_core::runtime::Capture<'_, SLAVES>) -> R,
    ) -> Option<R> {
        tick::with_capture(|c| f(c))
    }
}
