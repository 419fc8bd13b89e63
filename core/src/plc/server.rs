//! The Modbus server's application layer: register reads and writes against the map
//! ([`super::map::MAP`]), turned into the protocol handler's requests, so a PLC's command
//! or setting goes through exactly the validation, the ownership gate and the code a
//! serial frame goes through ([`Handler::plc_request`]). The transports (RTU, TCP) only
//! frame and unframe PDUs around [`Server::read_holding`], [`Server::read_input`] and
//! [`Server::write`].
//!
//! **Writes.** A write (function 6 or 16) is checked whole before anything changes:
//! - every register it covers must be a holding register of the map, whole 32-bit
//!   values only — else exception 02;
//! - every value must be one its register takes (an `owner` of 0 … 2, a `param.op` of
//!   1 or 2, an axis the board has, a position within ±8 000 000 µm, no undefined
//!   command bit, not both jogs) — else exception 03;
//! - the registers that only stage an argument or select what a read returns
//!   (`param.id`, `param.axis`, `param.value`, `param.op` = 1) and `heartbeat` and
//!   `owner` are free; every other write needs the
//!   PLC to own the machine (an `owner` = 2 in the same write counts) — else
//!   exception 01 ([`super::OwnerError::MODBUS_EXCEPTION`]).
//!
//! Then `owner` is taken or released, `heartbeat` is noted, and the actions run:
//! `param.op` (a setting read or written: a refused write is exception 03 when its value
//! is out of range or the id read-only or unknown, 04 when the board is busy) and the
//! `command` bits. A command a device refuses (not referenced, wrong state …) is
//! exception 04, with the serial Nak's code in `command_ack` (0x100 + code); the
//! `command` register then keeps its old value, so writing the same bits again retries.
//! Bits act in this order: stop (also `enable` cleared), clear_fault, hold, home,
//! activate_table, move, start, save, jog; the first refusal ends the write. `start`,
//! `hold`, `home`, `move` and the jogs need `enable` set in the same value (else
//! `command_ack` = [`ACK_ENABLE_OFF`]).
//!
//! **Heartbeat.** While the PLC owns the machine and a motion it started runs, a
//! `heartbeat` unchanged for `plc/heartbeat_ms` holds the axes (as the serial link's
//! `link/timeout_ms` does) and sets the `heartbeat_lost` status bit until it changes.

use super::image::{read_input, PlcFacts, NO_TABLE};
use super::map::{AxisCount, CommandBit, Register, RegisterTable, AXIS_BASE, AXIS_STRIDE};
use super::map::{MAP, MAX_AXES};
use super::owner::{Heartbeat, Side};
use crate::protocol::msg::{MotionLimitsMsg, NakCode, Request, Response};
use crate::protocol::{Device, Handler, ParamId};
use crate::runtime::{RefState, State, Status};
use embedded_storage::nor_flash::NorFlash;

/// A Modbus exception: the code the server answers a refused request with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Exception {
    /// 01: not the owner (or a function the board does not serve).
    IllegalFunction = 1,
    /// 02: no such register, or a split 32-bit value.
    IllegalAddress = 2,
    /// 03: a value the register does not take.
    IllegalValue = 3,
    /// 04: the board refused the command or setting (see `command_ack`, `param.result`).
    DeviceFailure = 4,
}

/// `command_ack` when a motion bit came without `enable`.
pub const ACK_ENABLE_OFF: u16 = 0x200;
/// `command_ack` of a command done.
pub const ACK_DONE: u16 = 1;
/// Words of the holding image: the board block and every axis block.
const HOLDING_WORDS: usize = AXIS_BASE as usize + AXIS_STRIDE as usize * MAX_AXES as usize;
/// A jog is renewed this often while its bit is set, ms (its deadman is 300 ms).
const JOG_RENEW_MS: u32 = 100;
/// Manual motion limits when their registers are 0.
const DEFAULT_ACC_UM_S2: u32 = 100_000;
const DEFAULT_JERK_UM_S3: u32 = 1_000_000;
/// Largest |position| a move takes, µm (the wire's I24F8 range).
const MAX_POS_UM: i32 = 8_000_000;

/// `param.result` codes.
pub mod param_result {
    /// Done.
    pub const DONE: u16 = 1;
    /// No setting has this id (or not on this axis).
    pub const UNKNOWN: u16 = 2;
    /// The value is out of range, or the set it makes is not valid.
    pub const RANGE: u16 = 3;
    /// The setting is read-only.
    pub const READ_ONLY: u16 = 4;
    /// The board is busy (a setting that needs Idle).
    pub const BUSY: u16 = 5;
}

/// What the input registers need from the board beyond the runtime's status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Live<const S: usize> {
    /// The master speed, master counts/s.
    pub master_speed_counts_per_s: i32,
    /// The tick's longest execution, µs.
    pub tick_max_us: u16,
    /// The gain backoff's level per axis.
    pub backoff_level: [u8; S],
}

/// The Modbus server of a board of `S` slaves.
#[derive(Clone, Debug)]
pub struct Server<const S: usize> {
    holding: [u16; HOLDING_WORDS],
    heartbeat: Heartbeat,
    command_ack: u16,
    command_count: u16,
    param_result: u16,
    param_read_value: f32,
    /// A motion the PLC started runs: the heartbeat watches it.
    plc_started: bool,
    /// The running jog (axis, speed I24F8 µm/s raw) and when it was last renewed.
    jog: Option<(u8, i32, u32)>,
}

fn word_at(img: &[u16; HOLDING_WORDS], address: u16) -> u16 {
    img.get(usize::from(address)).copied().unwrap_or(0)
}

fn u32_at(img: &[u16; HOLDING_WORDS], address: u16) -> u32 {
    (u32::from(word_at(img, address)) << 16) | u32::from(word_at(img, address.saturating_add(1)))
}

/// The holding register `name` (board) or `name` of `axis`, its address.
fn holding(name: &str, axis: u8) -> u16 {
    MAP.iter()
        .find(|r| r.table == RegisterTable::Holding && r.name == name)
        .map_or(u16::MAX, |r| r.address_of(axis))
}

impl<const S: usize> Server<S> {
    /// A server at power-up (every holding register 0), its clock at `now_ms`.
    pub const fn new(now_ms: u32) -> Self {
        Self {
            holding: [0; HOLDING_WORDS],
            heartbeat: Heartbeat::new(now_ms),
            command_ack: 0,
            command_count: 0,
            param_result: 0,
            param_read_value: 0.0,
            plc_started: false,
            jog: None,
        }
    }

    fn axes() -> AxisCount {
        let n = u8::try_from(S).unwrap_or(MAX_AXES).clamp(1, MAX_AXES);
        AxisCount::new(n).unwrap_or(AxisCount::ONE)
    }

    /// Reads holding registers (function 3): what was written, 0 where nothing was.
    pub fn read_holding(&self, start: u16, out: &mut [u16]) -> Result<(), Exception> {
        Self::check_span(start, out.len())?;
        for (k, o) in (0u16..).zip(out.iter_mut()) {
            *o = word_at(&self.holding, start.saturating_add(k));
        }
        Ok(())
    }

    /// Whether `len` words from `start` are whole holding registers of the map.
    fn check_span(start: u16, len: usize) -> Result<(), Exception> {
        let mut k = 0usize;
        while k < len {
            let a = start.saturating_add(u16::try_from(k).unwrap_or(u16::MAX));
            let (r, _, w) = Register::find(RegisterTable::Holding, a, Self::axes())
                .ok_or(Exception::IllegalAddress)?;
            let n = usize::from(r.ty.words());
            if w != 0 || k.saturating_add(n) > len {
                return Err(Exception::IllegalAddress);
            }
            k = k.saturating_add(n);
        }
        Ok(())
    }

    /// Reads input registers (function 4) from the runtime's status `st`, the handler's
    /// state and `live`.
    pub fn read_input<D: Device<S, N>, const N: usize, const P: usize>(
        &self,
        handler: &Handler<S, N>,
        dev: &D,
        st: &Status<S, P>,
        live: &Live<S>,
        start: u16,
        out: &mut [u16],
    ) -> Result<(), Exception> {
        let facts = self.facts(handler, dev, st, live);
        read_input(st, &facts, Self::axes(), start, out).map_err(|_| Exception::IllegalAddress)
    }

    /// The PLC-side facts of the input image.
    fn facts<D: Device<S, N>, const N: usize, const P: usize>(
        &self,
        handler: &Handler<S, N>,
        dev: &D,
        st: &Status<S, P>,
        live: &Live<S>,
    ) -> PlcFacts<S> {
        let plc = handler.plc_settings();
        let active = handler.active_id();
        let mut force_n = [0.0f32; S];
        for (i, f) in (0u8..).zip(force_n.iter_mut()) {
            let area = |p| dev.get_param(i, p).unwrap_or(0.0);
            let bar = |k: usize| {
                st.pressure_bar
                    .get(usize::from(i).saturating_mul(2).saturating_add(k))
                    .map_or(0.0f32, |p| p.to_num::<f32>())
            };
            // bar · mm² · 0.1 = N.
            *f = (bar(0) * area(ParamId::AreaAMm2) - bar(1) * area(ParamId::AreaBMm2)) * 0.1;
        }
        let referenced = st.reference.iter().all(|r| *r == RefState::Referenced);
        PlcFacts {
            ready: st.state == State::Idle && dev.active_table().is_some() && referenced,
            owner: handler.owner(),
            heartbeat_lost: self.heartbeat.lost(),
            command_ack: self.command_ack,
            command_count: self.command_count,
            table_active_id: u16::try_from(active).unwrap_or(NO_TABLE),
            param_result: self.param_result,
            param_read_value: self.param_read_value,
            master_speed_counts_per_s: live.master_speed_counts_per_s,
            tick_max_us: live.tick_max_us,
            in_position_um: core::array::from_fn(|i| plc.in_position_um(i) as u32),
            force_n,
            backoff_level: live.backoff_level,
        }
    }

    /// Checks every value of a staged image's written span (see the module docs).
    fn check_values(img: &[u16; HOLDING_WORDS], start: u16, len: usize) -> Result<(), Exception> {
        let bad = Err(Exception::IllegalValue);
        let axes = Self::axes();
        let mut k = 0usize;
        while k < len {
            let a = start.saturating_add(u16::try_from(k).unwrap_or(u16::MAX));
            let Some((r, _, _)) = Register::find(RegisterTable::Holding, a, axes) else {
                return Err(Exception::IllegalAddress);
            };
            let v = word_at(img, a);
            let ok = match r.name {
                "owner" => Side::from_register(v).is_some(),
                "table.select_id" => v != NO_TABLE,
                "param.op" => v == 1 || v == 2,
                "command_axis" | "param.axis" => usize::from(v) < S,
                "command" => {
                    let all = CommandBit::ALL.iter().fold(0u16, |m, b| m | b.mask());
                    let both = CommandBit::JogPos.mask() | CommandBit::JogNeg.mask();
                    v & !all == 0 && v & both != both
                }
                "move_to_um" => (u32_at(img, a) as i32).unsigned_abs() <= MAX_POS_UM as u32,
                "move_speed_um_s" => (0..=MAX_POS_UM).contains(&(u32_at(img, a) as i32)),
                _ => true,
            };
            if !ok {
                return bad;
            }
            k = k.saturating_add(usize::from(r.ty.words()));
        }
        Ok(())
    }

    /// Whether the span needs ownership: anything but `heartbeat`, `owner`, `param.id`,
    /// `param.axis`, `param.value` and a `param.op` of 1 (read).
    fn needs_owner(img: &[u16; HOLDING_WORDS], start: u16, len: usize) -> bool {
        let mut k = 0usize;
        while k < len {
            let a = start.saturating_add(u16::try_from(k).unwrap_or(u16::MAX));
            let Some((r, _, _)) = Register::find(RegisterTable::Holding, a, Self::axes()) else {
                return true;
            };
            match r.name {
                "heartbeat" | "owner" | "param.id" | "param.axis" | "param.value" => {}
                "param.op" if word_at(img, a) == 1 => {}
                _ => return true,
            }
            k = k.saturating_add(usize::from(r.ty.words()));
        }
        false
    }

    /// Writes `values` from `start` (functions 6 and 16) at `now_ms`; see the module docs.
    pub fn write<D: Device<S, N>, F: NorFlash, const N: usize>(
        &mut self,
        handler: &mut Handler<S, N>,
        dev: &mut D,
        flash: &mut F,
        start: u16,
        values: &[u16],
        now_ms: u32,
    ) -> Result<(), Exception> {
        let len = values.len();
        Self::check_span(start, len)?;
        let mut img = self.holding;
        for (k, v) in (0u16..).zip(values) {
            if let Some(w) = img.get_mut(usize::from(start.saturating_add(k))) {
                *w = *v;
            }
        }
        Self::check_values(&img, start, len)?;
        let end = usize::from(start).saturating_add(len);
        let written = |a: u16| (usize::from(start)..end).contains(&usize::from(a));
        // Ownership first: an `owner` = 2 in this write lets the rest of it act.
        let owner_at = holding("owner", 0);
        if written(owner_at) {
            let wants = Side::from_register(word_at(&img, owner_at)).unwrap_or(Side::None);
            handler
                .take_owner(dev, Side::Plc, wants)
                .map_err(|_| Exception::IllegalFunction)?;
            if wants == Side::Plc {
                self.heartbeat.restart(now_ms);
            }
        }
        if Self::needs_owner(&img, start, len) && handler.owner() != Side::Plc {
            return Err(Exception::IllegalFunction);
        }
        let hb = holding("heartbeat", 0);
        if written(hb) {
            self.heartbeat.write(word_at(&img, hb), now_ms);
            handler.set_plc_lost(self.heartbeat.lost());
        }
        let op = holding("param.op", 0);
        if written(op) {
            self.param_op(handler, dev, flash, &img)?;
        }
        let cmd = holding("command", 0);
        if written(cmd) {
            let old = word_at(&self.holding, cmd);
            self.command(handler, dev, flash, &img, old, now_ms)?;
        }
        self.holding = img;
        Ok(())
    }

    /// `param.op`: reads or writes the setting `param.id` of `param.axis`.
    fn param_op<D: Device<S, N>, F: NorFlash, const N: usize>(
        &mut self,
        handler: &mut Handler<S, N>,
        dev: &mut D,
        flash: &mut F,
        img: &[u16; HOLDING_WORDS],
    ) -> Result<(), Exception> {
        let id = word_at(img, holding("param.id", 0));
        let axis = u8::try_from(word_at(img, holding("param.axis", 0))).unwrap_or(u8::MAX);
        let value = f32::from_bits(u32_at(img, holding("param.value", 0)));
        let Ok(param) = u8::try_from(id) else {
            self.param_result = param_result::UNKNOWN;
            return Err(Exception::IllegalValue);
        };
        let req = if word_at(img, holding("param.op", 0)) == 1 {
            Request::GetParam { axis, param }
        } else {
            Request::SetParam { axis, param, value }
        };
        match handler.plc_request(dev, flash, &req) {
            Response::Param { value, .. } => {
                self.param_read_value = value;
                self.param_result = param_result::DONE;
                Ok(())
            }
            Response::Nak { nak, .. } => {
                let (result, e) = match nak.code {
                    NakCode::UnknownParam | NakCode::NoAxis => {
                        (param_result::UNKNOWN, Exception::IllegalValue)
                    }
                    NakCode::ReadOnly => (param_result::READ_ONLY, Exception::IllegalValue),
                    NakCode::NotOwner => (param_result::BUSY, Exception::IllegalFunction),
                    NakCode::ParamRange | NakCode::Refused => {
                        (param_result::RANGE, Exception::IllegalValue)
                    }
                    _ => (param_result::BUSY, Exception::DeviceFailure),
                };
                self.param_result = result;
                Err(e)
            }
            _ => {
                self.param_result = param_result::DONE;
                Ok(())
            }
        }
    }

    /// The manual-motion limits of `axis` from its `move_*` registers.
    fn limits(img: &[u16; HOLDING_WORDS], axis: u8) -> MotionLimitsMsg {
        let or = |v: u32, d: u32| if v == 0 { d } else { v };
        MotionLimitsMsg {
            vel_um_per_s: u32_at(img, holding("move_speed_um_s", axis)),
            acc_um_per_s2: or(
                u32_at(img, holding("move_acc_um_s2", axis)),
                DEFAULT_ACC_UM_S2,
            ),
            jerk_um_per_s3: or(
                u32_at(img, holding("move_jerk_um_s3", axis)),
                DEFAULT_JERK_UM_S3,
            ),
        }
    }

    /// The `command` register changed from `old` to the value in `img`.
    fn command<D: Device<S, N>, F: NorFlash, const N: usize>(
        &mut self,
        handler: &mut Handler<S, N>,
        dev: &mut D,
        flash: &mut F,
        img: &[u16; HOLDING_WORDS],
        old: u16,
        now_ms: u32,
    ) -> Result<(), Exception> {
        let new = word_at(img, holding("command", 0));
        let axis = u8::try_from(word_at(img, holding("command_axis", 0))).unwrap_or(0);
        let edge = |b: CommandBit| new & b.mask() != 0 && old & b.mask() == 0;
        let on = |b: CommandBit| new & b.mask() != 0;
        let enabled = on(CommandBit::Enable);
        let disabled_now = !enabled && old & CommandBit::Enable.mask() != 0;
        let lim = Self::limits(img, axis);
        let speed_raw = |sign: i32| {
            (lim.vel_um_per_s.min(MAX_POS_UM as u32) as i32)
                .saturating_mul(256)
                .saturating_mul(sign)
        };
        let jog_speed = if on(CommandBit::JogPos) {
            Some(speed_raw(1))
        } else if on(CommandBit::JogNeg) {
            Some(speed_raw(-1))
        } else {
            None
        };
        let holding_now = dev_state(dev) == HOLDING_CODE;
        let to_um = u32_at(img, holding("move_to_um", axis)) as i32;
        let mut reqs: heapless::Vec<(Request<'static>, bool), 10> = heapless::Vec::new();
        let mut push = |r: Request<'static>, needs_enable: bool| {
            let _ = reqs.push((r, needs_enable));
        };
        if edge(CommandBit::Stop) || disabled_now {
            push(Request::Stop, false);
        }
        if edge(CommandBit::ClearFault) {
            push(Request::ClearFault, false);
        }
        if edge(CommandBit::Hold) {
            push(Request::Hold, true);
        }
        if edge(CommandBit::Home) {
            push(Request::Home { axis }, true);
        }
        if edge(CommandBit::ActivateTable) {
            let id = u32::from(word_at(img, holding("table.select_id", 0)));
            push(Request::Activate { id }, false);
        }
        if edge(CommandBit::Move) {
            push(
                Request::MoveTo {
                    axis,
                    to_um: to_um.saturating_mul(256),
                    limits: lim,
                },
                true,
            );
        }
        if edge(CommandBit::Start) {
            let r = if holding_now {
                Request::Start
            } else {
                Request::Approach {
                    limits: Self::limits(img, 0),
                }
            };
            push(r, true);
        }
        if edge(CommandBit::Save) {
            push(Request::Save, false);
        }
        let jog_changed = match (self.jog, jog_speed) {
            (Some((a, s, _)), Some(v)) => a != axis || s != v,
            (None, None) => false,
            _ => true,
        };
        if jog_changed {
            let (speed, needs) = match jog_speed {
                Some(v) => (v, true),
                None => (0, false),
            };
            push(
                Request::Jog {
                    axis: self
                        .jog
                        .map_or(axis, |j| if jog_speed.is_some() { axis } else { j.0 }),
                    speed,
                    limits: lim,
                },
                needs,
            );
        }
        if reqs.is_empty() {
            return Ok(());
        }
        for (r, needs_enable) in &reqs {
            self.command_count = self.command_count.wrapping_add(1);
            if *needs_enable && !enabled {
                self.command_ack = ACK_ENABLE_OFF;
                return Err(Exception::DeviceFailure);
            }
            match handler.plc_request(dev, flash, r) {
                Response::Nak { nak, .. } => {
                    self.command_ack = 0x100 | u16::from(nak.code as u8);
                    return Err(if nak.code == NakCode::NotOwner {
                        Exception::IllegalFunction
                    } else {
                        Exception::DeviceFailure
                    });
                }
                _ => self.command_ack = ACK_DONE,
            }
            match r {
                Request::Approach { .. } | Request::Start | Request::MoveTo { .. } => {
                    self.plc_started = true;
                    self.heartbeat.restart(now_ms);
                }
                Request::Jog { axis, speed, .. } => {
                    self.jog = (*speed != 0).then_some((*axis, *speed, now_ms));
                    if *speed != 0 {
                        self.plc_started = true;
                        self.heartbeat.restart(now_ms);
                    }
                }
                Request::Stop => {
                    self.plc_started = false;
                    self.jog = None;
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The PLC link's periodic work at `now_ms` (call every few ms, as
    /// [`Handler::watch_link`]): renews a jog whose bit is set, and watches the
    /// heartbeat. Returns whether the heartbeat was lost now (the axes were held).
    pub fn poll<D: Device<S, N>, F: NorFlash, const N: usize>(
        &mut self,
        handler: &mut Handler<S, N>,
        dev: &mut D,
        flash: &mut F,
        now_ms: u32,
    ) -> bool {
        let owned = handler.owner() == Side::Plc;
        let timeout = handler.plc_settings().heartbeat_ms();
        if owned && self.plc_started {
            self.heartbeat.watch(now_ms, timeout);
        }
        if owned && self.plc_started && self.heartbeat.lost() {
            handler.set_plc_lost(true);
            self.jog = None;
            // Nothing left running, or held now; a refused Hold is tried at the next poll.
            let at_rest = dev.all_idle() || dev.manual_at_rest();
            if at_rest
                || matches!(
                    handler.plc_request(dev, flash, &Request::Hold),
                    Response::Ack { .. }
                )
            {
                self.plc_started = false;
            }
            return true;
        }
        if let Some((axis, speed, at)) = self.jog {
            if !owned {
                self.jog = None;
            } else if now_ms.wrapping_sub(at) >= JOG_RENEW_MS {
                let lim = Self::limits(&self.holding, axis);
                let r = Request::Jog {
                    axis,
                    speed,
                    limits: lim,
                };
                let ok = !matches!(handler.plc_request(dev, flash, &r), Response::Nak { .. });
                self.jog = ok.then_some((axis, speed, now_ms));
            }
        }
        false
    }
}

/// The serial Status' code of Holding ([`State::code`]).
const HOLDING_CODE: u8 = 2;

/// The runtime's state code as the device reports it.
fn dev_state<D: Device<S, N>, const S: usize, const N: usize>(dev: &D) -> u8 {
    let mut s = crate::protocol::msg::StatusMsg::default();
    dev.status(&mut s);
    s.state
}
