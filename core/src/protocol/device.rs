//! The protocol's [`Device`], once, for every board that runs the follower law in the
//! runtime: the firmware and the host's virtual board supply only the glue
//! ([`DeviceGlue`]: how to reach the runtime, how a command reaches the tick, what to
//! publish when a law is installed).
//!
//! What the link side keeps ([`LawDevice`]): the follower's configuration and the table
//! limits (SetParam edits them; the boot values are kept for [`Device::reset_params`]),
//! a copy of the active table (for Save and for rebuilding the law when a gain changes,
//! so the link side never borrows the table the tick runs), the law buffers the runtime
//! does not hold, and, at boot, the law built from flash and the restored reference
//! offsets, which [`LawDevice::start`] hands to the runtime.
//!
//! A new law (a table activated, a parameter changed) is built *in place* in a free law
//! buffer (`Follower::configure`, then one table copy) outside any critical section, then
//! installed in one [`DeviceGlue::write`] call that checks the safe point and only swaps
//! references (`Runtime::install`). No law or table is moved by value: a law buffer is a
//! pointer (`&'static mut` on the board, `Box` on the host).

use core::ops::DerefMut;

use super::diag::{
    phase_code, put_capture_row, CaptureMsg, FaultEventMsg, MasterStateMsg, CAPTURE_DATA_MAX,
};
use super::handler::{Device, Motion};
use super::msg::ParamId;
use super::msg::{Nak, NakCode, StatusMsg};
use super::overrides::ParamRecord;
use super::params::{
    apply_param, apply_saved_set, home_um, read_param, reference_offset_um, um_per_count, SlaveRefs,
};
use super::report::{
    command_nak, fill_status, motion_command, refused, state_code, REFUSED_LAW, REFUSED_NOT_SAFE,
};
use super::wire::Writer;
use crate::follower::{Follower, FollowerConfig};
use crate::runtime::{
    BootCause, Capture, CaptureError, Command, CommandError, Controller, Learned, Runtime,
    RuntimeCoeffs, State, Trigger, FAULT_HISTORY_LEN,
};
use crate::table::{CamTable, TableLimits};
use crate::units::{DacCode, PosUm};

/// A law buffer: a pointer to a follower the runtime can run.
pub trait LawBuffer<const S: usize, const N: usize>:
    Controller<S> + DerefMut<Target = Follower<S, N>>
{
}

impl<T, const S: usize, const N: usize> LawBuffer<S, N> for T where
    T: Controller<S> + DerefMut<Target = Follower<S, N>>
{
}

/// What a board supplies around [`LawDevice`].
pub trait DeviceGlue<L, const S: usize, const P: usize> {
    /// Runs `f` on the runtime (briefly: on the board inside a critical section the tick
    /// waits for); `None` before the runtime runs (boot).
    fn read<R>(&self, f: impl FnOnce(&Runtime<L, S, P>) -> R) -> Option<R>;
    /// [`DeviceGlue::read`], mutable.
    fn write<R>(&mut self, f: impl FnOnce(&mut Runtime<L, S, P>) -> R) -> Option<R>;
    /// Has the tick apply `cmd` and waits for its answer; `None` if there is no answer
    /// (no tick yet, a full queue, or the wait timed out: the tick then drops it unapplied).
    fn command(&mut self, cmd: Command) -> Option<Result<(), CommandError>>;
    /// The valve null codes of a law being installed (the board's panic handler writes
    /// them): called inside the same [`DeviceGlue::write`] that swaps the law in, so the
    /// nulls published always belong to the law that runs. Default: nothing to publish.
    fn publish_nulls(_nulls: &[DacCode; S]) {}
    /// Tick timing in the runtime's status (host clock cycles) → ns.
    fn cycles_to_ns(&self, cycles: u32) -> u32;
    /// Runs `f` on the board's capture ring (briefly, as [`DeviceGlue::write`]: the tick
    /// records into it); `None` if the board keeps none (the default).
    fn capture<R>(&mut self, _f: impl FnOnce(&mut Capture<'_, S>) -> R) -> Option<R> {
        None
    }
    /// A test board's simulated master ([`super::diag::master_op`]); `None`: the master
    /// is a real encoder (the default).
    fn virtual_master(
        &mut self,
        _op: u8,
        _speed_scale: f32,
    ) -> Option<Result<MasterStateMsg, Nak>> {
        None
    }
}

/// The link side's state (see the module docs). `T` holds the copy of the active table.
pub struct LawDevice<L, T, const S: usize, const N: usize> {
    fcfg: FollowerConfig<S>,
    limits: TableLimits<S>,
    boot_cfg: FollowerConfig<S>,
    boot_limits: TableLimits<S>,
    active: T,
    pool: LawPool<L>,
    /// The reference offsets and home positions set before the runtime runs (boot),
    /// given to it by [`LawDevice::start`]; the home positions set since, too (so a
    /// reset of the parameters at boot returns to the defaults).
    boot_refs: SlaveRefs<S>,
    firmware: [u8; 3],
}

impl<L, T, const S: usize, const N: usize> LawDevice<L, T, S, N>
where
    L: LawBuffer<S, N>,
    T: DerefMut<Target = CamTable<S, N>>,
{
    /// Boots with `fcfg` and `limits`, no table (`active` is emptied), both law buffers
    /// free; `firmware` is what Info reports.
    pub fn new(
        fcfg: FollowerConfig<S>,
        limits: TableLimits<S>,
        mut active: T,
        laws: [L; 2],
        firmware: [u8; 3],
    ) -> Self {
        active.clear();
        let [a, b] = laws;
        Self {
            fcfg,
            limits,
            boot_cfg: fcfg,
            boot_limits: limits,
            active,
            pool: LawPool {
                free: [Some(a), Some(b)],
                boot_law: None,
            },
            boot_refs: SlaveRefs::NONE,
            firmware,
        }
    }

    /// The follower's configuration in force.
    pub fn follower_config(&self) -> &FollowerConfig<S> {
        &self.fcfg
    }

    /// The runtime after boot: the law built from flash (if a slot was loaded), the
    /// home positions set and the reference offsets restored with it (an offset the
    /// runtime refuses is left out and its slave reported in the returned mask, bit k =
    /// slave k).
    pub fn start<const P: usize>(
        &mut self,
        mut coeffs: RuntimeCoeffs<S>,
        boot: BootCause,
    ) -> (Runtime<L, S, P>, u32) {
        // The saved encoder scales go into the coefficients the runtime starts with (an
        // absolute slave's offset is restored below in the scale it was saved in).
        for (axis, k) in (0u8..).zip(self.boot_refs.scales.iter()) {
            if let Some(k) = k {
                // Checked when it was set; one the coefficients refuse is left out.
                let _ = coeffs.set_um_per_count(axis, *k);
            }
        }
        let mut rt = Runtime::new(coeffs, self.pool.boot_law.take(), boot);
        let mut refused_mask = 0u32;
        for (axis, home) in (0u8..).zip(self.boot_refs.homes.iter()) {
            if let Some(h) = home {
                // Every slave of `S` exists in the runtime: never refused.
                let _ = rt.set_home_um(axis, *h);
            }
        }
        for (axis, off) in (0u8..).zip(self.boot_refs.offsets.iter()) {
            if let Some(o) = off {
                if rt.restore_reference_offset(axis, *o).is_err() {
                    refused_mask |= 1u32.checked_shl(u32::from(axis)).unwrap_or(0);
                }
            }
        }
        (rt, refused_mask)
    }
}

/// The law buffers the runtime does not hold (both at boot, one once a law runs), and the
/// law built at boot before the runtime runs.
struct LawPool<L> {
    free: [Option<L>; 2],
    boot_law: Option<L>,
}

impl<L> LawPool<L> {
    fn take_free(&mut self) -> Option<L> {
        self.free.iter_mut().find_map(Option::take)
    }

    fn give_back(&mut self, law: L) {
        if let Some(slot) = self.free.iter_mut().find(|s| s.is_none()) {
            *slot = Some(law);
        }
    }

    /// Builds a law for `table` with `fcfg` in a free buffer and installs it: before the
    /// runtime runs (boot) it becomes the boot law; otherwise it is swapped in if the
    /// runtime is at a safe point (checked and installed in one [`DeviceGlue::write`]),
    /// and the buffer of the law that ran becomes free. On any refusal what runs is
    /// unchanged and the buffer is free again.
    fn install<G, const S: usize, const N: usize, const P: usize>(
        &mut self,
        glue: &mut G,
        fcfg: &FollowerConfig<S>,
        table: &CamTable<S, N>,
    ) -> Result<(), Nak>
    where
        L: LawBuffer<S, N>,
        G: DeviceGlue<L, S, P>,
    {
        let Some(mut law) = self.take_free() else {
            return Err(refused(REFUSED_LAW));
        };
        if law.configure(fcfg).is_err() {
            self.give_back(law);
            return Err(refused(REFUSED_LAW));
        }
        law.load_table(table);
        if !law.is_ready() {
            // An empty table: never handed to the runtime.
            self.give_back(law);
            return Err(refused(REFUSED_LAW));
        }
        let nulls = Controller::null_codes(&*law);
        if glue.read(|_| ()).is_none() {
            G::publish_nulls(&nulls);
            if let Some(old) = self.boot_law.replace(law) {
                self.give_back(old);
            }
            return Ok(());
        }
        let mut new = Some(law);
        let swapped = glue
            .write(|rt| {
                if !rt.at_safe_point() {
                    return None;
                }
                // The backoff levels and feed-forward trims the running law learned,
                // for the axes whose
                // coefficients the new one keeps.
                if let (Some(running), Some(n)) = (rt.law(), new.as_mut()) {
                    n.carry_learned_from(running);
                }
                // At a safe point (checked in this call): `install` cannot refuse.
                let old = rt.install(new.take()?).ok()?;
                G::publish_nulls(&nulls);
                Some(old)
            })
            .flatten();
        match swapped {
            Some(old) => {
                // `None` at the first activation after an empty boot.
                if let Some(o) = old {
                    self.give_back(o);
                }
                Ok(())
            }
            None => {
                if let Some(n) = new {
                    self.give_back(n);
                }
                Err(refused(REFUSED_NOT_SAFE))
            }
        }
    }
}

/// The [`Device`] for one handler call: the link side's state and the board's glue.
pub struct BoardDevice<'a, L, T, G, const S: usize, const N: usize, const P: usize> {
    /// The link side's state.
    pub st: &'a mut LawDevice<L, T, S, N>,
    /// The board's glue.
    pub glue: &'a mut G,
}

impl<L, T, G, const S: usize, const N: usize, const P: usize> BoardDevice<'_, L, T, G, S, N, P>
where
    L: LawBuffer<S, N>,
    T: DerefMut<Target = CamTable<S, N>>,
    G: DeviceGlue<L, S, P>,
{
    fn active(&self) -> Option<&CamTable<S, N>> {
        (!self.st.active.is_empty()).then_some(&*self.st.active)
    }

    /// A per-slave value the runtime holds once it runs (`live`); before (boot) the one
    /// kept for it in `boot`, or `default` when none was set. `UnknownParam` for a slave
    /// the board does not have.
    fn runtime_or_boot<V: Copy>(
        &self,
        axis: u8,
        param: ParamId,
        live: impl FnOnce(&Runtime<L, S, P>) -> Option<V>,
        boot: &[Option<V>; S],
        default: V,
    ) -> Result<V, Nak> {
        let unknown = Nak::with(NakCode::UnknownParam, u16::from(axis), param as u8);
        match self.glue.read(live) {
            Some(v) => v.ok_or(unknown),
            None => boot
                .get(usize::from(axis))
                .map(|v| v.unwrap_or(default))
                .ok_or(unknown),
        }
    }
}

impl<L, T, G, const S: usize, const N: usize, const P: usize> Device<S, N>
    for BoardDevice<'_, L, T, G, S, N, P>
where
    L: LawBuffer<S, N>,
    T: DerefMut<Target = CamTable<S, N>>,
    G: DeviceGlue<L, S, P>,
{
    fn firmware(&self) -> [u8; 3] {
        self.st.firmware
    }
    fn period_us(&self) -> u32 {
        self.st.fcfg.period_us
    }
    fn table_limits(&self) -> TableLimits<S> {
        self.st.limits
    }
    fn law_buffers(&self) -> u8 {
        2
    }
    fn active_table(&self) -> Option<&CamTable<S, N>> {
        self.active()
    }
    fn at_safe_point(&self) -> bool {
        // Before the runtime runs (boot) nothing runs: always safe.
        self.glue.read(|rt| rt.at_safe_point()).unwrap_or(true)
    }
    fn all_idle(&self) -> bool {
        self.glue
            .read(|rt| matches!(rt.state(), State::Idle | State::Fault))
            .unwrap_or(true)
    }
    fn manual_at_rest(&self) -> bool {
        self.glue
            .read(|rt| {
                rt.state() == State::Manual
                    && rt
                        .status()
                        .manual
                        .iter()
                        .all(|m| *m == crate::runtime::ManualKind::Hold)
            })
            .unwrap_or(false)
    }
    fn install_table(&mut self, table: &CamTable<S, N>) -> Result<(), Nak> {
        let fcfg = self.st.fcfg;
        self.st.pool.install(self.glue, &fcfg, table)?;
        self.st.active.copy_from(table);
        Ok(())
    }
    fn command(&mut self, m: Motion) -> Result<(), Nak> {
        let state = self.glue.read(|rt| state_code(rt.state())).unwrap_or(0xFF);
        let cmd = motion_command(m, &self.st.limits)?;
        match self.glue.command(cmd) {
            Some(Ok(())) => Ok(()),
            Some(Err(e)) => Err(command_nak(state, e)),
            // No tick answered in time (or none runs yet): detail 0xFFFF.
            None => Err(Nak::with(NakCode::BadState, 0xFFFF, 0)),
        }
    }
    fn persisted_offset_um(&self, axis: u8) -> Option<f32> {
        self.glue
            .read(|rt| rt.absolute_offset_um(axis))
            .flatten()
            .map(|o| o.to_num())
    }
    fn get_param(&self, axis: u8, param: ParamId) -> Result<f32, Nak> {
        let refs = &self.st.boot_refs;
        match param {
            ParamId::UmPerCount => {
                self.runtime_or_boot(axis, param, |rt| rt.um_per_count(axis), &refs.scales, 1.0)
            }
            ParamId::HomeUm => self
                .runtime_or_boot(
                    axis,
                    param,
                    |rt| rt.references().home_um().get(usize::from(axis)).copied(),
                    &refs.homes,
                    PosUm::ZERO,
                )
                .map(|h| h.to_num()),
            ParamId::SlaveOffsetUm => self
                .runtime_or_boot(
                    axis,
                    param,
                    |rt| rt.references().offsets().get(usize::from(axis)).copied(),
                    &refs.offsets,
                    PosUm::ZERO,
                )
                .map(|o| o.to_num()),
            _ => read_param(&self.st.fcfg, &self.st.limits, axis, param),
        }
    }
    fn set_param(&mut self, axis: u8, param: ParamId, value: f32) -> Result<(), Nak> {
        let range = Nak::with(NakCode::ParamRange, u16::from(axis), param as u8);
        if param == ParamId::UmPerCount {
            let k = um_per_count(axis, value)?;
            let slot = self
                .st
                .boot_refs
                .scales
                .get_mut(usize::from(axis))
                .ok_or(Nak::with(
                    NakCode::UnknownParam,
                    u16::from(axis),
                    param as u8,
                ))?;
            match self.glue.write(|rt| rt.set_um_per_count(axis, k)) {
                Some(Err(CommandError::Busy)) => return Err(Nak::new(NakCode::NotIdle)),
                Some(Err(_)) => return Err(range),
                Some(Ok(())) | None => {}
            }
            *slot = Some(k);
            return Ok(());
        }
        if param == ParamId::HomeUm {
            let h = home_um(axis, value)?;
            let slot = self
                .st
                .boot_refs
                .homes
                .get_mut(usize::from(axis))
                .ok_or(Nak::with(
                    NakCode::UnknownParam,
                    u16::from(axis),
                    param as u8,
                ))?;
            // In any state: it acts at the next reference edge of an armed homing.
            if let Some(r) = self.glue.write(|rt| rt.set_home_um(axis, h)) {
                r.map_err(|_| range)?;
            }
            *slot = Some(h);
            return Ok(());
        }
        if param == ParamId::SlaveOffsetUm {
            let off = reference_offset_um(axis, value)?;
            // Before the runtime runs (boot): kept for `LawDevice::start`.
            return match self.glue.write(|rt| rt.restore_reference_offset(axis, off)) {
                Some(r) => r.map_err(|_| range),
                None => {
                    let slot = self
                        .st
                        .boot_refs
                        .offsets
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
        apply_param(&mut f, &mut lim, self.active(), axis, param, value)?;
        // Rebuild the law if one runs (in the free buffer, from the copy of its table).
        if !self.st.active.is_empty() {
            let st = &mut *self.st;
            match st.pool.install(self.glue, &f, &st.active) {
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
        // is valid (the reference offsets checked before any is kept).
        if !self.st.active.is_empty() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let mut f = self.st.fcfg;
        let mut lim = self.st.limits;
        let mut refs = self.st.boot_refs;
        apply_saved_set::<S, N>(&mut f, &mut lim, &mut refs, records)?;
        self.st.fcfg = f;
        self.st.limits = lim;
        self.st.boot_refs = refs;
        Ok(())
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        // Only at boot, before a table is installed (no law to rebuild).
        if !self.st.active.is_empty() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        self.st.fcfg = self.st.boot_cfg;
        self.st.limits = self.st.boot_limits;
        self.st.boot_refs = SlaveRefs::NONE;
        Ok(())
    }
    fn status(&self, out: &mut StatusMsg) {
        // The gain backoff's levels and the feed-forward trims come from the law (not
        // kept per tick in the status), read in the same critical section as the
        // status: one tick's picture.
        let read = self.glue.read(|rt| {
            let mut learned = [Learned::NONE; S];
            for (i, l) in learned.iter_mut().enumerate() {
                if let Some(law) = rt.law() {
                    *l = law.learned(i);
                }
            }
            (*rt.status(), learned)
        });
        if let Some((st, learned)) = read {
            fill_status::<S, P>(&st, |c| self.glue.cycles_to_ns(c), out);
            for (a, l) in out.axes.iter_mut().zip(learned) {
                a.backoff = l.backoff_level;
                a.ff_trim = l.ff_trim_q16.map(ff_trim_e4);
            }
        }
    }
    fn fault_history(&self, out: &mut heapless::Vec<FaultEventMsg, FAULT_HISTORY_LEN>) {
        self.glue.read(|rt| {
            for e in rt.fault_history().oldest_ordered() {
                // Both hold FAULT_HISTORY_LEN: never full.
                let _ = out.push(FaultEventMsg::from(e));
            }
        });
    }
    fn capture_arm(&mut self, trigger: Trigger, pre: u32, post: u32) -> Result<(), Nak> {
        match self.glue.capture(|c| c.arm(trigger, pre, post)) {
            None => Err(Nak::new(NakCode::CaptureTrigger)),
            Some(Ok(())) => Ok(()),
            Some(Err(CaptureError::TooLong { capacity })) => Err(Nak::with(
                NakCode::CaptureTooLong,
                u16::try_from(capacity).unwrap_or(u16::MAX),
                0,
            )),
            Some(Err(CaptureError::NoChannel)) => {
                let axis = match trigger {
                    Trigger::Above { channel, .. } | Trigger::Below { channel, .. } => {
                        channel.to_wire().1
                    }
                    _ => 0,
                };
                Err(Nak::with(NakCode::NoAxis, u16::from(axis), 0))
            }
        }
    }
    fn virtual_master(&mut self, op: u8, speed_scale: f32) -> Result<MasterStateMsg, Nak> {
        self.glue
            .virtual_master(op, speed_scale)
            .unwrap_or(Err(Nak::with(NakCode::NoVirtualMaster, u16::from(op), 0)))
    }
    fn capture_read(&mut self, offset: u32, count: u8, out: &mut CaptureMsg) {
        self.glue.capture(|c| {
            let info = c.info();
            out.phase = phase_code(info.phase);
            out.pre = info.pre;
            out.rows = info.rows;
            out.trigger_tick = info.trigger_tick;
            out.capacity = info.capacity;
            out.offset = offset;
            out.data.clear();
            let _ = out.data.resize(CAPTURE_DATA_MAX, 0);
            let mut w = Writer::new(&mut out.data);
            let row_len = super::diag::capture_row_len(S);
            for k in (0..u32::from(count)).map_while(|i| offset.checked_add(i)) {
                let Some((row, flags)) = c.row(k) else { break };
                if w.len().saturating_add(row_len) > CAPTURE_DATA_MAX {
                    break;
                }
                if put_capture_row(&mut w, &row, flags).is_none() {
                    break;
                }
            }
            let n = w.len();
            out.data.truncate(n);
        });
    }
}

/// A trim ratio, Q16 (65 536 = 1), as Status' ratio − 1 in 1/10 000: (r − 65 536) ·
/// 10 000 / 65 536, rounded down; the ratio 0.5 … 2 gives −5 000 … +10 000.
fn ff_trim_e4(r: i32) -> i16 {
    let x = i64::from(r).saturating_sub(65_536).saturating_mul(10_000) >> 16;
    x.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::runtime::{EncoderSample, RuntimeConfig, Sample};
    use crate::table::{AxisLimits, Node};
    use crate::units::{Counts, Master, MasterRate, PosUm, VelUmPerS};
    use std::boxed::Box;

    type Law = Box<Follower<1, 8>>;
    type Rt = Runtime<Law, 1, 0>;

    std::thread_local! {
        /// Null publications of this test's thread.
        static PUBLISHED: core::cell::Cell<u32> = const { core::cell::Cell::new(0) };
    }

    fn published() -> u32 {
        PUBLISHED.with(|p| p.get())
    }

    /// The glue of a board whose runtime is a plain value (`None` until boot ends).
    struct Direct {
        rt: Option<Rt>,
    }

    impl DeviceGlue<Law, 1, 0> for Direct {
        fn read<R>(&self, f: impl FnOnce(&Rt) -> R) -> Option<R> {
            self.rt.as_ref().map(f)
        }
        fn write<R>(&mut self, f: impl FnOnce(&mut Rt) -> R) -> Option<R> {
            self.rt.as_mut().map(f)
        }
        fn command(&mut self, cmd: Command) -> Option<Result<(), CommandError>> {
            let s = Sample {
                enc: EncoderSample {
                    master: Counts(0),
                    slaves: [Counts(100_000)],
                    master_edges: None,
                },
                pressure_bar: [],
                estop: false,
                overrun: false,
            };
            self.rt.as_mut()?.step(&s, Some(cmd)).reply
        }
        fn publish_nulls(_nulls: &[DacCode; 1]) {
            PUBLISHED.with(|p| p.set(p.get() + 1));
        }
        fn cycles_to_ns(&self, c: u32) -> u32 {
            c
        }
    }

    fn limits() -> TableLimits<1> {
        TableLimits {
            master_speed_per_s: MasterRate::from_num(1000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(0),
                max_um: PosUm::from_num(500_000),
                max_speed_um_per_s: VelUmPerS::from_num(200_000),
            }],
        }
    }

    fn table(x_um: i32) -> Box<CamTable<1, 8>> {
        let nodes: [Node<1>; 3] = core::array::from_fn(|j| Node {
            master: Master::from_num(j as i32 * 1000),
            slave_um: [PosUm::from_num(x_um)],
        });
        let mut t = Box::new(CamTable::empty());
        t.rebuild_from_nodes(&nodes, &limits()).unwrap();
        t
    }

    fn device() -> LawDevice<Law, Box<CamTable<1, 8>>, 1, 8> {
        LawDevice::new(
            FollowerConfig::default(),
            limits(),
            table(1),
            [
                Box::new(Follower::unconfigured()),
                Box::new(Follower::unconfigured()),
            ],
            [1, 2, 3],
        )
    }

    fn coeffs() -> RuntimeCoeffs<1> {
        RuntimeConfig::<1>::default().build().unwrap()
    }

    /// A device whose runtime runs (no table yet), and the glue that holds it.
    fn running() -> (LawDevice<Law, Box<CamTable<1, 8>>, 1, 8>, Direct) {
        let mut st = device();
        let (rt, _) = st.start::<0>(coeffs(), BootCause::Normal);
        (st, Direct { rt: Some(rt) })
    }

    #[test]
    fn boot_builds_the_law_before_the_runtime_exists_then_hands_it_over() {
        let mut st = device();
        let mut g = Direct { rt: None };
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        assert_eq!(d.firmware(), [1, 2, 3]);
        assert!(d.active_table().is_none(), "`new` empties the table copy");
        assert!(d.at_safe_point() && d.all_idle());
        // A command before the runtime runs has no tick to answer it.
        assert_eq!(
            d.command(Motion::Start).unwrap_err(),
            Nak::with(NakCode::BadState, 0xFFFF, 0)
        );
        d.install_table(&table(100_000)).unwrap();
        d.set_param(0, ParamId::SlaveOffsetUm, 2500.0).unwrap();
        assert_eq!(published(), 1);
        let (rt, refused) = st.start::<0>(coeffs(), BootCause::Normal);
        assert_eq!(refused, 0);
        assert!(rt.law().is_some_and(|l| l.is_ready()));
        assert_eq!(rt.absolute_offset_um(0), Some(PosUm::from_num(2500)));
        assert_eq!(st.active.len(), 3);
    }

    /// The home position is a setting: set at boot it reaches the runtime with
    /// `start`, set while the runtime runs it acts on the next homing at once, and a
    /// value out of range is refused naming the parameter, the old one kept.
    #[test]
    fn the_home_position_is_a_setting_before_and_after_the_runtime_starts() {
        let mut st = device();
        let mut g = Direct { rt: None };
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        assert_eq!(d.get_param(0, ParamId::HomeUm), Ok(0.0));
        d.set_param(0, ParamId::HomeUm, 150_000.0).unwrap();
        assert_eq!(d.get_param(0, ParamId::HomeUm), Ok(150_000.0));
        let (rt, _) = st.start::<0>(coeffs(), BootCause::Normal);
        assert_eq!(rt.references().home_um()[0], PosUm::from_num(150_000));
        let mut g = Direct { rt: Some(rt) };
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        d.set_param(0, ParamId::HomeUm, -2_500.5).unwrap();
        assert_eq!(d.get_param(0, ParamId::HomeUm), Ok(-2_500.5));
        let home = |g: &Direct| g.rt.as_ref().map(|r| r.references().home_um()[0]);
        assert_eq!(home(d.glue), Some(PosUm::from_num(-2_500.5)));
        let range = Nak::with(NakCode::ParamRange, 0, ParamId::HomeUm as u8);
        assert_eq!(d.set_param(0, ParamId::HomeUm, 9.0e6), Err(range));
        assert_eq!(d.set_param(0, ParamId::HomeUm, f32::NAN), Err(range));
        assert_eq!(
            d.set_param(3, ParamId::HomeUm, 0.0).unwrap_err().code,
            NakCode::UnknownParam
        );
        assert_eq!(home(d.glue), Some(PosUm::from_num(-2_500.5)));
        // A saved set restores it at boot.
        let mut st2 = device();
        let mut refs = SlaveRefs::NONE;
        let (mut f, mut l) = (st2.fcfg, st2.limits);
        let rec = [ParamRecord {
            axis: 0,
            param: ParamId::HomeUm,
            value: 20_000.0,
        }];
        apply_saved_set::<1, 8>(&mut f, &mut l, &mut refs, &rec).unwrap();
        st2.boot_refs = refs;
        let (rt2, _) = st2.start::<0>(coeffs(), BootCause::Normal);
        assert_eq!(rt2.references().home_um()[0], PosUm::from_num(20_000));
    }

    /// The encoder scale is a setting: kept at boot and given to the runtime by
    /// `start`, set in Idle afterwards, refused out of range (|x| < 0.001 too) naming
    /// the parameter.
    #[test]
    fn the_encoder_scale_is_a_setting_before_and_after_the_runtime_starts() {
        let mut st = device();
        let mut g = Direct { rt: None };
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        assert_eq!(d.get_param(0, ParamId::UmPerCount), Ok(1.0));
        d.set_param(0, ParamId::UmPerCount, 0.5).unwrap();
        let (rt, _) = st.start::<0>(coeffs(), BootCause::Normal);
        assert_eq!(rt.um_per_count(0), Some(0.5));
        let mut g = Direct { rt: Some(rt) };
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        d.set_param(0, ParamId::UmPerCount, -0.1).unwrap();
        assert_eq!(d.get_param(0, ParamId::UmPerCount), Ok(-0.1));
        let range = Nak::with(NakCode::ParamRange, 0, ParamId::UmPerCount as u8);
        for k in [0.0, 0.0005, -2000.0, f32::INFINITY] {
            assert_eq!(d.set_param(0, ParamId::UmPerCount, k), Err(range), "{k}");
        }
        assert_eq!(d.get_param(0, ParamId::UmPerCount), Ok(-0.1));
    }

    /// Status' trim: the ratio − 1 in 1/10 000, over the trim's whole range (0.5 … 2),
    /// rounded down; a ratio outside it saturates instead of wrapping.
    #[test]
    fn status_carries_the_trim_in_ten_thousandths() {
        assert_eq!(super::ff_trim_e4(65_536), 0);
        assert_eq!(super::ff_trim_e4(32_768), -5_000);
        assert_eq!(super::ff_trim_e4(131_072), 10_000);
        // 0.78 (51 118 in Q16): −2 200 (one below for the rounding down).
        assert!((-2_201..=-2_199).contains(&super::ff_trim_e4(51_118)));
        assert_eq!(super::ff_trim_e4(i32::MAX), i16::MAX);
        assert_eq!(super::ff_trim_e4(i32::MIN), i16::MIN);
    }

    /// The gain backoff's level survives a law rebuild that keeps the axis'
    /// coefficients (a new table, a board-wide setting) and is gone after one that
    /// changes them (a gain, a backoff threshold): what the axis learned about the machine is kept until the
    /// engineer changes the axis.
    #[test]
    fn a_rebuilt_law_keeps_the_backoff_level_unless_the_axis_changed() {
        use crate::follower::FollowerInputs;
        use crate::units::PressureBar;
        let (mut st, mut g) = running();
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        d.set_param(0, ParamId::KpLsbPerUm, 0.5).unwrap();
        d.set_param(0, ParamId::OscBandUm, 4.0).unwrap();
        d.install_table(&table(100_000)).unwrap();
        // The running law sees its slave shake at 25 Hz, growing from 2 to 40 µm.
        let level = |d: &BoardDevice<'_, _, _, Direct, 1, 8, 0>| {
            d.glue
                .rt
                .as_ref()
                .and_then(|r| r.law())
                .map_or(0, |l| l.learned(0).backoff_level)
        };
        if let Some(law) = d.glue.rt.as_mut().and_then(|r| r.law_mut()) {
            for k in 0..400u32 {
                let t = f64::from(k) * 1e-3;
                let x =
                    100_000.0 + (2.0 + 95.0 * t) * (2.0 * core::f64::consts::PI * 25.0 * t).sin();
                Follower::tick(
                    &mut **law,
                    &FollowerInputs {
                        master: Master::ZERO,
                        pos_um: [PosUm::from_num(x)],
                        pressure_bar: [[PressureBar::ZERO; 2]; 1],
                    },
                );
            }
        }
        let learned = level(&d);
        assert!(learned >= 1, "backed off");
        // A new table and a board-wide setting rebuild the law; the axis is the same.
        d.install_table(&table(120_000)).unwrap();
        assert_eq!(level(&d), learned, "a new table keeps it");
        d.set_param(0, ParamId::MasterFilterHz, 6.0).unwrap();
        assert_eq!(level(&d), learned, "a board-wide setting keeps it");
        // A threshold out of its range is refused by name and changes nothing.
        let range = |id: ParamId| Err(Nak::with(NakCode::ParamRange, 0, id as u8));
        for (id, v) in [
            (ParamId::BackoffHalfCycles, 4.5),
            (ParamId::BackoffMaxLevel, 5.0),
            (ParamId::BackoffFirstScale, 0.0),
            (ParamId::BackoffHighPassHz, f32::NAN),
        ] {
            assert_eq!(d.set_param(0, id, v), range(id), "{id:?} = {v}");
        }
        assert_eq!(level(&d), learned, "a refused threshold keeps it");
        assert_eq!(d.get_param(0, ParamId::BackoffMaxLevel), Ok(4.0));
        // A threshold of the axis: the set value again, the threshold in force.
        d.set_param(0, ParamId::BackoffMaxLevel, 3.0).unwrap();
        assert_eq!(
            level(&d),
            0,
            "a changed threshold starts from the set value"
        );
        assert_eq!(d.get_param(0, ParamId::BackoffMaxLevel), Ok(3.0));
        // A gain of the axis: the set value again.
        d.set_param(0, ParamId::KpLsbPerUm, 0.4).unwrap();
        assert_eq!(level(&d), 0, "a changed gain starts from the set value");
    }

    #[test]
    fn a_running_law_is_swapped_only_at_a_safe_point_and_rebuilt_by_set_param() {
        let (mut st, mut g) = running();
        let mut d = BoardDevice::<_, _, _, 1, 8, 0> {
            st: &mut st,
            glue: &mut g,
        };
        // Parameters first, a table next: reset is refused once one is installed.
        d.reset_params().unwrap();
        d.install_table(&table(100_000)).unwrap();
        assert_eq!(d.reset_params().unwrap_err(), Nak::new(NakCode::NotIdle));
        // Following: not a safe point, and parameters are refused.
        d.command(Motion::Start).unwrap();
        assert!(!d.at_safe_point() && !d.all_idle());
        assert_eq!(
            d.install_table(&table(200_000)).unwrap_err(),
            refused(REFUSED_NOT_SAFE)
        );
        assert_eq!(
            d.set_param(0, ParamId::KpLsbPerUm, 2.0).unwrap_err(),
            Nak::new(NakCode::NotIdle)
        );
        // The running table is unchanged by the refusals.
        let x = |d: &BoardDevice<'_, _, _, Direct, 1, 8, 0>| {
            d.active_table()
                .and_then(|t| t.node(0))
                .map(|n| n.slave_um[0])
        };
        assert_eq!(x(&d), Some(PosUm::from_num(100_000)));
        d.command(Motion::Stop).unwrap();
        // Idle: a gain change rebuilds the running law (same table, new parameters) …
        d.set_param(0, ParamId::KpLsbPerUm, 2.0).unwrap();
        assert_eq!(d.st.follower_config().axes[0].gains.kp_lsb_per_um, 2.0);
        let before = published();
        d.set_param(0, ParamId::ValveNullLsb, 50.0).unwrap();
        let nulls = d.glue.rt.as_ref().map(|r| r.null_codes()[0].get());
        assert_eq!(nulls, Some(50), "the running law has the new valve null");
        assert_eq!(published(), before + 1);
        // … an impossible one is refused with the parameter named, nothing changed.
        assert_eq!(
            d.set_param(0, ParamId::KpLsbPerUm, -1.0).unwrap_err(),
            Nak::with(NakCode::ParamRange, 0, ParamId::KpLsbPerUm as u8)
        );
        assert_eq!(d.st.follower_config().axes[0].gains.kp_lsb_per_um, 2.0);
        // A limit the running table violates is refused too.
        assert!(d.set_param(0, ParamId::MaxUm, 50_000.0).is_err());
        assert_eq!(x(&d), Some(PosUm::from_num(100_000)));
        // Every parameter reads back what is in force; the two Kv are set separately.
        d.set_param(0, ParamId::KvNegLsbPerUmS, 0.25).unwrap();
        assert_eq!(d.get_param(0, ParamId::KvNegLsbPerUmS), Ok(0.25));
        assert_eq!(d.get_param(0, ParamId::KvPosLsbPerUmS), Ok(0.0));
        assert_eq!(d.get_param(0, ParamId::KpLsbPerUm), Ok(2.0));
        assert_eq!(d.get_param(0, ParamId::ValveNullLsb), Ok(50.0));
        assert_eq!(d.get_param(0, ParamId::PeriodUs), Ok(1000.0));
        d.set_param(0, ParamId::ValveInvert, 1.0).unwrap();
        assert_eq!(d.get_param(0, ParamId::ValveInvert), Ok(1.0));
        assert!(d.st.follower_config().axes[0].valve.invert);
        d.set_param(0, ParamId::MasterFilterHz, 20.0).unwrap();
        assert_eq!(d.get_param(0, ParamId::MasterFilterHz), Ok(20.0));
        // Above 0.2/T for this board's 1 ms: refused as a set.
        assert_eq!(
            d.set_param(0, ParamId::MasterFilterHz, 300.0),
            Err(Nak::with(
                NakCode::ParamRange,
                0,
                ParamId::MasterFilterHz as u8
            ))
        );
        assert_eq!(d.get_param(0, ParamId::SlaveOffsetUm), Ok(0.0));
        assert_eq!(
            d.get_param(1, ParamId::KpLsbPerUm),
            Err(Nak::with(
                NakCode::UnknownParam,
                1,
                ParamId::KpLsbPerUm as u8
            ))
        );
        for pp in crate::protocol::settings::all_paths(1) {
            assert!(
                pp.id.held_by_handler() || d.get_param(pp.axis, pp.id).is_ok(),
                "{pp:?}"
            );
        }
    }
}
