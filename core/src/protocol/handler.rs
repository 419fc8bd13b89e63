//! The board side: bytes in, frames out, one request at a time.
//!
//! ```text
//! UART RX bytes ──► FrameDecoder ──► seq check ──► Request::decode ──► dispatch ──► Ack/Nak/Info/Status ──► tx
//!                                                       │
//!                       staging bank (upload) ─Commit─► committed bank ─Activate (safe point)─► Device
//!                                                                                  Save ──► Store (2 flash slots)
//! ```
//!
//! Rules (every one is a test in `handler_tests.rs`):
//! - A frame that is not valid (COBS, length, CRC) gets `Nak` with `seq` 0xFFFF and
//!   `req` 0: the sender's seq cannot be trusted.
//! - `Hello` is accepted with any `seq` and opens a session; after it the next request
//!   must carry `seq + 1` (wrapping). Repeating the last accepted `seq` is `Duplicate`
//!   (the request was done; it is not done twice), any other `seq` is `OutOfOrder`.
//! - Only a positive answer (Ack, Info, Status) advances the expected `seq`; after a Nak
//!   the host may retry with the same `seq`. A Nak means nothing changed.
//! - An upload fills the staging bank only; the active table keeps running.
//!   `TableCommit` checks the whole-table CRC and the [`CamTable`] rules and moves the
//!   table to the committed bank; `Activate(id)` installs it at once if the device is at
//!   a safe point (idle, or the running table has ended), otherwise it is armed
//!   (Ack flag bit 0) and [`Handler::poll`] installs it at the next safe point.
//! - `Save` needs every axis idle (erasing a sector stalls the CPU for up to 2 s on the
//!   single-bank STM32F4, so never while a table runs) and writes the older slot: the
//!   active table and every parameter changed by SetParam since boot (boot applies them
//!   again before it validates the table).

use super::diag::{
    trigger_from_wire, CaptureMsg, FaultEventMsg, FaultsMsg, LinkStats, MasterStateMsg,
};
use super::frame::{self, FrameDecoder, FrameError, MAX_PAYLOAD, MAX_WIRE};
use super::frame::{Crc32, CRC32};
use super::msg::{
    read_row, row_len, ty, Info, Nak, NakCode, ParamId, Request, Response, StatusMsg, Telemetry,
    FLAG_LINK_LOST, FLAG_PRESSURE_STALE, FLAG_UNREFERENCED, NO_TABLE, PROTOCOL_VERSION,
};
use super::overrides::ParamOverrides;
use super::store::{SlotHeader, Store};
use crate::runtime::{Trigger, FAULT_HISTORY_LEN};
use crate::table::{CamTable, Node, TableLimits};
use embedded_storage::nor_flash::NorFlash;
use heapless::Vec;

/// A motion command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Motion {
    /// Idle → Following.
    Start,
    /// → Idle.
    Stop,
    /// Following → Holding.
    Hold,
    /// Clear a latched fault.
    ClearFault,
    /// Set-position: slave `axis` is at `pos_um` (Idle or Fault).
    SetPosition {
        /// Slave axis.
        axis: u8,
        /// Where it is, µm.
        pos_um: crate::units::PosUm,
    },
    /// Arm homing of slave `axis` (Idle or Fault).
    Home {
        /// Slave axis.
        axis: u8,
    },
    /// Jog slave `axis` at `speed` (Idle or Manual; renews the deadman).
    Jog {
        /// Slave axis.
        axis: u8,
        /// Target speed, µm/s.
        speed: crate::units::VelUmPerS,
        /// Acceleration and jerk.
        limits: crate::runtime::MotionLimits,
    },
    /// Move slave `axis` to `to` by the S-curve (Idle or Manual, at rest, referenced).
    MoveTo {
        /// Slave axis.
        axis: u8,
        /// Target, µm.
        to: crate::units::PosUm,
        /// Velocity, acceleration and jerk limits.
        limits: crate::runtime::MotionLimits,
    },
    /// Move every slave to the table at the present master, then follow.
    Approach {
        /// Velocity, acceleration and jerk limits.
        limits: crate::runtime::MotionLimits,
    },
    /// The identification test move on slave `axis` (Idle or Manual, at rest,
    /// referenced).
    Test {
        /// Slave axis.
        axis: u8,
        /// The test.
        spec: crate::runtime::TestSpec,
    },
}

/// What the handler needs from the machine it controls: the runtime on the board, the
/// virtual board on the host. The seam between protocol and control.
pub trait Device<const S: usize, const N: usize> {
    /// Firmware version (major, minor, patch).
    fn firmware(&self) -> [u8; 3];
    /// Control period, µs.
    fn period_us(&self) -> u32;
    /// Limits a table is validated against.
    fn table_limits(&self) -> TableLimits<S>;
    /// Law buffers (Info): 2 where a new law is built beside the running one.
    fn law_buffers(&self) -> u8 {
        1
    }
    /// The running table, if any.
    fn active_table(&self) -> Option<&CamTable<S, N>>;
    /// Idle, or the running table has ended: a table may be swapped now.
    fn at_safe_point(&self) -> bool;
    /// Every axis idle (valves at null, not following).
    fn all_idle(&self) -> bool;
    /// In `Manual` with every slave holding (no jog, move, test or approach running):
    /// nothing a lost host could leave running. Default: never.
    fn manual_at_rest(&self) -> bool {
        false
    }
    /// Installs a copy of `table` (only called at a safe point). Errors:
    /// [`NakCode::Refused`] if the device cannot run it; what runs is then unchanged.
    /// By reference: a table is 12 KiB on the board, and no table is ever moved by value
    /// (the device copies it into its own buffer in place, [`CamTable::copy_from`]).
    fn install_table(&mut self, table: &CamTable<S, N>) -> Result<(), Nak>;
    /// Start / Stop / Hold / ClearFault.
    fn command(&mut self, m: Motion) -> Result<(), Nak>;
    /// Sets one parameter (validated; typed error).
    fn set_param(&mut self, axis: u8, param: ParamId, value: f32) -> Result<(), Nak>;
    /// The value of one parameter in force (every id but [`ParamId::LinkTimeoutMs`],
    /// which the handler holds), in its unit; `UnknownParam` for a slave it does not have.
    fn get_param(&self, axis: u8, param: ParamId) -> Result<f32, Nak>;
    /// Applies a saved set of parameters at boot, **as one validated set**: all of them,
    /// or none ([`super::params::apply_param_set`]: the order they were first set in does
    /// not matter; [`ParamId::LinkTimeoutMs`] is the handler's and is skipped). Only
    /// called while no table is installed. The default sets them one
    /// by one and stops at the first refusal — the handler then undoes everything with
    /// [`Device::reset_params`] — which is order-dependent: a device overrides it.
    fn set_params(&mut self, records: &[super::ParamRecord]) -> Result<(), Nak> {
        for r in records.iter().filter(|r| !r.param.held_by_handler()) {
            self.set_param(r.axis, r.param, r.value)?;
        }
        Ok(())
    }
    /// Restores every parameter [`Device::set_param`] can change to the board's boot
    /// configuration. [`Handler::boot`] calls it when a slot's table is refused, before
    /// it tries the older slot, so no parameter of a refused slot stays applied. Only
    /// needed (and only allowed) while no table is installed: otherwise
    /// [`NakCode::NotIdle`] and nothing changes.
    fn reset_params(&mut self) -> Result<(), Nak>;
    /// Fills state, faults, timing, master and per-axis fields of a status.
    fn status(&self, out: &mut StatusMsg);
    /// The reference offset of slave `axis` if it is absolute (worth persisting, see
    /// [`ParamId::SlaveOffsetUm`]), µm; `None` for an incremental axis.
    fn persisted_offset_um(&self, _axis: u8) -> Option<f32> {
        None
    }
    /// The fault history, oldest first (default: the device keeps none).
    fn fault_history(&self, _out: &mut heapless::Vec<FaultEventMsg, FAULT_HISTORY_LEN>) {}
    /// Arms the loop-rate capture. Default: the device keeps no capture ring
    /// ([`NakCode::CaptureTrigger`]).
    fn capture_arm(&mut self, _trigger: Trigger, _pre: u32, _post: u32) -> Result<(), Nak> {
        Err(Nak::new(NakCode::CaptureTrigger))
    }
    /// The capture's state and up to `count` rows from `offset` (whole rows that fit
    /// [`super::diag::CAPTURE_DATA_MAX`]). Default: never armed, no ring.
    fn capture_read(&mut self, _offset: u32, _count: u8, _out: &mut CaptureMsg) {}
    /// A test board's simulated master ([`super::diag::master_op`]). Default: the master
    /// is a real encoder ([`NakCode::NoVirtualMaster`]).
    fn virtual_master(&mut self, op: u8, _speed_scale: f32) -> Result<MasterStateMsg, Nak> {
        Err(Nak::with(NakCode::NoVirtualMaster, u16::from(op), 0))
    }
}

/// A host-link timeout from its SetParam value: 0 (off) or 10 … 60 000 whole ms, else
/// `ParamRange` naming [`ParamId::LinkTimeoutMs`].
fn link_timeout_ms(value: f32) -> Result<u32, Nak> {
    let ok = value == 0.0 || (10.0..=60_000.0).contains(&value);
    let whole = ParamId::LinkTimeoutMs.check(0, value).is_ok();
    if !ok || !whole {
        return Err(Nak::with(
            NakCode::ParamRange,
            0,
            ParamId::LinkTimeoutMs as u8,
        ));
    }
    // A whole number in 0 … 60 000: the cast is exact.
    Ok(value as u32)
}

/// Why the board booted what it booted (`Status.boot_reason`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum BootReason {
    /// No flash slot held a save (never saved, or no slot's header reads as a complete
    /// save): the boot configuration runs, no table.
    #[default]
    NoSave = 0,
    /// The newest complete save booted (its table and settings, or its settings alone).
    Newest = 1,
    /// The newest slot's rows did not read back (CRC): the previous complete save booted.
    FallbackUnreadable = 2,
    /// The newest slot's settings were refused as a set: the previous save booted.
    FallbackSettings = 3,
    /// The newest slot's table breaks the rules under its own settings: the previous
    /// save booted.
    FallbackTable = 4,
    /// Every saved slot was refused: the boot configuration runs, no table.
    NoneBootable = 5,
}

impl BootReason {
    /// From the wire byte.
    pub fn from_u8(b: u8) -> Option<Self> {
        use BootReason::*;
        [
            NoSave,
            Newest,
            FallbackUnreadable,
            FallbackSettings,
            FallbackTable,
            NoneBootable,
        ]
        .into_iter()
        .find(|r| *r as u8 == b)
    }
}

/// An upload in progress.
#[derive(Clone)]
struct Upload {
    id: u32,
    rows: u16,
    crc: Crc32,
}

impl core::fmt::Debug for Upload {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // The running CRC (the crate's digest) has no Debug.
        f.debug_struct("Upload")
            .field("id", &self.id)
            .field("rows", &self.rows)
            .finish_non_exhaustive()
    }
}

/// The protocol handler: one per serial port.
#[derive(Clone, Debug)]
pub struct Handler<const S: usize, const N: usize> {
    dec: FrameDecoder,
    store: Store,
    session: bool,
    last_seq: u16,
    upload: Option<Upload>,
    staging: Vec<Node<S>, N>,
    /// The committed table's buffer, rebuilt in place at each Commit (and used by
    /// [`Handler::boot`] to build a slot's table); `committed_id` says whether it holds a
    /// committed table.
    committed: CamTable<S, N>,
    committed_id: Option<u32>,
    pending: bool,
    /// The active table's id (`None`: no table; all-zero, so a static handler is `.bss`).
    active_id: Option<u32>,
    /// The active table's CRC-32 (Status), worked out once when it is installed.
    active_crc: u32,
    saved: Option<SlotHeader>,
    /// The slot [`Handler::boot`] booted, and why.
    boot_slot: Option<u8>,
    boot_reason: BootReason,
    /// SetParams accepted since boot (plus those boot applied): what Save stores.
    overrides: ParamOverrides,
    decimation: u16,
    tick_count: u16,
    tel_seq: u16,
    /// Host-link watchdog ([`ParamId::LinkTimeoutMs`], 0 = off).
    link: LinkWatch,
    /// The PLC link's settings (`plc/…`, `axis/<n>/in_position_um`).
    pub(super) plc: crate::plc::PlcSettings<S>,
    /// Who moves the machine (`crate::plc::owner`).
    pub(super) owner: crate::plc::Ownership,
    /// The PLC's heartbeat is lost (the PLC server reports it): an owning PLC has timed
    /// out.
    pub(super) plc_lost: bool,
}

/// The host-link watchdog's state (see [`Handler::watch_link`]).
#[derive(Clone, Copy, Debug, Default)]
struct LinkWatch {
    timeout_ms: u32,
    /// Valid frames received (wrapping), and the count at the last watch.
    frames: u32,
    /// Frames that failed COBS, length or CRC checks (wrapping).
    bad_frames: u32,
    /// Requests (whole frames) answered with a Nak (wrapping; a damaged frame's Nak is
    /// counted in `bad_frames` only).
    naks: u32,
    seen: u32,
    last_ms: u32,
    /// A Start from this link is in force (cleared by Stop, Hold, a trip).
    host_started: bool,
    /// Tripped since the last Start ([`super::msg::FLAG_LINK_LOST`]).
    lost: bool,
}

/// Ack flag: Activate armed for the next safe point.
pub const ACK_DEFERRED: u8 = 1;

impl<const S: usize, const N: usize> Handler<S, N> {
    /// Most rows one chunk can carry: (payload − 3-byte chunk header) / row length, ≤ 255.
    pub const MAX_CHUNK_ROWS: usize = {
        let r = (MAX_PAYLOAD - 3) / row_len(S);
        if r > 255 {
            255
        } else {
            r
        }
    };

    /// A handler using `store`; call [`Handler::boot`] once at power-up. `const`: a
    /// handler (18 384 B with the board's 2 × 256-row buffers, `llvm-nm` of the firmware) can be a static initialised at
    /// link time.
    pub const fn new(store: Store) -> Self {
        Self {
            dec: FrameDecoder::new(),
            store,
            session: false,
            last_seq: 0,
            upload: None,
            staging: Vec::new(),
            committed: CamTable::empty(),
            committed_id: None,
            pending: false,
            active_id: None,
            active_crc: 0,
            saved: None,
            boot_slot: None,
            boot_reason: BootReason::NoSave,
            overrides: ParamOverrides::new(),
            decimation: 0,
            tick_count: 0,
            tel_seq: 0,
            link: LinkWatch {
                timeout_ms: 0,
                frames: 0,
                bad_frames: 0,
                naks: 0,
                seen: 0,
                last_ms: 0,
                host_started: false,
                lost: false,
            },
            plc: crate::plc::PlcSettings::DEFAULT,
            owner: crate::plc::Ownership::NONE,
            plc_lost: false,
        }
    }

    /// The host-link watchdog; call every few ms (the firmware's link task: every
    /// wake-up, ≤ 10 ms) with a millisecond clock (wrapping). If
    /// [`ParamId::LinkTimeoutMs`] is set and the axes follow after a Start (or an
    /// Approach, or run a TestMove) from this link,
    /// no valid frame for that long holds them (`Motion::Hold`: the slaves hold the
    /// table position of the frozen master; valves stay powered and controlled) and
    /// sets [`super::msg::FLAG_LINK_LOST`] until the next Start. Returns whether it
    /// tripped now.
    pub fn watch_link<D: Device<S, N>>(&mut self, dev: &mut D, now_ms: u32) -> bool {
        let w = &mut self.link;
        if w.frames != w.seen {
            w.seen = w.frames;
            w.last_ms = now_ms;
            return false;
        }
        if w.timeout_ms == 0 || !w.host_started || now_ms.wrapping_sub(w.last_ms) < w.timeout_ms {
            return false;
        }
        if dev.all_idle() || dev.manual_at_rest() {
            // Nothing left running for the watch (a test that ended holds in Manual).
            w.host_started = false;
            return false;
        }
        // Only a Hold the device took ends the watch; a refused or unanswered one is
        // tried again at the next call (Status does not claim a hold that did not happen).
        let held = dev.command(Motion::Hold).is_ok();
        if held {
            self.link.host_started = false;
            self.link.lost = true;
        }
        held
    }

    /// The host-link watchdog held the axes since the host's last Start: an owning host
    /// has timed out.
    pub(super) fn link_lost(&self) -> bool {
        self.link.lost
    }

    /// Runs `f` (a request from another side than the serial host) without touching the
    /// host-link watchdog's view: a PLC's Start is not watched by the serial link.
    pub(super) fn with_link_kept<R>(&mut self, f: impl FnOnce(&mut Self) -> R) -> R {
        let (started, lost) = (self.link.host_started, self.link.lost);
        let r = f(self);
        self.link.host_started = started;
        self.link.lost = lost;
        r
    }

    fn set_link_timeout(&mut self, value: f32) -> Result<(), Nak> {
        self.link.timeout_ms = link_timeout_ms(value)?;
        Ok(())
    }

    /// Loads the newest valid flash slot: applies its parameters as one set
    /// ([`Device::set_params`]; a set refused as a whole refuses the slot), then installs
    /// its table if it passes the [`CamTable`] rules with the resulting limits; otherwise
    /// it undoes that slot's parameters ([`Device::reset_params`]) and tries the older slot
    /// the same way — a slot is a table *and* its parameters, never half of one. Returns
    /// the header of the slot that booted (`rows` 0: settings saved without a table, which
    /// apply with no table running; `None`: nothing booted, boot configuration — also if
    /// the device cannot undo a refused slot's parameters); [`Handler::boot_report`] says
    /// which and why. Finally the slot that
    /// booted is confirmed and a slot that did not read as valid is revoked
    /// ([`Store::confirm`], [`Store::revoke`]), so every later boot of this flash boots the
    /// same.
    pub fn boot<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
    ) -> Option<SlotHeader> {
        // Slots that did not read as valid at this boot (blank, cut or garbage).
        let mut invalid = [true; 2];
        let booted = self.boot_slots(dev, flash, &mut invalid);
        // What this boot read is what every later boot reads: the slot that booted has
        // its commit record programmed again, a slot that did not read as valid has it
        // programmed to zero (the store's module docs). A flash error here changes
        // nothing that booted.
        if let Some(h) = booted {
            let _ = self.store.confirm(flash, h.slot);
        }
        for (slot, bad) in (0u8..).zip(invalid) {
            if bad && booted.map(|h| h.slot) != Some(slot) {
                let _ = self.store.revoke(flash, slot);
            }
        }
        booted
    }

    fn boot_slots<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
        invalid: &mut [bool; 2],
    ) -> Option<SlotHeader> {
        let slots = self.store.newest_first::<F, S, N>(flash);
        for h in slots.iter().flatten() {
            if let Some(v) = invalid.get_mut(usize::from(h.slot)) {
                *v = false;
            }
        }
        // Why the newest slot did not boot (the reason a later slot boots instead).
        let mut refused: Option<BootReason> = None;
        self.boot_slot = None;
        // A slot whose header reads as a complete save: a save exists, so booting nothing
        // means every save was refused.
        self.boot_reason = if slots.iter().any(Option::is_some) {
            BootReason::NoneBootable
        } else {
            BootReason::NoSave
        };
        for h in slots.into_iter().flatten() {
            // The slot's records go straight into the handler's own set (what the next
            // Save stores): no copy of them on the stack.
            if self
                .store
                .read_slot(flash, h.slot, &mut self.staging, &mut self.overrides)
                .is_none()
            {
                if let Some(v) = invalid.get_mut(usize::from(h.slot)) {
                    *v = true;
                }
                self.overrides.clear();
                refused.get_or_insert(BootReason::FallbackUnreadable);
                continue;
            }
            // The slot's settings as one set: all apply, or the slot is refused like a
            // table that fails its rules (the older slot is tried). The link timeout and
            // the PLC link's settings are the handler's; the device skips them.
            let mut timeout = Ok(0);
            let mut plc = crate::plc::PlcSettings::DEFAULT;
            let mut plc_ok = true;
            for r in self.overrides.iter() {
                if r.param == ParamId::LinkTimeoutMs {
                    timeout = link_timeout_ms(r.value);
                } else if r.param.held_by_handler() {
                    plc_ok &= plc.set(r.axis, r.param, r.value).is_ok();
                }
            }
            let ok = timeout.is_ok() && plc_ok && dev.set_params(self.overrides.as_slice()).is_ok();
            self.plc = if ok {
                plc
            } else {
                crate::plc::PlcSettings::DEFAULT
            };
            if !ok {
                // Cleared first: a reset that fails ends the boot with none of them.
                self.overrides.clear();
                dev.reset_params().ok()?;
                self.link.timeout_ms = 0;
                refused.get_or_insert(BootReason::FallbackSettings);
                continue;
            }
            self.link.timeout_ms = timeout.unwrap_or(0);
            if h.rows == 0 {
                // Settings saved before any table: they apply, no table runs.
                self.saved = Some(h);
                self.boot_slot = Some(h.slot);
                self.boot_reason = refused.unwrap_or(BootReason::Newest);
                return Some(h);
            }
            // Built in place in the committed table's buffer (nothing is committed at boot).
            self.committed_id = None;
            let t = self
                .committed
                .rebuild_from_nodes(&self.staging, &dev.table_limits());
            self.staging.clear();
            if t.is_ok() {
                // The slot stays the saved one even if the device refuses its table.
                self.saved = Some(h);
                dev.install_table(&self.committed).ok()?;
                self.set_active(h.id);
                self.boot_slot = Some(h.slot);
                self.boot_reason = refused.unwrap_or(BootReason::Newest);
                return Some(h);
            }
            // Refused: back to the boot configuration before the older slot.
            self.overrides.clear();
            dev.reset_params().ok()?;
            self.link.timeout_ms = 0;
            self.plc = crate::plc::PlcSettings::DEFAULT;
            refused.get_or_insert(BootReason::FallbackTable);
        }
        None
    }

    /// Attaches the flash store (a handler built with [`Store::UNATTACHED`] as a static
    /// gets its store once the flash driver exists, before [`Handler::boot`]).
    pub fn set_store(&mut self, store: Store) {
        self.store = store;
    }

    /// The flash slot [`Handler::boot`] booted (`None`: none) and why.
    pub fn boot_report(&self) -> (Option<u8>, BootReason) {
        (self.boot_slot, self.boot_reason)
    }

    /// Table `id`, just installed from the committed buffer, is the active one.
    fn set_active(&mut self, id: u32) {
        let t = &self.committed;
        self.active_id = Some(id);
        let nodes = (0..t.len()).map_while(|i| t.node(i));
        self.active_crc = super::upload::rows_crc(nodes).unwrap_or(0);
    }

    /// Id of the active table ([`NO_TABLE`] if none).
    pub fn active_id(&self) -> u32 {
        self.active_id.unwrap_or(NO_TABLE)
    }

    /// Installs an armed activation once the device is at a safe point. Call every loop.
    /// Returns the device's refusal, if it refused (the active id then stays).
    pub fn poll<D: Device<S, N>>(&mut self, dev: &mut D) -> Result<(), Nak> {
        if self.pending && dev.at_safe_point() {
            self.pending = false;
            if let Some(id) = self.committed_id {
                // The limits may have changed since Commit: the table is checked against
                // the ones in force now, and a table they refuse stays committed, unrun.
                self.committed.check_limits(&dev.table_limits())?;
                dev.install_table(&self.committed)?;
                self.committed_id = None;
                self.set_active(id);
            }
        }
        Ok(())
    }

    /// Counts one control tick; every `decimation` ticks sends `sample()` as Telemetry.
    pub fn on_tick(&mut self, tx: &mut impl FnMut(&[u8]), sample: impl FnOnce() -> Telemetry) {
        if self.decimation == 0 {
            return;
        }
        self.tick_count = self.tick_count.saturating_add(1);
        if self.tick_count >= self.decimation {
            self.tick_count = 0;
            let seq = self.tel_seq;
            self.tel_seq = seq.wrapping_add(1);
            send(tx, seq, &Response::Telemetry(sample()));
        }
    }

    /// Feeds received bytes; every response frame goes to `tx` (whole frames).
    pub fn on_bytes<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
        bytes: &[u8],
        tx: &mut impl FnMut(&[u8]),
    ) {
        for &b in bytes {
            let (seq, resp) = match self.dec.push(b) {
                None => continue,
                Some(Err(e)) => {
                    self.link.bad_frames = self.link.bad_frames.wrapping_add(1);
                    let code = match e {
                        FrameError::Cobs => NakCode::Framing,
                        FrameError::Truncated => NakCode::Truncated,
                        FrameError::Oversized => NakCode::Oversized,
                        FrameError::Crc => NakCode::Crc,
                    };
                    (
                        0xFFFF,
                        Response::Nak {
                            req: 0,
                            nak: Nak::new(code),
                        },
                    )
                }
                Some(Ok(f)) => {
                    self.link.frames = self.link.frames.wrapping_add(1);
                    // Copy out of the decoder's buffer so `self` is free for dispatch.
                    let mut p = [0u8; MAX_PAYLOAD];
                    let len = f.payload.len();
                    let (seq, t) = (f.seq, f.ty);
                    if let Some(d) = p.get_mut(..len) {
                        d.copy_from_slice(f.payload);
                    }
                    let payload = p.get(..len).unwrap_or(&[]);
                    let r = self.request(dev, flash, seq, t, payload);
                    if matches!(r, Response::Nak { .. }) {
                        self.link.naks = self.link.naks.wrapping_add(1);
                    }
                    (seq, r)
                }
            };
            send(tx, seq, &resp);
            // A refused deferred activation leaves the active id as it was; the host sees
            // that in Status.
            let _ = self.poll(dev);
        }
    }

    /// One checked frame → its response; advances the session seq on success.
    fn request<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
        seq: u16,
        t: u8,
        payload: &[u8],
    ) -> Response {
        let nak = |nak: Nak| Response::Nak { req: t, nak };
        let req = match Request::decode(t, payload) {
            Ok(r) => r,
            // A host of another version is told which version this board speaks.
            Err(NakCode::Version) => {
                return nak(Nak::with(NakCode::Version, u16::from(PROTOCOL_VERSION), 0))
            }
            Err(code) => return nak(Nak::new(code)),
        };
        if !matches!(req, Request::Hello) {
            if !self.session {
                return nak(Nak::new(NakCode::NoSession));
            }
            if seq == self.last_seq {
                return nak(Nak::new(NakCode::Duplicate));
            }
            if seq != self.last_seq.wrapping_add(1) {
                return nak(Nak::with(
                    NakCode::OutOfOrder,
                    self.last_seq.wrapping_add(1),
                    0,
                ));
            }
        }
        let r = match self.gate(dev, crate::plc::Side::Host, &req) {
            Ok(()) => self.dispatch(dev, flash, &req),
            Err(nak) => Response::Nak { req: t, nak },
        };
        if !matches!(r, Response::Nak { .. }) {
            self.session = true;
            self.last_seq = seq;
        }
        r
    }

    pub(super) fn dispatch<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
        req: &Request<'_>,
    ) -> Response {
        let t = req.ty();
        let ack = Response::Ack { req: t, flags: 0 };
        let r = match *req {
            Request::Hello => return Response::Info(self.info(dev)),
            Request::GetStatus => return Response::Status(self.status(dev)),
            Request::TableBegin { id, columns, rows } => self.begin(id, columns, rows),
            Request::TableChunk {
                offset,
                count,
                data,
            } => self.chunk(offset, count, data),
            Request::TableCommit { crc } => self.commit(dev, crc),
            Request::TableAbort => {
                self.upload = None;
                self.staging.clear();
                Ok(())
            }
            Request::Activate { id } => match self.committed_id {
                Some(cid) if cid == id => {
                    // Checked against the limits in force now, not those at Commit: a
                    // SetParam since may have made the table too steep or out of range.
                    if let Err(e) = self.committed.check_limits(&dev.table_limits()) {
                        return Response::Nak {
                            req: t,
                            nak: e.into(),
                        };
                    }
                    self.pending = true;
                    match self.poll(dev) {
                        Ok(()) => {
                            let flags = if self.pending { ACK_DEFERRED } else { 0 };
                            return Response::Ack { req: t, flags };
                        }
                        Err(e) => Err(e),
                    }
                }
                _ => Err(Nak::new(NakCode::UnknownTable)),
            },
            Request::Start => dev.command(Motion::Start).map(|()| {
                self.link.host_started = true;
                self.link.lost = false;
            }),
            Request::Stop => dev.command(Motion::Stop).map(|()| {
                self.link.host_started = false;
            }),
            Request::Hold => dev.command(Motion::Hold).map(|()| {
                self.link.host_started = false;
            }),
            Request::ClearFault => dev.command(Motion::ClearFault),
            Request::SetPosition { axis, pos_um } => dev
                .command(Motion::SetPosition {
                    axis,
                    pos_um: crate::units::PosUm::from_bits(pos_um),
                })
                .map(|()| {
                    // An absolute axis keeps its new offset across a power cycle (Save).
                    if let Some(off) = dev.persisted_offset_um(axis) {
                        self.overrides.record(axis, ParamId::SlaveOffsetUm, off);
                    }
                }),
            Request::Home { axis } => dev.command(Motion::Home { axis }),
            Request::Jog {
                axis,
                speed,
                limits,
            } => dev.command(Motion::Jog {
                axis,
                speed: crate::units::VelUmPerS::from_bits(speed),
                limits: limits.into(),
            }),
            Request::MoveTo {
                axis,
                to_um,
                limits,
            } => dev.command(Motion::MoveTo {
                axis,
                to: crate::units::PosUm::from_bits(to_um),
                limits: limits.into(),
            }),
            Request::TestMove { axis, test } => match test.spec() {
                Some(spec) => dev.command(Motion::Test { axis, spec }).map(|()| {
                    // The link watchdog watches a test like a run: a lost host holds the
                    // axes (the test ends at its centre).
                    self.link.host_started = true;
                    self.link.lost = false;
                }),
                None => Err(Nak::with(
                    NakCode::Motion,
                    u16::from(axis),
                    super::msg::motion_reason::TEST_SPEC,
                )),
            },
            Request::Approach { limits } => dev
                .command(Motion::Approach {
                    limits: limits.into(),
                })
                .map(|()| {
                    // Following starts at the approach's end: the link watchdog watches.
                    self.link.host_started = true;
                    self.link.lost = false;
                }),
            Request::GetParam { axis, param } => {
                let value = match ParamId::from_u8(param) {
                    Some(ParamId::LinkTimeoutMs) => Ok(self.link.timeout_ms as f32),
                    Some(p) if p.held_by_handler() => self.plc.get(axis, p),
                    Some(p) => dev.get_param(axis, p),
                    None => Err(Nak::with(NakCode::UnknownParam, u16::from(axis), param)),
                };
                return match value {
                    Ok(value) => Response::Param { axis, param, value },
                    Err(nak) => Response::Nak { req: t, nak },
                };
            }
            Request::SetParam { axis, param, value } => match ParamId::from_u8(param) {
                Some(p) if p.info().read_only => {
                    Err(Nak::with(NakCode::ReadOnly, u16::from(axis), param))
                }
                Some(ParamId::LinkTimeoutMs) => self.set_link_timeout(value).map(|()| {
                    self.overrides.record(0, ParamId::LinkTimeoutMs, value);
                }),
                Some(p) if p.held_by_handler() => self.plc.set(axis, p, value).map(|()| {
                    let a = if p.info().scope == super::settings::Scope::Axis {
                        axis
                    } else {
                        0
                    };
                    self.overrides.record(a, p, value);
                }),
                Some(p) => dev.set_param(axis, p, value).map(|()| {
                    self.overrides.record(axis, p, value);
                }),
                None => Err(Nak::with(NakCode::UnknownParam, u16::from(axis), param)),
            },
            Request::Save => self.save(dev, flash),
            Request::SetTelemetry { decimation } => {
                self.decimation = decimation;
                self.tick_count = 0;
                Ok(())
            }
            Request::GetFaults => {
                let mut f = FaultsMsg::default();
                dev.fault_history(&mut f.events);
                f.link = LinkStats {
                    frames: self.link.frames,
                    bad_frames: self.link.bad_frames,
                    naks: self.link.naks,
                };
                return Response::Faults(f);
            }
            Request::CaptureArm(c) => {
                match trigger_from_wire(c.trigger, c.channel, c.axis, c.value) {
                    Some(t) => dev.capture_arm(t, c.pre, c.post),
                    None => {
                        let detail = u16::from(c.trigger);
                        Err(Nak::with(NakCode::CaptureTrigger, detail, c.channel))
                    }
                }
            }
            Request::GetCapture { offset, count } => {
                let mut c = CaptureMsg::default();
                dev.capture_read(offset, count, &mut c);
                return Response::Capture(c);
            }
            Request::VirtualMaster { op, speed_scale } => {
                return match dev.virtual_master(op, speed_scale) {
                    Ok(m) => Response::MasterState(m),
                    Err(nak) => Response::Nak { req: t, nak },
                }
            }
            Request::Owner { side } => match crate::plc::Side::from_register(u16::from(side)) {
                Some(w @ (crate::plc::Side::None | crate::plc::Side::Host)) => {
                    self.take_owner(dev, crate::plc::Side::Host, w)
                }
                _ => Err(Nak::with(NakCode::Malformed, u16::from(side), 0)),
            },
        };
        match r {
            Ok(()) => ack,
            Err(nak) => Response::Nak { req: t, nak },
        }
    }

    fn info<D: Device<S, N>>(&self, dev: &D) -> Info {
        Info {
            protocol: PROTOCOL_VERSION,
            firmware: dev.firmware(),
            axes: u8::try_from(S).unwrap_or(u8::MAX),
            capacity_rows: u16::try_from(N).unwrap_or(u16::MAX),
            max_chunk_rows: u8::try_from(Self::MAX_CHUNK_ROWS).unwrap_or(u8::MAX),
            period_us: dev.period_us(),
            active_id: self.active_id(),
            law_buffers: dev.law_buffers(),
            period_min_us: crate::runtime::PERIOD_MIN_US,
            period_max_us: crate::runtime::PERIOD_MAX_US,
            max_segment_counts: crate::table::MAX_SEGMENT_COUNTS,
            limits: super::msg::InfoLimits::of(&dev.table_limits()),
        }
    }

    fn status<D: Device<S, N>>(&self, dev: &D) -> StatusMsg {
        let mut s = StatusMsg::default();
        dev.status(&mut s);
        let mut flags = s.flags & (1 | FLAG_UNREFERENCED | FLAG_PRESSURE_STALE);
        if self.link.lost {
            flags |= FLAG_LINK_LOST;
        }
        if self.pending {
            flags |= 2;
        }
        if self.upload.is_some() {
            flags |= 4;
        }
        if self.committed_id.is_some() {
            flags |= 8;
        }
        if self.session {
            flags |= 16;
        }
        s.flags = flags;
        s.owner = self.owner.owner() as u8;
        s.active_id = self.active_id();
        s.active_rows = dev
            .active_table()
            .map_or(0, |t| u16::try_from(t.len()).unwrap_or(u16::MAX));
        s.active_crc = self.active_crc;
        s.committed_id = self.committed_id.unwrap_or(NO_TABLE);
        s.saved_id = self.saved.map_or(NO_TABLE, |h| h.id);
        s.boot_slot = self.boot_slot.unwrap_or(0xFF);
        s.boot_reason = self.boot_reason as u8;
        s.upload_rows = u16::try_from(self.staging.len()).unwrap_or(u16::MAX);
        s
    }

    fn begin(&mut self, id: u32, columns: u8, rows: u16) -> Result<(), Nak> {
        if usize::from(columns) != S {
            return Err(Nak::with(
                NakCode::Columns,
                u16::try_from(S).unwrap_or(u16::MAX),
                0,
            ));
        }
        if usize::from(rows) > N {
            return Err(Nak::with(
                NakCode::TooManyRows,
                u16::try_from(N).unwrap_or(u16::MAX),
                0,
            ));
        }
        if rows < 2 {
            return Err(Nak::new(NakCode::TableTooFewNodes));
        }
        if id == NO_TABLE {
            return Err(Nak::new(NakCode::UnknownTable));
        }
        self.staging.clear();
        self.upload = Some(Upload {
            id,
            rows,
            crc: CRC32.digest(),
        });
        Ok(())
    }

    fn chunk(&mut self, offset: u16, count: u8, data: &[u8]) -> Result<(), Nak> {
        let up = self.upload.as_mut().ok_or(Nak::new(NakCode::NoUpload))?;
        let have = self.staging.len();
        if usize::from(offset) != have {
            return Err(Nak::with(
                NakCode::ChunkOffset,
                u16::try_from(have).unwrap_or(u16::MAX),
                0,
            ));
        }
        let rl = row_len(S);
        if count == 0 || Some(data.len()) != usize::from(count).checked_mul(rl) {
            return Err(Nak::new(NakCode::Length));
        }
        if have.saturating_add(usize::from(count)) > usize::from(up.rows) {
            return Err(Nak::with(NakCode::TooManyRows, up.rows, 0));
        }
        let mut r = super::wire::Reader::new(data);
        for _ in 0..count {
            let n = read_row::<S>(&mut r).ok_or(Nak::new(NakCode::Length))?;
            // Capacity was checked at Begin (rows ≤ N) and above (have + count ≤ rows).
            self.staging
                .push(n)
                .map_err(|_| Nak::with(NakCode::TooManyRows, up.rows, 0))?;
        }
        up.crc.update(data);
        Ok(())
    }

    fn commit<D: Device<S, N>>(&mut self, dev: &D, crc: u32) -> Result<(), Nak> {
        let up = self.upload.clone().ok_or(Nak::new(NakCode::NoUpload))?;
        let have = self.staging.len();
        if have != usize::from(up.rows) {
            return Err(Nak::with(
                NakCode::Incomplete,
                u16::try_from(have).unwrap_or(u16::MAX),
                0,
            ));
        }
        if up.crc.finalize() != crc {
            return Err(Nak::new(NakCode::TableCrc));
        }
        // In place; a refused table leaves the committed one as it was.
        self.committed
            .rebuild_from_nodes(&self.staging, &dev.table_limits())?;
        self.committed_id = Some(up.id);
        self.pending = false;
        self.upload = None;
        self.staging.clear();
        Ok(())
    }

    fn save<D: Device<S, N>, F: NorFlash>(&mut self, dev: &D, flash: &mut F) -> Result<(), Nak> {
        if !dev.all_idle() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        // The active table and the settings, or the settings alone before any table.
        let t = dev.active_table();
        if t.is_none() && self.overrides.is_empty() {
            return Err(Nak::new(NakCode::NothingToSave));
        }
        // Settings alone would become the newest save and boot without the saved table
        // that did not run (its install was refused): refused (detail 1), nothing changes.
        if t.is_none() && self.saved.is_some_and(|h| h.rows > 0) {
            return Err(Nak::with(NakCode::NothingToSave, 1, 0));
        }
        // Never erase the slot that booted or was saved last (the one that boots now),
        // even when the other slot is newer: after a fallback boot the newer slot is the
        // refused one.
        let keep = self.saved.map(|h| h.slot);
        let h = self
            .store
            .save_keeping(flash, keep, self.active_id(), t, &self.overrides)
            .map_err(|_| Nak::new(NakCode::Flash))?;
        self.saved = Some(h);
        Ok(())
    }
}

/// Encodes and sends one response frame.
fn send(tx: &mut impl FnMut(&[u8]), seq: u16, r: &Response) {
    let mut p = [0u8; MAX_PAYLOAD];
    let mut out = [0u8; MAX_WIRE + 1];
    let Some(n) = r.encode(&mut p) else { return };
    let Some(m) = frame::encode(seq, r.ty(), p.get(..n).unwrap_or(&[]), &mut out) else {
        return;
    };
    tx(out.get(..m).unwrap_or(&[]));
}

/// Builds one request frame (host side and tests): returns its length in `out`
/// (`out` needs [`MAX_WIRE`] + 1 bytes).
pub fn encode_request(seq: u16, req: &Request<'_>, out: &mut [u8]) -> Option<usize> {
    let mut p = [0u8; MAX_PAYLOAD];
    let n = req.encode(&mut p)?;
    frame::encode(seq, req.ty(), p.get(..n)?, out)
}

/// Frame type of a response.
pub const fn is_response(t: u8) -> bool {
    t >= ty::ACK
}
