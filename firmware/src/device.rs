//! The board as the protocol handler sees it: `hydra_core::protocol::Device` over the
//! tick's runtime (the firmware's counterpart of `host-sim/src/vboard.rs::Machine`).
//!
//! The runtime lives in the tick (priority 0); this side runs in the thread-mode link
//! task. Reads (state, status, safe point) and law installs go through
//! [`crate::tick::with_runtime`], a short critical section. Motion commands go through
//! the tick's command queue and are answered after the tick that applied them
//! ([`LinkIo::command_wait`]), so a command never races the tick.
//!
//! A new law (a table activated, a parameter changed) is built here *in place* in the
//! free one of the two static law buffers (`crate::laws`; `Follower::configure`, then
//! one table copy), outside any critical section, then installed together with its
//! valve null codes ([`ValveBank::publish_safe_codes`], read by the panic handler) in one
//! critical section that only swaps references, only at a safe point (checked in that
//! section; `Runtime::install` refuses otherwise). No law or table is ever moved by
//! value: every frame of this module is small (the CI's stack check,
//! `scripts/stack-check.py`).
//!
//! A copy of the active table is kept in a static buffer for Save and for rebuilding the
//! law when a gain changes, so this side never borrows the table the tick is using.

use hydra_core::follower::FollowerConfig;
use hydra_core::protocol::msg::StatusMsg;
use hydra_core::protocol::report::{
    command_nak, fill_status, motion_command, refused, state_code, REFUSED_LAW, REFUSED_NOT_SAFE,
};
use hydra_core::protocol::{
    apply_param, apply_saved_set, reference_offset_um, Device, Motion, Nak, NakCode, ParamId,
    ParamRecord,
};
use hydra_core::runtime::State;
use hydra_core::table::{CamTable, TableLimits};
use hydra_core::units::PosUm;

use crate::board::{SLAVES, SYSCLK_HZ};
use crate::laws::{self, LawRef};
use crate::link::LinkIo;
use crate::program::{PERIOD_US, TABLE_NODES};
use crate::tick;
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

/// What the link side keeps about the machine: gains, limits, the active table and the
/// law buffers not given to the runtime. Small (a few hundred bytes): the tables and
/// laws it points to are statics.
pub struct DeviceState {
    /// The follower's configuration (gains, calibration); SetParam edits it.
    pub fcfg: FollowerConfig<SLAVES>,
    /// The limits tables are validated against; SetParam edits them.
    pub limits: TableLimits<SLAVES>,
    /// Copy of the table inside the running law ([`Table::empty`] while none runs).
    active: &'static mut Table,
    /// The law buffers the runtime does not hold.
    pool: LawPool,
    /// Reference offsets of absolute slaves restored from flash at boot, before the
    /// runtime exists (`main` applies them).
    pub boot_offsets: [Option<PosUm>; SLAVES],
}

/// The law buffers the runtime does not hold (both at boot, one once a law runs).
struct LawPool {
    free: [Option<LawRef>; 2],
    /// The law built before the tick runs (boot), for `main` to hand to the runtime.
    boot_law: Option<LawRef>,
}

impl LawPool {
    fn take_free(&mut self) -> Option<LawRef> {
        self.free.iter_mut().find_map(Option::take)
    }

    fn give_back(&mut self, law: LawRef) {
        if let Some(slot) = self.free.iter_mut().find(|s| s.is_none()) {
            *slot = Some(law);
        }
    }
}

impl DeviceState {
    /// The boot configuration (`crate::program`), no table, both law buffers free.
    /// `None` if called twice (the static buffers are taken once).
    pub fn new() -> Option<Self> {
        let [a, b] = laws::take()?;
        Some(Self {
            fcfg: crate::program::follower_config(),
            limits: crate::program::table_limits(),
            active: ACTIVE.try_take()?,
            boot_offsets: [None; SLAVES],
            pool: LawPool {
                free: [Some(a), Some(b)],
                boot_law: None,
            },
        })
    }

    /// The law built at boot (from a flash slot), once.
    pub fn take_boot_law(&mut self) -> Option<LawRef> {
        self.pool.boot_law.take()
    }
}

/// The handler's view of the board for one call (`io` is `None` at boot, before the
/// link runs: commands are then refused).
pub struct BoardDevice<'a, 'b> {
    /// Gains, limits, active table.
    pub st: &'a mut DeviceState,
    /// The link's queues to the tick.
    pub io: Option<&'a mut LinkIo<'b>>,
}

/// Builds a law for `table` with `fcfg` in a free law buffer (in place: configure, then
/// one table copy; outside any critical section) and installs it: at boot (the tick not
/// running yet) it becomes the boot law; otherwise it is swapped in if the runtime is at
/// a safe point — checked and installed in one critical section that only swaps
/// references (`crate::laws`) — and the buffer of the law that ran becomes free. The
/// valve nulls for the panic handler are published in the same section. On any refusal
/// what runs is unchanged and the buffer is free again.
fn install(pool: &mut LawPool, fcfg: &FollowerConfig<SLAVES>, table: &Table) -> Result<(), Nak> {
    let Some(law) = pool.take_free() else {
        defmt::error!("no free law buffer");
        return Err(refused(REFUSED_LAW));
    };
    if let Err(e) = law.configure(fcfg) {
        defmt::error!("follower rejected the configuration: {}", e);
        pool.give_back(law);
        return Err(refused(REFUSED_LAW));
    }
    law.load_table(table);
    if !law.is_ready() {
        // An empty table: never handed to the runtime.
        pool.give_back(law);
        return Err(refused(REFUSED_LAW));
    }
    let nulls = hydra_core::runtime::Controller::null_codes(&*law);
    let running = tick::with_runtime(|_| ()).is_some();
    if !running {
        ValveBank::publish_safe_codes(&nulls);
        if let Some(old) = pool.boot_law.replace(law) {
            pool.give_back(old);
        }
        return Ok(());
    }
    let mut new = Some(law);
    let swapped = tick::with_runtime(|rt| {
        if !rt.at_safe_point() {
            return None;
        }
        // At a safe point (checked in this section): `install` cannot refuse, so the
        // reference is never dropped.
        let old = rt.install(new.take()?).ok()?;
        ValveBank::publish_safe_codes(&nulls);
        Some(old)
    })
    .flatten();
    match swapped {
        Some(old) => {
            // `None` at the first activation after an empty boot.
            if let Some(o) = old {
                pool.give_back(o);
            }
            Ok(())
        }
        None => {
            if let Some(n) = new {
                pool.give_back(n);
            }
            Err(refused(REFUSED_NOT_SAFE))
        }
    }
}

fn cycles_to_ns(c: u32) -> u32 {
    let ns = u64::from(c).saturating_mul(1_000_000_000) / u64::from(SYSCLK_HZ);
    u32::try_from(ns).unwrap_or(u32::MAX)
}

impl Device<SLAVES, TABLE_NODES> for BoardDevice<'_, '_> {
    fn firmware(&self) -> [u8; 3] {
        FIRMWARE
    }
    fn period_us(&self) -> u32 {
        PERIOD_US
    }
    fn table_limits(&self) -> TableLimits<SLAVES> {
        self.st.limits
    }
    fn active_table(&self) -> Option<&Table> {
        (!self.st.active.is_empty()).then_some(&*self.st.active)
    }
    fn at_safe_point(&self) -> bool {
        // Before the tick starts (boot) nothing runs: always safe.
        tick::with_runtime(|rt| rt.at_safe_point()).unwrap_or(true)
    }
    fn all_idle(&self) -> bool {
        tick::with_runtime(|rt| matches!(rt.state(), State::Idle | State::Fault)).unwrap_or(true)
    }
    fn install_table(&mut self, table: &Table) -> Result<(), Nak> {
        let fcfg = self.st.fcfg;
        match install(&mut self.st.pool, &fcfg, table) {
            Ok(()) => {
                self.st.active.copy_from(table);
                defmt::info!("table installed ({} rows)", table.len());
                Ok(())
            }
            Err(e) => {
                defmt::warn!("table not installed: {}", e);
                Err(e)
            }
        }
    }
    fn command(&mut self, m: Motion) -> Result<(), Nak> {
        let cmd = motion_command(m);
        let state = tick::with_runtime(|rt| state_code(rt.state())).unwrap_or(0xFF);
        let io = self
            .io
            .as_mut()
            .ok_or(Nak::with(NakCode::BadState, 0xFFFF, 0))?;
        match io.command_wait(cmd) {
            Some(Ok(())) => Ok(()),
            Some(Err(e)) => {
                defmt::info!("command {} refused: {}", cmd, e);
                Err(command_nak(state, e))
            }
            // The tick did not answer in time (or the queue is full): detail 0xFFFF.
            None => Err(Nak::with(NakCode::BadState, 0xFFFF, 0)),
        }
    }
    fn persisted_offset_um(&self, axis: u8) -> Option<f32> {
        tick::with_runtime(|rt| rt.absolute_offset_um(axis))
            .flatten()
            .map(|o| o.to_num())
    }
    fn set_param(&mut self, axis: u8, param: ParamId, value: f32) -> Result<(), Nak> {
        let range = Nak::with(NakCode::ParamRange, u16::from(axis), param as u8);
        if param == ParamId::SlaveOffsetUm {
            let off = reference_offset_um(axis, value)?;
            // Before the tick starts (boot) the runtime does not exist yet: kept for
            // `main` to restore once it does.
            return match tick::with_runtime(|rt| rt.restore_reference_offset(axis, off)) {
                Some(r) => r.map_err(|_| range),
                None => {
                    let slot = self
                        .st
                        .boot_offsets
                        .get_mut(usize::from(axis))
                        .ok_or(range)?;
                    *slot = Some(off);
                    Ok(())
                }
            };
        }
        if !self.all_idle() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let mut f = self.st.fcfg;
        let mut lim = self.st.limits;
        let active = (!self.st.active.is_empty()).then_some(&*self.st.active);
        apply_param(&mut f, &mut lim, active, axis, param, value)?;
        // Rebuild the law if one runs (in the free buffer, from the copy of its table).
        if !self.st.active.is_empty() {
            match install(&mut self.st.pool, &f, self.st.active) {
                Ok(()) => {}
                Err(n) if n.code == NakCode::Refused && n.detail == REFUSED_NOT_SAFE => {
                    return Err(Nak::new(NakCode::NotIdle))
                }
                Err(_) => return Err(range),
            }
        }
        self.st.fcfg = f;
        self.st.limits = lim;
        Ok(())
    }
    fn set_params(&mut self, records: &[ParamRecord]) -> Result<(), Nak> {
        // Boot only (no table yet): the whole set on copies, then kept only if all of it
        // is valid (`apply_param_set`; the reference offsets checked before any is kept).
        if !self.st.active.is_empty() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let mut f = self.st.fcfg;
        let mut lim = self.st.limits;
        let mut offsets = self.st.boot_offsets;
        apply_saved_set::<SLAVES, TABLE_NODES>(&mut f, &mut lim, &mut offsets, records)?;
        self.st.fcfg = f;
        self.st.limits = lim;
        self.st.boot_offsets = offsets;
        Ok(())
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        // Only at boot, before a table is installed (no law to rebuild).
        if !self.st.active.is_empty() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        self.st.fcfg = crate::program::follower_config();
        self.st.limits = crate::program::table_limits();
        self.st.boot_offsets = [None; SLAVES];
        Ok(())
    }
    fn status(&self, out: &mut StatusMsg) {
        if let Some(st) = tick::with_runtime(|rt| *rt.status()) {
            fill_status::<SLAVES, _>(&st, cycles_to_ns, out);
        }
    }
}
