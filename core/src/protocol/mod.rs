//! The UART protocol: table upload, commands, status and telemetry.
//!
//! Layers, bottom up (byte-by-byte description in `PROTOCOL.md`):
//!
//! - [`frame`]: `COBS(seq · type · payload · crc32) 0x00` (COBS and CRC-32 from the `cobs`
//!   and `crc` crates; the CRC also of tables and flash slots), the streaming
//!   [`frame::FrameDecoder`];
//! - [`wire`]: little-endian field reader/writer;
//! - [`msg`]: requests, responses, typed [`msg::NakCode`]s;
//! - [`settings`]: the settings tree — every parameter's path, unit and range;
//! - [`store`]: two flash slots (table + [`overrides`], the changed parameters) through
//!   the `embedded-storage` NorFlash traits;
//! - [`upload`]: the request sequence of a table upload (every host's);
//! - [`report`]: the runtime's status as Status reports it (shared by every device);
//! - [`handler`]: the board's state machine ([`handler::Handler`]) behind the
//!   [`handler::Device`] seam;
//! - `ramflash` (host only): an F407-like NOR flash in RAM (sector erase, word program,
//!   half-done operations and weak cells at a power cut), for tests and the virtual board.
//!
//! Firmware glue: construct `Handler::new(Store::new(&flash, base, slot)?)`, call
//! `boot` once, then from the low-priority UART task `on_bytes(dev, flash, rx, tx)` with
//! each DMA chunk, `poll(dev)` every loop, and `on_tick(tx, sample)` for telemetry.

pub mod device;
pub mod diag;
pub mod frame;
pub mod handler;
mod handler_plc;
pub mod msg;
pub mod overrides;
pub mod params;
#[cfg(any(test, feature = "std"))]
#[allow(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation
)]
pub mod ramflash;
pub mod report;
pub mod settings;
pub mod store;
pub mod upload;
pub mod wire;

pub use device::{BoardDevice, DeviceGlue, LawBuffer, LawDevice};
pub use handler::{BootReason, Device, Handler, Motion};
pub use handler_plc::needs_owner;
pub use msg::{Nak, NakCode, ParamId, Request, Response};
pub use overrides::{ParamOverrides, ParamRecord};
pub use params::{
    apply_param, apply_param_set, apply_saved_set, home_um, read_param, reference_offset_um,
    um_per_count, validate_params, SlaveRefs,
};
pub use store::{SlotHeader, Store, StoreError};

#[cfg(test)]
mod golden_tests;
#[cfg(test)]
mod handler_tests;
#[cfg(test)]
mod plc_tests;
#[cfg(test)]
mod powercut_tests;
