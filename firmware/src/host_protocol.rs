//! The framed protocol (`PROTOCOL.md`) on the host link: the same
//! `hydra_core::protocol::Handler` the virtual board (`host-sim serve --pty`) runs,
//! behind the link task's [`LinkProtocol`] slot.
//!
//! | handler entry point | called from |
//! |---|---|
//! | `Handler::boot` | [`Framed::boot`], in `main` before the tick starts: the newest valid flash slot becomes the boot law |
//! | `Handler::on_bytes` | [`LinkProtocol::on_rx`], each chunk of the RX DMA ring |
//! | `Handler::poll` | [`LinkProtocol::on_wake`], every wake-up of the link task (≤ 10 ms): an armed activation is installed at the next safe point |
//! | `Handler::on_tick` | [`LinkProtocol::on_sample`], once per tick sample queued by the tick (telemetry every `decimation` samples) |
//!
//! The handler's output frames are collected whole and queued for the UART's DMA write;
//! a frame that does not fit the batch is dropped whole (the host times out and
//! retries with the same seq, which the handler answers `Duplicate` if it was done).

use heapless::Vec;
use hydra_core::protocol::msg::Telemetry;
use hydra_core::protocol::{Handler, SlotHeader, Store, StoreError};
use static_cell::ConstStaticCell;

use crate::channels::{BoardStatus, Reply, TickSample};
use crate::consts::SLAVES;
use crate::consts::TABLE_NODES;
use crate::device::{device_state, Dev, DeviceState, FwGlue};
use crate::flash::{SlotFlash, SLOT0_OFFSET, SLOT_BYTES};
use crate::link::{LinkIo, LinkProtocol};
use hydra_core::protocol::BoardDevice;

/// Output bytes one `on_rx` call may produce (a 64-byte chunk of garbage yields at most
/// 64 Nak frames of 15 wire bytes).
const TX_LEN: usize = 1024;

/// The protocol handler with its staging and committed tables (≈ 17 KiB): a static,
/// all-zero at link time (`.bss`), never built on the stack.
static HANDLER: ConstStaticCell<Handler<SLAVES, TABLE_NODES>> =
    ConstStaticCell::new(Handler::new(Store::UNATTACHED));

/// Why the framed protocol could not start.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum FramedError {
    /// The flash slots' geometry.
    Store(StoreError),
    /// [`Framed::new`] called twice (its static buffers are taken once).
    Taken,
}

/// The framed protocol's state: handler, flash and the device's link-side state (small:
/// the tables are statics it points to).
pub struct Framed {
    handler: &'static mut Handler<SLAVES, TABLE_NODES>,
    flash: SlotFlash,
    /// Gains, limits, the copy of the active table and the free law buffers.
    pub dev: DeviceState,
    tx: Vec<u8, TX_LEN>,
}

impl Framed {
    /// The handler on the two slots of `flash` (sectors 10 and 11).
    pub fn new(flash: SlotFlash) -> Result<Self, FramedError> {
        let store = Store::new::<_, SLAVES, TABLE_NODES>(&flash, SLOT0_OFFSET, SLOT_BYTES)
            .map_err(FramedError::Store)?;
        let handler = HANDLER.try_take().ok_or(FramedError::Taken)?;
        handler.set_store(store);
        Ok(Self {
            handler,
            flash,
            dev: device_state().ok_or(FramedError::Taken)?,
            tx: Vec::new(),
        })
    }

    /// Loads the newest valid slot and builds its law in place (call before the tick
    /// starts; then build the runtime with `DeviceState::start`).
    pub fn boot(&mut self) -> Option<SlotHeader> {
        let mut glue = FwGlue { io: None };
        let mut dev: Dev<'_, '_> = BoardDevice {
            st: &mut self.dev,
            glue: &mut glue,
        };
        self.handler.boot(&mut dev, &mut self.flash)
    }

    fn flush(&mut self, io: &mut LinkIo<'_>) {
        if !self.tx.is_empty() && !io.send_whole(&self.tx) {
            defmt::warn!("host link: {} output bytes dropped", self.tx.len());
        }
        self.tx.clear();
    }
}

/// Appends a whole frame or nothing.
fn push_frame(tx: &mut Vec<u8, TX_LEN>, frame: &[u8]) {
    if tx.extend_from_slice(frame).is_err() {
        defmt::warn!("host link: frame of {} bytes dropped", frame.len());
    }
}

impl LinkProtocol for Framed {
    fn on_rx(&mut self, bytes: &[u8], io: &mut LinkIo<'_>) {
        let mut glue = FwGlue { io: Some(&mut *io) };
        let mut dev: Dev<'_, '_> = BoardDevice {
            st: &mut self.dev,
            glue: &mut glue,
        };
        let tx = &mut self.tx;
        self.handler
            .on_bytes(&mut dev, &mut self.flash, bytes, &mut |f| push_frame(tx, f));
        self.flush(io);
    }

    fn on_reply(&mut self, _reply: Reply, _io: &mut LinkIo<'_>) {
        // Every command is answered inside `on_rx` (`LinkIo::command_wait`); a reply
        // arriving later belongs to a command that timed out and was already Nak'd.
    }

    fn on_state_change(&mut self, _status: &BoardStatus, _io: &mut LinkIo<'_>) {
        // The host polls Status; state changes are logged over defmt by the link task.
    }

    fn on_wake(&mut self, io: &mut LinkIo<'_>) {
        let mut glue = FwGlue { io: Some(&mut *io) };
        let mut dev: Dev<'_, '_> = BoardDevice {
            st: &mut self.dev,
            glue: &mut glue,
        };
        if let Err(e) = self.handler.poll(&mut dev) {
            defmt::warn!("deferred activation refused: {}", e);
        }
        // The host-link watchdog (off unless `LinkTimeoutMs` is set).
        let now_ms = embassy_time::Instant::now().as_millis() as u32;
        if self.handler.watch_link(&mut dev, now_ms) {
            defmt::warn!("host link silent while following: axes held");
        }
    }

    fn on_sample(&mut self, sample: &TickSample, io: &mut LinkIo<'_>) {
        let tx = &mut self.tx;
        self.handler
            .on_tick(&mut |f| push_frame(tx, f), || Telemetry::of_sample(sample));
        self.flush(io);
    }
}
