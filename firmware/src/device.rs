//! The board as the protocol handler sees it: `hydra_core::protocol::Device` over the
//! tick's runtime (the firmware's counterpart of `host-sim/src/vboard.rs::Machine`).
//!
//! The runtime lives in the tick (priority 0); this side runs in the thread-mode link
//! task. Reads (state, status, safe point) and law installs go through
//! [`crate::tick::with_runtime`], a short critical section. Motion commands go through
//! the tick's command queue and are answered after the tick that applied them
//! ([`LinkIo::command_wait`]), so a command never races the tick.
//!
//! A new law (a table activated, a parameter changed) is built here, outside the
//! critical section, then installed together with its valve null codes
//! ([`ValveBank::publish_safe_codes`], read by the panic handler) in one critical
//! section, only at a safe point (the handler checks it; `Runtime::install` refuses
//! otherwise). That section moves the law (`Follower<2, 256>`) into the runtime: the tick
//! after it starts late by that copy, once, while the valves are at null or holding the
//! table's end.
//!
//! A copy of the active table is kept here for Save and for rebuilding the law when a
//! gain changes, so this side never borrows the table the tick is using.

use hydra_core::follower::FollowerConfig;
use hydra_core::protocol::msg::StatusMsg;
use hydra_core::protocol::report::{
    bad_state, fill_status, motion_command, refused, state_code, REFUSED_LAW, REFUSED_NOT_SAFE,
};
use hydra_core::protocol::{apply_param, Device, Motion, Nak, NakCode, ParamId};
use hydra_core::runtime::State;
use hydra_core::table::{CamTable, TableLimits};

use crate::board::{SLAVES, SYSCLK_HZ};
use crate::laws::{self, LawRef};
use crate::link::LinkIo;
use crate::program::{Law, PERIOD_US, TABLE_NODES};
use crate::tick;
use crate::valves::ValveBank;

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

/// What the link side keeps about the machine: gains, limits, the active table.
pub struct DeviceState {
    /// The follower's configuration (gains, calibration); SetParam edits it.
    pub fcfg: FollowerConfig<SLAVES>,
    /// The limits tables are validated against; SetParam edits them.
    pub limits: TableLimits<SLAVES>,
    /// Copy of the table inside the running law.
    pub active: Option<Table>,
    /// The law buffer not in use by the runtime (see [`install`]).
    pub spare: Option<LawRef>,
}

impl DeviceState {
    /// The boot configuration (`crate::program`), no table.
    pub fn new() -> Self {
        Self {
            fcfg: crate::program::follower_config(),
            limits: crate::program::table_limits(),
            active: None,
            spare: None,
        }
    }

    /// The law for the active table with the present configuration (boot).
    pub fn law(&self) -> Option<Law> {
        let t = self.active.clone()?;
        match Law::new(&self.fcfg, t) {
            Ok(l) => Some(l),
            Err(e) => {
                defmt::error!("follower rejected the table: {}", e);
                None
            }
        }
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

/// Installs `law` (and its null codes for the panic handler) if the tick runs; `false`
/// if the runtime is not at a safe point. The law is first written into the spare law
/// buffer (outside the critical section); the section only swaps references
/// (`crate::laws`), and the buffer of the law that ran becomes the spare.
fn install(st: &mut DeviceState, law: Law) -> bool {
    let nulls = hydra_core::runtime::Controller::null_codes(&law);
    let Some(new) = laws::place(law, st.spare.take()) else {
        defmt::error!("no free law buffer");
        return false;
    };
    let mut new = Some(new);
    // Checked and installed in one section: `install` cannot then refuse, so the
    // reference is never dropped (a dropped one would leave no spare buffer).
    let swapped = tick::with_runtime(|rt| {
        if !rt.at_safe_point() {
            return None;
        }
        let old = rt.install(new.take()?).ok()?;
        ValveBank::publish_safe_codes(&nulls);
        Some(old)
    })
    .flatten();
    match swapped {
        Some(old) => {
            // `None` at the first activation: the other buffer is still unused.
            st.spare = old;
            true
        }
        None => {
            st.spare = new;
            false
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
        self.st.active.as_ref()
    }
    fn at_safe_point(&self) -> bool {
        // Before the tick starts (boot) nothing runs: always safe.
        tick::with_runtime(|rt| rt.at_safe_point()).unwrap_or(true)
    }
    fn all_idle(&self) -> bool {
        tick::with_runtime(|rt| matches!(rt.state(), State::Idle | State::Fault)).unwrap_or(true)
    }
    fn install_table(&mut self, table: Table) -> Result<(), Nak> {
        let law = match Law::new(&self.st.fcfg, table.clone()) {
            Ok(l) => l,
            Err(e) => {
                defmt::error!("follower rejected the table: {}", e);
                return Err(refused(REFUSED_LAW));
            }
        };
        // Before the tick starts (boot) `main` builds the law from `st.active` itself.
        let running = tick::with_runtime(|_| ()).is_some();
        if !running || install(self.st, law) {
            self.st.active = Some(table);
            defmt::info!(
                "table installed ({} rows)",
                self.st.active.as_ref().map_or(0, |t| t.len())
            );
            Ok(())
        } else {
            defmt::warn!("table not installed: runtime not at a safe point");
            Err(refused(REFUSED_NOT_SAFE))
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
                Err(bad_state(state))
            }
            // The tick did not answer in time (or the queue is full): detail 0xFFFF.
            None => Err(Nak::with(NakCode::BadState, 0xFFFF, 0)),
        }
    }
    fn set_param(&mut self, axis: u8, param: ParamId, value: f32) -> Result<(), Nak> {
        let range = Nak::with(NakCode::ParamRange, u16::from(axis), param as u8);
        if !self.all_idle() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let mut f = self.st.fcfg;
        let mut lim = self.st.limits;
        apply_param(
            &mut f,
            &mut lim,
            self.st.active.as_ref(),
            axis,
            param,
            value,
        )?;
        // Rebuild the law if one runs.
        if let Some(t) = self.st.active.clone() {
            let law = Law::new(&f, t).map_err(|_| range)?;
            if !install(self.st, law) {
                return Err(Nak::new(NakCode::NotIdle));
            }
        }
        self.st.fcfg = f;
        self.st.limits = lim;
        Ok(())
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        // Only at boot, before a table is installed (no law to rebuild).
        if self.st.active.is_some() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        self.st.fcfg = crate::program::follower_config();
        self.st.limits = crate::program::table_limits();
        Ok(())
    }
    fn status(&self, out: &mut StatusMsg) {
        if let Some(st) = tick::with_runtime(|rt| *rt.status()) {
            fill_status::<SLAVES, _>(&st, cycles_to_ns, out);
        }
    }
}
