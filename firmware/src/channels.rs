//! The channels between the tick and the host link, in one leaf module both use: the
//! message types, the lock-free queues' ends each side holds, the tick's reply signal
//! and the command timing both sides agree on. (The queues themselves are statics of
//! `main.rs`, which splits them between the two.)

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use heapless::spsc::{Consumer, Producer};
use hydra_core::runtime::Status;

use crate::consts::{PRESSURES, SLAVES};

pub use hydra_core::runtime::{Reply, TickCommand};

/// The status snapshot of this board.
pub type BoardStatus = Status<SLAVES, PRESSURES>;
/// One tick's telemetry sample of this board.
pub type TickSample = hydra_core::runtime::TickSample<SLAVES>;

/// The capture ring of this board.
pub type BoardCapture = hydra_core::runtime::Capture<'static, SLAVES>;

/// How long the link's `LinkIo::command_wait` waits for the tick's answer, ms (10 periods at
/// 1 kHz; the tick drops a command older than this less one period unapplied,
/// [`COMMAND_MAX_AGE_US`]).
pub const COMMAND_WAIT_MS: u32 = 10;

/// Age beyond which a queued command is dropped unapplied, µs: the link's wait for an
/// answer ([`COMMAND_WAIT_MS`]) less one period, so a command whose wait
/// timed out can never take effect later (e.g. a Start after a flash erase).
pub const COMMAND_MAX_AGE_US: u32 = COMMAND_WAIT_MS * 1000 - crate::consts::PERIOD_US;

/// The tick's latest answer, with the token of the command it answers (the tick signals
/// every reply; the link's `LinkIo::command_wait` waits on it).
pub static REPLY: Signal<CriticalSectionRawMutex, Reply> = Signal::new();

/// The channels between the tick and the host link.
pub struct TickLinks {
    /// Commands in.
    pub cmd_rx: Consumer<'static, TickCommand>,
    /// Replies out.
    pub reply_tx: Producer<'static, Reply>,
    /// Status snapshots out.
    pub status_tx: Producer<'static, BoardStatus>,
    /// Per-tick telemetry samples out.
    pub sample_tx: Producer<'static, TickSample>,
    /// The capture ring.
    pub capture: BoardCapture,
}

/// The link's channels to the tick.
pub struct LinkChannels {
    /// Commands to the tick.
    pub cmd_tx: Producer<'static, TickCommand>,
    /// Replies from the tick.
    pub reply_rx: Consumer<'static, Reply>,
    /// Status snapshots from the tick.
    pub status_rx: Consumer<'static, BoardStatus>,
    /// Per-tick samples from the tick.
    pub sample_rx: Consumer<'static, TickSample>,
}
