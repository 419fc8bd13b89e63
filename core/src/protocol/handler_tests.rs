//! Handler tests: the upload path, every bad-frame kind, power cuts during Save, and a
//! proptest state machine over random requests and random bytes.

use super::frame::{FrameDecoder, MAX_WIRE};
use super::handler::{encode_request, BootReason, Device, Handler, Motion, ACK_DEFERRED};
use super::msg::{
    row_len, write_row, AxisStatus, Nak, NakCode, ParamId, Request, Response, StatusMsg, Telemetry,
    NO_TABLE,
};
use super::overrides::ParamOverrides;
use super::ramflash::RamFlash;
use super::store::Store;
use super::upload::TableUpload;
use super::wire::Writer;
use crate::table::{AxisLimits, CamTable, Node, TableLimits};
use crate::units::{Master, MasterRate, PosUm, VelUmPerS};
use proptest::prelude::*;
use std::vec;
use std::vec::Vec;

pub(super) const S: usize = 1;
pub(super) const N: usize = 64;
pub(super) const SLOT: u32 = 2048;

/// A machine with one axis: a table, a running flag and an end-of-table flag.
#[derive(Clone, Debug, Default)]
pub(super) struct Mock {
    pub(super) table: Option<CamTable<S, N>>,
    pub(super) running: bool,
    ended: bool,
    pub(super) kp: f32,
    /// Refuse every table (as a device whose law cannot be built).
    refuse: bool,
    /// Narrower table limits (µm), as after a firmware update; 0: the default 500 mm.
    max_um: i32,
    /// `reset_params` fails (a device that cannot undo parameters).
    no_reset: bool,
    /// Hold commands received.
    pub(super) holds: u32,
    /// Jog commands received, and the last one's speed (I24F8 µm/s raw).
    pub(super) jogs: u32,
    pub(super) jog_speed: i32,
    /// Refuse Hold (a device whose tick did not answer).
    refuse_hold: bool,
    /// The last set-position.
    position: Option<PosUm>,
    /// A restored reference offset (`ParamId::SlaveOffsetUm`).
    offset: Option<f32>,
    /// In Manual with every slave holding.
    manual_rest: bool,
}

impl Device<S, N> for Mock {
    fn firmware(&self) -> [u8; 3] {
        [0, 1, 0]
    }
    fn period_us(&self) -> u32 {
        1000
    }
    fn table_limits(&self) -> TableLimits<S> {
        TableLimits {
            master_speed_per_s: MasterRate::from_num(1000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(0),
                max_um: PosUm::from_num(if self.max_um > 0 {
                    self.max_um
                } else {
                    500_000
                }),
                max_speed_um_per_s: VelUmPerS::from_num(1_000_000),
            }],
        }
    }
    fn active_table(&self) -> Option<&CamTable<S, N>> {
        self.table.as_ref()
    }
    fn at_safe_point(&self) -> bool {
        !self.running || self.ended
    }
    fn all_idle(&self) -> bool {
        !self.running
    }
    fn manual_at_rest(&self) -> bool {
        self.manual_rest
    }
    fn install_table(&mut self, t: &CamTable<S, N>) -> Result<(), Nak> {
        if self.refuse {
            return Err(Nak::with(NakCode::Refused, 0, 0));
        }
        self.table = Some(t.clone());
        self.ended = false;
        Ok(())
    }
    fn command(&mut self, m: Motion) -> Result<(), Nak> {
        match m {
            Motion::Start if self.table.is_none() => Err(Nak::with(NakCode::BadState, 0, 0)),
            Motion::Start => {
                self.running = true;
                Ok(())
            }
            Motion::Stop => {
                self.running = false;
                Ok(())
            }
            Motion::Hold if self.refuse_hold => Err(Nak::with(NakCode::BadState, 0xFFFF, 0)),
            Motion::Hold => {
                self.holds += 1;
                Ok(())
            }
            Motion::ClearFault => Ok(()),
            Motion::SetPosition { axis, .. } | Motion::Home { axis } if usize::from(axis) >= S => {
                Err(Nak::with(NakCode::NoAxis, u16::from(axis), 0))
            }
            Motion::SetPosition { pos_um, .. } => {
                self.position = Some(pos_um);
                Ok(())
            }
            Motion::Home { .. } => Ok(()),
            Motion::Test { .. } => {
                self.running = true;
                Ok(())
            }
            Motion::Approach { .. } if self.table.is_some() => {
                self.running = true;
                Ok(())
            }
            Motion::Jog { speed, .. } => {
                self.jogs += 1;
                self.jog_speed = speed.to_bits();
                Ok(())
            }
            Motion::MoveTo { .. } | Motion::Approach { .. } => {
                Err(Nak::with(NakCode::BadState, 0, 1))
            }
        }
    }
    fn persisted_offset_um(&self, _axis: u8) -> Option<f32> {
        self.position.map(|p| p.to_num::<f32>() - 1.0)
    }
    fn set_param(&mut self, axis: u8, p: ParamId, v: f32) -> Result<(), Nak> {
        if usize::from(axis) >= S {
            return Err(Nak::with(NakCode::UnknownParam, u16::from(axis), p as u8));
        }
        match p {
            ParamId::KpLsbPerUm if (0.0..=1000.0).contains(&v) => {
                self.kp = v;
                Ok(())
            }
            ParamId::SlaveOffsetUm => {
                self.offset = Some(v);
                Ok(())
            }
            _ => Err(Nak::with(NakCode::ParamRange, u16::from(axis), p as u8)),
        }
    }
    fn get_param(&self, axis: u8, p: ParamId) -> Result<f32, Nak> {
        match p {
            _ if usize::from(axis) >= S => {
                Err(Nak::with(NakCode::UnknownParam, u16::from(axis), p as u8))
            }
            ParamId::KpLsbPerUm => Ok(self.kp),
            ParamId::SlaveOffsetUm => Ok(self.offset.unwrap_or(0.0)),
            _ => Err(Nak::with(NakCode::UnknownParam, u16::from(axis), p as u8)),
        }
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        if self.table.is_some() || self.no_reset {
            return Err(Nak::new(NakCode::NotIdle));
        }
        self.kp = 0.0;
        Ok(())
    }
    fn status(&self, out: &mut StatusMsg) {
        out.state = u8::from(self.running);
        out.flags = u8::from(self.ended);
        out.axes.push(AxisStatus::default()).unwrap();
    }
}

/// The rig: handler, device, flash and a host-side seq counter.
pub(super) struct Rig {
    pub(super) h: Handler<S, N>,
    pub(super) dev: Mock,
    pub(super) flash: RamFlash,
    pub(super) seq: u16,
}

pub(super) fn nodes(n: usize, scale: i32) -> Vec<Node<S>> {
    (0..n)
        .map(|i| Node {
            master: Master::from_num(i as i32 * 10),
            slave_um: [PosUm::from_num(1000 + scale * i as i32)],
        })
        .collect()
}

fn rows_bytes(ns: &[Node<S>]) -> Vec<u8> {
    let mut b = std::vec![0u8; ns.len() * row_len(S)];
    let mut w = Writer::new(&mut b);
    for n in ns {
        write_row(&mut w, n).unwrap();
    }
    b
}

fn decode_all(bytes: &[u8]) -> Vec<(u16, Response)> {
    let mut d = FrameDecoder::new();
    let mut v = Vec::new();
    for &b in bytes {
        if let Some(f) = d.push(b) {
            let f = f.unwrap();
            v.push((f.seq, Response::decode(f.ty, f.payload).unwrap()));
        }
    }
    v
}

impl Rig {
    /// A rig around a handler and device that booted from `flash` (a power cycle), its
    /// session opened with Hello.
    fn booted(h: Handler<S, N>, dev: Mock, flash: RamFlash) -> Self {
        let mut r = Self {
            h,
            dev,
            flash,
            seq: 0,
        };
        assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
        r
    }

    pub(super) fn new() -> Self {
        let flash = RamFlash::new(4 * SLOT as usize);
        let store = Store::new::<_, S, N>(&flash, 0, SLOT).unwrap();
        Self {
            h: Handler::new(store),
            dev: Mock::default(),
            flash,
            seq: 0,
        }
    }

    fn raw(&mut self, bytes: &[u8]) -> Vec<(u16, Response)> {
        let mut out = Vec::new();
        self.h
            .on_bytes(&mut self.dev, &mut self.flash, bytes, &mut |f| {
                out.extend_from_slice(f)
            });
        decode_all(&out)
    }

    fn frame(seq: u16, q: &Request<'_>) -> Vec<u8> {
        let mut b = [0u8; MAX_WIRE + 1];
        let n = encode_request(seq, q, &mut b).unwrap();
        b[..n].to_vec()
    }

    /// Sends with the next seq; advances it only on a positive answer (as a host does).
    pub(super) fn req(&mut self, q: &Request<'_>) -> Response {
        let s = if matches!(q, Request::Hello) {
            self.seq
        } else {
            self.seq.wrapping_add(1)
        };
        let r = self.raw(&Self::frame(s, q));
        assert_eq!(r.len(), 1, "one answer per request");
        assert_eq!(r[0].0, s, "answer carries the request seq");
        if !matches!(r[0].1, Response::Nak { .. }) {
            self.seq = s;
        }
        r[0].1.clone()
    }

    /// SetParam of slave 0 (or a board-wide parameter), which must be acknowledged.
    pub(super) fn set_param(&mut self, param: ParamId, value: f32) {
        self.ack(&Request::SetParam {
            axis: 0,
            param: param as u8,
            value,
        });
    }

    pub(super) fn ack(&mut self, q: &Request<'_>) -> u8 {
        match self.req(q) {
            Response::Ack { req, flags } => {
                assert_eq!(req, q.ty());
                flags
            }
            r => panic!("{q:?} answered {r:?}"),
        }
    }

    /// Uploads `ns` as table `id` (core's [`TableUpload`] sequence, each step Ack'd) and
    /// returns the answer to the commit.
    pub(super) fn upload(&mut self, id: u32, ns: &[Node<S>]) -> Result<(), Nak> {
        let per = Handler::<S, N>::MAX_CHUNK_ROWS;
        let mut up = TableUpload::new(id, ns, per).unwrap();
        let mut buf = std::vec![0u8; up.chunk_bytes()];
        while let Some(q) = up.next_request(&mut buf).unwrap() {
            if !matches!(q, Request::TableCommit { .. }) {
                self.ack(&q);
                continue;
            }
            return match self.req(&q) {
                Response::Ack { .. } => Ok(()),
                Response::Nak { nak, .. } => Err(nak),
                r => panic!("{r:?}"),
            };
        }
        unreachable!("an upload ends with its commit")
    }

    /// What must not change on a Nak: active table, both flash slots, handler status.
    fn snapshot(&mut self) -> (Option<CamTable<S, N>>, Vec<u8>, u32, StatusMsg) {
        let mut st = StatusMsg::default();
        self.dev.status(&mut st);
        (
            self.dev.table.clone(),
            self.flash.mem.clone(),
            self.h.active_id(),
            st,
        )
    }
}

pub(super) fn nak_code(r: &Response) -> NakCode {
    match r {
        Response::Nak { nak, .. } => nak.code,
        r => panic!("expected a Nak, got {r:?}"),
    }
}

/// A rig with table 1 active and saved, table 2 active and saved (both slots full),
/// and a session open.
pub(super) fn loaded_rig() -> Rig {
    let mut r = Rig::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    for (id, scale) in [(1, 100), (2, 150)] {
        r.upload(id, &nodes(10, scale)).unwrap();
        assert_eq!(r.ack(&Request::Activate { id }), 0);
        r.ack(&Request::Save);
    }
    assert_eq!(r.h.active_id(), 2);
    r
}

#[test]
fn upload_activate_save_boot() {
    let mut r = Rig::new();
    match r.req(&Request::Hello) {
        Response::Info(i) => {
            assert_eq!(i.axes, 1);
            assert_eq!(i.capacity_rows, N as u16);
            assert_eq!(i.active_id, NO_TABLE);
        }
        x => panic!("{x:?}"),
    }
    assert_eq!(nak_code(&r.req(&Request::Start)), NakCode::BadState);
    // 40 rows: several chunks.
    r.upload(7, &nodes(40, 100)).unwrap();
    assert_eq!(r.ack(&Request::Activate { id: 7 }), 0);
    assert_eq!(r.h.active_id(), 7);
    r.ack(&Request::Start);
    // Saving while running is refused.
    assert_eq!(nak_code(&r.req(&Request::Save)), NakCode::NotIdle);
    // An upload while running goes to the inactive bank; activation waits for a safe point.
    let before = r.dev.table.clone();
    r.upload(8, &nodes(12, 50)).unwrap();
    assert_eq!(r.dev.table, before, "the active table kept running");
    assert_eq!(r.ack(&Request::Activate { id: 8 }), ACK_DEFERRED);
    assert_eq!(r.h.active_id(), 7);
    r.dev.ended = true;
    r.h.poll(&mut r.dev).unwrap();
    assert_eq!(r.h.active_id(), 8);
    assert_eq!(r.dev.table.as_ref().unwrap().len(), 12);
    r.ack(&Request::Stop);
    r.ack(&Request::Save);
    match r.req(&Request::GetStatus) {
        Response::Status(s) => {
            assert_eq!(s.active_id, 8);
            assert_eq!(s.saved_id, 8);
            assert_eq!(s.committed_id, NO_TABLE);
        }
        x => panic!("{x:?}"),
    }
    // Reboot from flash.
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut h2 = Handler::<S, N>::new(store);
    let mut dev2 = Mock::default();
    assert_eq!(h2.boot_report(), (None, BootReason::NoSave));
    let hd = h2.boot(&mut dev2, &mut r.flash).unwrap();
    assert_eq!(hd.id, 8);
    assert_eq!(dev2.table, r.dev.table);
    assert_eq!(h2.boot_report(), (Some(hd.slot), BootReason::Newest));
    // A blank flash boots nothing and says so.
    let mut blank = RamFlash::new(2 * SLOT as usize);
    let mut h3 = Handler::<S, N>::new(store);
    assert!(h3.boot(&mut Mock::default(), &mut blank).is_none());
    assert_eq!(h3.boot_report(), (None, BootReason::NoSave));
}

/// Settings saved before any table come back at boot with no table running; with
/// neither a table nor a changed setting there is nothing to save.
#[test]
fn settings_alone_are_saved_and_come_back_without_a_table() {
    let mut r = Rig::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    assert_eq!(nak_code(&r.req(&Request::Save)), NakCode::NothingToSave);
    r.set_param(ParamId::KpLsbPerUm, 0.5);
    r.ack(&Request::Save);
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut h2 = Handler::<S, N>::new(store);
    let mut dev2 = Mock::default();
    let hd = h2.boot(&mut dev2, &mut r.flash).unwrap();
    assert_eq!((hd.rows, hd.params, hd.id), (0, 1, NO_TABLE));
    assert_eq!(dev2.kp, 0.5);
    assert!(dev2.table.is_none());
    assert_eq!(h2.boot_report(), (Some(hd.slot), BootReason::Newest));
    // Then a table and the same settings: the next boot runs both.
    let mut r2 = Rig::booted(h2, dev2, r.flash.clone());
    r2.upload(3, &nodes(10, 100)).unwrap();
    r2.ack(&Request::Activate { id: 3 });
    r2.ack(&Request::Save);
    let mut dev3 = Mock::default();
    let hd = Handler::<S, N>::new(store)
        .boot(&mut dev3, &mut r2.flash)
        .unwrap();
    assert_eq!((hd.id, hd.rows, dev3.kp), (3, 10, 0.5));
}

/// A saved slot that cannot boot and no older one: nothing runs, and the board says
/// every saved slot was refused. A table whose install the device refuses at boot: the
/// settings alone cannot be saved over it (it would stop booting), nothing changes.
#[test]
fn none_bootable_is_reported_and_a_saved_table_is_not_replaced_by_settings_alone() {
    let mut r = loaded_rig();
    r.set_param(ParamId::KpLsbPerUm, 0.5);
    r.ack(&Request::Save);
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut narrow = Mock {
        max_um: 1_000,
        ..Mock::default()
    };
    let mut h = Handler::<S, N>::new(store);
    assert!(h.boot(&mut narrow, &mut r.flash).is_none());
    assert_eq!(h.boot_report(), (None, BootReason::NoneBootable));
    assert_eq!(narrow.kp, 0.0, "the refused slot's kp is undone");
    // The device refuses the table's install at boot: it is the saved one, not running.
    let mut refusing = Mock {
        refuse: true,
        ..Mock::default()
    };
    let mut h = Handler::<S, N>::new(store);
    let _ = h.boot(&mut refusing, &mut r.flash);
    let mut r2 = Rig::booted(h, refusing, r.flash.clone());
    r2.set_param(ParamId::KpLsbPerUm, 0.25);
    match r2.req(&Request::Save) {
        Response::Nak { nak, .. } => {
            assert_eq!(nak, Nak::with(NakCode::NothingToSave, 1, 0));
        }
        x => panic!("{x:?}"),
    }
}

/// GetParam reads what SetParam set (and the handler's own link timeout); read-only and
/// unknown parameters are typed refusals; Status reports the boot.
#[test]
fn get_param_reads_back_and_read_only_params_are_refused() {
    let mut r = loaded_rig();
    let get = |r: &mut Rig, axis, p: ParamId| {
        r.req(&Request::GetParam {
            axis,
            param: p as u8,
        })
    };
    r.set_param(ParamId::KpLsbPerUm, 0.5);
    assert_eq!(
        get(&mut r, 0, ParamId::KpLsbPerUm),
        Response::Param {
            axis: 0,
            param: ParamId::KpLsbPerUm as u8,
            value: 0.5
        }
    );
    r.set_param(ParamId::LinkTimeoutMs, 250.0);
    assert!(matches!(
        get(&mut r, 0, ParamId::LinkTimeoutMs),
        Response::Param { value, .. } if value == 250.0
    ));
    for p in [ParamId::PeriodUs, ParamId::SlaveOffsetUm] {
        let n = r.req(&Request::SetParam {
            axis: 0,
            param: p as u8,
            value: 1.0,
        });
        assert_eq!(
            n,
            Response::Nak {
                req: super::msg::ty::SET_PARAM,
                nak: Nak::with(NakCode::ReadOnly, 0, p as u8)
            }
        );
    }
    assert_eq!(
        nak_code(&get(&mut r, 3, ParamId::KpLsbPerUm)),
        NakCode::UnknownParam
    );
    assert_eq!(
        nak_code(&r.req(&Request::GetParam {
            axis: 0,
            param: 200
        })),
        NakCode::UnknownParam
    );
    match r.req(&Request::GetStatus) {
        Response::Status(s) => assert_eq!((s.boot_slot, s.boot_reason), (0xFF, 0)),
        x => panic!("{x:?}"),
    }
}

#[test]
fn saved_parameters_come_back_at_boot() {
    let mut r = loaded_rig();
    r.set_param(ParamId::KpLsbPerUm, 0.5);
    r.set_param(ParamId::KpLsbPerUm, 0.75);
    // A refused value is not recorded.
    r.req(&Request::SetParam {
        axis: 0,
        param: ParamId::KpLsbPerUm as u8,
        value: -1.0,
    });
    r.ack(&Request::Save);
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut h2 = Handler::<S, N>::new(store);
    let mut dev2 = Mock::default();
    let hd = h2.boot(&mut dev2, &mut r.flash).unwrap();
    assert_eq!((hd.id, hd.params), (2, 1));
    assert_eq!(dev2.kp, 0.75);
    assert_eq!(dev2.table, r.dev.table);
    // Saved again after that boot without a SetParam: the parameter is still stored.
    let mut r3 = Rig::booted(h2, dev2, r.flash.clone());
    r3.ack(&Request::Save);
    let mut dev4 = Mock::default();
    let hd = Handler::<S, N>::new(store)
        .boot(&mut dev4, &mut r3.flash)
        .unwrap();
    assert_eq!(hd.generation, 4, "a new slot was written");
    assert_eq!(dev4.kp, 0.75);
}

/// A slot is a table and its parameters: when the newest slot's table is refused at boot
/// (here: limits narrowed by a firmware update), its parameters are undone before the
/// older slot boots — the board never runs one slot's table with another's gains.
#[test]
fn a_refused_slot_leaves_none_of_its_parameters() {
    let mut r = Rig::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    // Slot 1: table 1 (1.0 … 1.9 mm), no parameter.
    r.upload(1, &nodes(10, 100)).unwrap();
    r.ack(&Request::Activate { id: 1 });
    r.ack(&Request::Save);
    // Slot 2: kp 0.75 and table 2 (1 … 28 mm).
    r.set_param(ParamId::KpLsbPerUm, 0.75);
    r.upload(2, &nodes(10, 3000)).unwrap();
    r.ack(&Request::Activate { id: 2 });
    r.ack(&Request::Save);
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    // Same board: slot 2 with its parameter.
    let mut dev = Mock::default();
    let hd = Handler::<S, N>::new(store)
        .boot(&mut dev, &mut r.flash)
        .unwrap();
    assert_eq!((hd.id, hd.params, dev.kp), (2, 1, 0.75));
    // Limits narrowed to 20 mm: slot 2's table is refused, slot 1 boots with the boot kp.
    let mut dev = Mock {
        max_um: 20_000,
        ..Mock::default()
    };
    let mut h = Handler::<S, N>::new(store);
    let hd = h.boot(&mut dev, &mut r.flash).unwrap();
    assert_eq!((hd.id, hd.params), (1, 0));
    assert_eq!(h.boot_report(), (Some(hd.slot), BootReason::FallbackTable));
    assert_eq!(dev.kp, 0.0, "slot 2's kp must not stay applied");
    assert_eq!(dev.table.as_ref().map(|t| t.len()), Some(10));
    // A device that cannot undo parameters boots no table rather than a mix.
    let mut dev = Mock {
        max_um: 20_000,
        no_reset: true,
        ..Mock::default()
    };
    assert!(Handler::<S, N>::new(store)
        .boot(&mut dev, &mut r.flash)
        .is_none());
    assert!(dev.table.is_none());
}

#[test]
fn set_param_and_telemetry() {
    let mut r = Rig::new();
    r.req(&Request::Hello);
    r.set_param(ParamId::KpLsbPerUm, 0.5);
    assert_eq!(r.dev.kp, 0.5);
    let n = r.req(&Request::SetParam {
        axis: 0,
        param: ParamId::KpLsbPerUm as u8,
        value: -1.0,
    });
    assert_eq!(nak_code(&n), NakCode::ParamRange);
    let n = r.req(&Request::SetParam {
        axis: 0,
        param: 200,
        value: 1.0,
    });
    assert_eq!(nak_code(&n), NakCode::UnknownParam);
    r.ack(&Request::SetTelemetry { decimation: 10 });
    let mut out = Vec::new();
    for k in 0..100u32 {
        r.h.on_tick(&mut |f| out.extend_from_slice(f), || Telemetry {
            tick: k,
            ..Default::default()
        });
    }
    let tel = decode_all(&out);
    assert_eq!(tel.len(), 10);
    assert!(matches!(&tel[9].1, Response::Telemetry(t) if t.tick == 99));
}

/// Every bad-frame kind gets its Nak code and changes nothing.
#[test]
fn bad_frames_change_nothing() {
    let mut r = loaded_rig();
    // Leave an upload half done, to check chunks cannot be mixed up either.
    r.ack(&Request::TableBegin {
        id: 9,
        columns: 1,
        rows: 4,
    });
    let two = rows_bytes(&nodes(2, 10));
    r.ack(&Request::TableChunk {
        offset: 0,
        count: 2,
        data: &two,
    });
    let good_next = r.seq.wrapping_add(1);
    let cases: Vec<(&str, Vec<u8>, NakCode)> = {
        // A Stop frame whose CRC is off by one bit (valid COBS).
        let mut body = std::vec![0u8; 3];
        body[..2].copy_from_slice(&good_next.to_le_bytes());
        body[2] = 0x21;
        let c = super::frame::crc32(&body) ^ 0x0100;
        body.extend_from_slice(&c.to_le_bytes());
        let mut enc = [0u8; 16];
        let n = cobs::encode(&body, &mut enc);
        let mut crc = enc[..n].to_vec();
        crc.push(0);
        // A frame with a valid CRC but only 5 bytes: below the 7-byte minimum.
        let mut short = [0u8; 16];
        let n = cobs::encode(&[1, 2, 3, 4, 5], &mut short);
        let mut short = short[..n].to_vec();
        short.push(0);
        let mut big = std::vec![0x42u8; MAX_WIRE + 40];
        big.push(0);
        // Right CRC, payload one byte short of a TableBegin.
        let mut p = [0u8; 16];
        let n = Request::TableBegin {
            id: 3,
            columns: 1,
            rows: 3,
        }
        .encode(&mut p)
        .unwrap();
        let mut f = [0u8; 64];
        let m = super::frame::encode(good_next, 0x10, &p[..n - 1], &mut f).unwrap();
        let trunc_payload = f[..m].to_vec();
        let m = super::frame::encode(good_next, 0x10, &[0; 12], &mut f).unwrap();
        let long_payload = f[..m].to_vec();
        let m = super::frame::encode(good_next, 0x5A, &[], &mut f).unwrap();
        let unknown = f[..m].to_vec();
        let bad_cobs = std::vec![0x05, 0x01, 0x00];
        let three = rows_bytes(&nodes(3, 10));
        std::vec![
            ("corrupted", crc, NakCode::Crc),
            ("truncated frame", short, NakCode::Truncated),
            ("truncated payload", trunc_payload, NakCode::Truncated),
            ("oversized", big, NakCode::Oversized),
            ("too long payload", long_payload, NakCode::Length),
            ("unknown type", unknown, NakCode::UnknownType),
            ("framing", bad_cobs, NakCode::Framing),
            (
                "duplicated",
                Rig::frame(r.seq, &Request::Start),
                NakCode::Duplicate
            ),
            (
                "out of order",
                Rig::frame(good_next.wrapping_add(3), &Request::Stop),
                NakCode::OutOfOrder
            ),
            (
                "chunk replayed",
                Rig::frame(
                    good_next,
                    &Request::TableChunk {
                        offset: 0,
                        count: 2,
                        data: &two
                    }
                ),
                NakCode::ChunkOffset
            ),
            (
                "chunk past end",
                Rig::frame(
                    good_next,
                    &Request::TableChunk {
                        offset: 2,
                        count: 3,
                        data: &three
                    }
                ),
                NakCode::TooManyRows
            ),
            (
                "incomplete",
                Rig::frame(good_next, &Request::TableCommit { crc: 0 }),
                NakCode::Incomplete
            ),
            (
                "wrong columns",
                Rig::frame(
                    good_next,
                    &Request::TableBegin {
                        id: 5,
                        columns: 3,
                        rows: 4
                    }
                ),
                NakCode::Columns
            ),
            (
                "too many rows",
                Rig::frame(
                    good_next,
                    &Request::TableBegin {
                        id: 5,
                        columns: 1,
                        rows: N as u16 + 1
                    }
                ),
                NakCode::TooManyRows
            ),
            (
                "unknown table",
                Rig::frame(good_next, &Request::Activate { id: 77 }),
                NakCode::UnknownTable
            ),
        ]
    };
    for (what, bytes, code) in cases {
        let before = r.snapshot();
        let resp = r.raw(&bytes);
        assert_eq!(resp.len(), 1, "{what}: one answer");
        assert_eq!(nak_code(&resp[0].1), code, "{what}");
        assert_eq!(r.snapshot(), before, "{what} changed something");
    }
    // The session still works with the expected seq, and the upload resumes.
    r.ack(&Request::TableChunk {
        offset: 2,
        count: 2,
        data: &rows_bytes(&nodes(4, 10)[2..]),
    });
    let all = rows_bytes(&nodes(4, 10));
    let before = r.snapshot();
    let n = r.req(&Request::TableCommit {
        crc: super::frame::crc32(&all) ^ 1,
    });
    assert_eq!(nak_code(&n), NakCode::TableCrc);
    assert_eq!(r.snapshot(), before);
    r.ack(&Request::TableCommit {
        crc: super::frame::crc32(&all),
    });
}

/// Invalid tables get the CamTable rule that failed, and change nothing.
#[test]
fn a_table_the_device_refuses_changes_nothing() {
    let mut r = Rig::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    r.upload(7, &nodes(40, 100)).unwrap();
    r.ack(&Request::Activate { id: 7 });
    r.ack(&Request::Start);
    // Immediate activation refused: typed Nak, the running table and its id stay.
    r.dev.ended = true;
    r.dev.refuse = true;
    r.upload(8, &nodes(12, 50)).unwrap();
    let before = r.dev.table.clone();
    assert_eq!(
        nak_code(&r.req(&Request::Activate { id: 8 })),
        NakCode::Refused
    );
    assert_eq!(r.h.active_id(), 7);
    assert_eq!(r.dev.table, before);
    // Deferred activation refused at the safe point: poll reports it, the id stays.
    r.dev.ended = false;
    r.upload(9, &nodes(12, 50)).unwrap();
    assert_eq!(r.ack(&Request::Activate { id: 9 }), ACK_DEFERRED);
    r.dev.ended = true;
    assert_eq!(
        r.h.poll(&mut r.dev).map_err(|n| n.code),
        Err(NakCode::Refused)
    );
    assert_eq!(r.h.active_id(), 7);
    assert_eq!(r.dev.table, before);
    match r.req(&Request::GetStatus) {
        Response::Status(s) => assert_eq!(s.active_id, 7),
        x => panic!("{x:?}"),
    }
}

#[test]
fn invalid_tables_are_refused() {
    let mut r = loaded_rig();
    let mut not_mono = nodes(6, 10);
    not_mono[3].master = not_mono[2].master;
    let mut out_of_range = nodes(6, 10);
    out_of_range[4].slave_um[0] = PosUm::from_num(600_000);
    let mut steep = nodes(6, 10);
    // 10 counts at 1000 counts/s = 10 ms; 20 mm in 10 ms = 2 m/s > 1 m/s.
    steep[5].slave_um[0] = steep[4].slave_um[0] + PosUm::from_num(20_000);
    for (ns, code, row) in [
        (not_mono, NakCode::TableNotMonotonic, 3),
        (out_of_range, NakCode::TableOutOfRange, 4),
        (steep, NakCode::TableTooSteep, 5),
    ] {
        let before = r.snapshot();
        let nak = r.upload(11, &ns).unwrap_err();
        assert_eq!((nak.code, nak.detail), (code, row));
        assert_eq!(r.dev.table, before.0);
        assert_eq!(r.flash.mem, before.1);
        assert_eq!(
            nak_code(&r.req(&Request::Activate { id: 11 })),
            NakCode::UnknownTable
        );
        r.ack(&Request::TableAbort);
    }
    let n = r.req(&Request::TableBegin {
        id: 12,
        columns: 1,
        rows: 1,
    });
    assert_eq!(nak_code(&n), NakCode::TableTooFewNodes);
}

/// A power cut at every operation of a Save leaves a bootable valid table: the old or
/// the new.
#[test]
fn power_cut_at_every_byte_of_save() {
    let mut r = loaded_rig();
    r.upload(3, &nodes(30, 120)).unwrap();
    r.ack(&Request::Activate { id: 3 });
    let old = loaded_rig().dev.table.unwrap();
    let new = r.dev.table.clone().unwrap();
    let base = r.flash.clone();
    // Count the flash operations of a complete Save.
    let mut f = base.clone();
    let ops0 = f.ops;
    let store = Store::new::<_, S, N>(&f, 0, SLOT).unwrap();
    // The new slot also carries a changed parameter.
    let mut params = ParamOverrides::new();
    params.record(0, ParamId::KpLsbPerUm, 0.25);
    store.save(&mut f, 3, &new, &params).unwrap();
    let total = f.ops - ops0;
    // One sector erase, then the slot word by word (32-byte header, one 6-byte
    // parameter record, 30 rows of 12 bytes, the CRC and the commit record).
    assert!(
        total > (32 + 6 + 30 * 12) / 4,
        "a save erases a slot and writes it: {total}"
    );
    std::eprintln!("save: {total} flash operations");
    let (mut saw_old, mut saw_new) = (0, 0);
    for cut in 0..=total {
        let mut f = base.clone();
        f.cut_after(cut);
        let res = store.save(&mut f, 3, &new, &params);
        assert_eq!(res.is_ok(), cut == total, "cut {cut}");
        f.power_on();
        let mut h = Handler::<S, N>::new(store);
        let mut dev = Mock::default();
        let hd = h.boot(&mut dev, &mut f).expect("bootable after a cut");
        let t = dev.table.unwrap();
        if hd.id == 3 {
            assert_eq!(t, new);
            assert_eq!(dev.kp, 0.25, "the new table comes with its parameters");
            saw_new += 1;
        } else {
            assert_eq!(hd.id, 2);
            assert_eq!(t, old);
            assert_eq!(dev.kp, 0.0, "the old table with the old parameters");
            saw_old += 1;
        }
    }
    assert_eq!(saw_new, 1, "only the complete save shows the new table");
    assert_eq!(saw_old, total);
}

/// One step of the random walk.
#[derive(Clone, Debug)]
enum Op {
    Hello,
    Begin(u8, u16),
    Chunk(u16, u8, i32),
    Commit(bool),
    Activate(u32),
    Start,
    Stop,
    End,
    Save,
    Status,
    /// A commissioning request with random fields (GetFaults, CaptureArm, GetCapture,
    /// VirtualMaster): never changes a table.
    Diag(u8, u8, u8, i32, u32, u32),
    /// A valid request with a wrong seq offset.
    Reseq(i8),
    /// Flip a byte of the next valid request.
    Corrupt(usize, u8),
    /// Random bytes.
    Noise(Vec<u8>),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        Just(Op::Hello),
        (0u8..3, 0u16..70).prop_map(|(c, r)| Op::Begin(c, r)),
        (0u16..70, 0u8..12, -50i32..300).prop_map(|(o, c, s)| Op::Chunk(o, c, s)),
        any::<bool>().prop_map(Op::Commit),
        (0u32..4).prop_map(Op::Activate),
        Just(Op::Start),
        Just(Op::Stop),
        Just(Op::End),
        Just(Op::Save),
        Just(Op::Status),
        (
            0u8..4,
            any::<u8>(),
            any::<u8>(),
            any::<i32>(),
            any::<u32>(),
            any::<u32>()
        )
            .prop_map(|(k, a, b, v, p, q)| Op::Diag(k, a, b, v, p, q)),
        any::<i8>().prop_map(Op::Reseq),
        (any::<usize>(), 1u8..=255).prop_map(|(i, x)| Op::Corrupt(i, x)),
        proptest::collection::vec(any::<u8>(), 0..40).prop_map(Op::Noise),
    ]
}

fn fuzz_cases() -> u32 {
    crate::env_cases("HYDRA_FUZZ_CASES", 200)
}

/// Replays a sequence, tracking the table the host last committed successfully.
fn run_ops(ops: &[Op]) {
    let mut r = Rig::new();
    let mut next_id = 1u32;
    let mut rows_sent: Vec<Node<S>> = Vec::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    for o in ops {
        let before = r.snapshot();
        let seq = r.seq.wrapping_add(1);
        let (resp, raw) = match o {
            Op::Hello => (r.raw(&Rig::frame(r.seq, &Request::Hello)), false),
            Op::Begin(c, n) => {
                next_id += 1;
                rows_sent.clear();
                (
                    r.raw(&Rig::frame(
                        seq,
                        &Request::TableBegin {
                            id: next_id,
                            columns: *c,
                            rows: *n,
                        },
                    )),
                    false,
                )
            }
            Op::Chunk(off, c, scale) => {
                let ns: Vec<Node<S>> = (0..*c as usize)
                    .map(|i| Node {
                        master: Master::from_num((rows_sent.len() + i) as i32 * 10),
                        slave_um: [PosUm::from_num(1000 + scale * (rows_sent.len() + i) as i32)],
                    })
                    .collect();
                let resp = r.raw(&Rig::frame(
                    seq,
                    &Request::TableChunk {
                        offset: *off,
                        count: *c,
                        data: &rows_bytes(&ns),
                    },
                ));
                if matches!(resp.first(), Some((_, Response::Ack { .. }))) {
                    rows_sent.extend_from_slice(&ns);
                }
                (resp, false)
            }
            Op::Commit(right) => {
                let crc = super::frame::crc32(&rows_bytes(&rows_sent)) ^ u32::from(!right);
                (
                    r.raw(&Rig::frame(seq, &Request::TableCommit { crc })),
                    false,
                )
            }
            Op::Activate(k) => (
                r.raw(&Rig::frame(
                    seq,
                    &Request::Activate {
                        id: next_id.wrapping_sub(*k),
                    },
                )),
                false,
            ),
            Op::Start => (r.raw(&Rig::frame(seq, &Request::Start)), false),
            Op::Stop => (r.raw(&Rig::frame(seq, &Request::Stop)), false),
            Op::End => {
                r.dev.ended = true;
                let _ = r.h.poll(&mut r.dev);
                continue;
            }
            Op::Save => (r.raw(&Rig::frame(seq, &Request::Save)), false),
            Op::Status => (r.raw(&Rig::frame(seq, &Request::GetStatus)), false),
            Op::Diag(kind, a, b, v, p, q) => {
                let req = match kind {
                    0 => Request::GetFaults,
                    1 => Request::CaptureArm(super::diag::CaptureArmMsg {
                        trigger: *a,
                        channel: *b,
                        axis: *a,
                        value: *v,
                        pre: *p,
                        post: *q,
                    }),
                    2 => Request::GetCapture {
                        offset: *p,
                        count: *b,
                    },
                    _ => Request::VirtualMaster {
                        op: *a,
                        speed_scale: *v as f32,
                    },
                };
                let before = r.snapshot();
                let resp = r.raw(&Rig::frame(seq, &req));
                assert_eq!(r.snapshot(), before, "{req:?} changed a table");
                (resp, false)
            }
            Op::Reseq(d) => {
                let s = seq.wrapping_add(*d as u16);
                (r.raw(&Rig::frame(s, &Request::Stop)), false)
            }
            Op::Corrupt(i, x) => {
                let mut f = Rig::frame(seq, &Request::Save);
                let k = i % f.len();
                f[k] ^= x;
                // Resynchronise like a host does after noise.
                let mut b = std::vec![0u8];
                b.extend_from_slice(&f);
                b.push(0);
                (r.raw(&b), true)
            }
            Op::Noise(v) => {
                let mut b = v.clone();
                b.push(0);
                (r.raw(&b), true)
            }
        };
        if !raw {
            assert_eq!(resp.len(), 1, "{o:?}: exactly one answer");
        }
        for (s, x) in &resp {
            match x {
                Response::Nak { .. } => {
                    if resp.len() == 1 {
                        assert_eq!(
                            r.snapshot(),
                            before,
                            "{o:?} was refused but changed something"
                        );
                    }
                }
                Response::Telemetry(_) => panic!("no telemetry was asked for"),
                _ => r.seq = *s,
            }
        }
        // Invariants: a table is active iff an id is; both slots are never invalid at once
        // after a successful save; a running machine always has a table.
        assert_eq!(r.dev.table.is_some(), r.h.active_id() != NO_TABLE);
        if r.dev.running {
            assert!(r.dev.table.is_some());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: fuzz_cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// The decoder and the handler take any sequence of requests and bytes without
    /// panicking, answer each request once, and change nothing when they say Nak.
    #[test]
    fn state_machine_fuzz(ops in proptest::collection::vec(op(), 1..40)) {
        run_ops(&ops);
    }

    /// Any bytes at all: never a panic, never more answers than delimiters.
    #[test]
    fn decoder_fuzz(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut r = Rig::new();
        let resp = r.raw(&bytes);
        let zeros = bytes.iter().filter(|b| **b == 0).count();
        prop_assert!(resp.len() <= zeros);
        prop_assert!(r.dev.table.is_none());
        prop_assert!(r.flash.mem.iter().all(|b| *b == 0xFF));
    }
}

/// The host-link watchdog: off by default; once set, a Start from the link followed by
/// silence longer than the timeout holds the axes (one Hold) and is reported in Status
/// until the next Start; frames keep it quiet; bad timeouts are refused.
#[test]
fn link_watchdog_holds_after_silence_only_when_set() {
    let mut r = loaded_rig();
    r.ack(&Request::Start);
    assert!(!r.h.watch_link(&mut r.dev, 0));
    assert!(!r.h.watch_link(&mut r.dev, 1_000_000), "off by default");
    r.ack(&Request::Stop);
    for bad in [5.0, 60_001.0, f32::NAN, -1.0] {
        let q = Request::SetParam {
            axis: 0,
            param: ParamId::LinkTimeoutMs as u8,
            value: bad,
        };
        assert_eq!(nak_code(&r.req(&q)), NakCode::ParamRange, "{bad}");
    }
    r.set_param(ParamId::LinkTimeoutMs, 100.0);
    // Not started from the link: silence is fine.
    assert!(!r.h.watch_link(&mut r.dev, 2_000_000));
    r.ack(&Request::Start);
    let t0 = 3_000_000;
    assert!(!r.h.watch_link(&mut r.dev, t0), "the Start frame was seen");
    assert!(!r.h.watch_link(&mut r.dev, t0 + 60));
    // A frame at +60 ms keeps it alive past +100.
    let _ = r.req(&Request::GetStatus);
    assert!(!r.h.watch_link(&mut r.dev, t0 + 90));
    assert!(!r.h.watch_link(&mut r.dev, t0 + 150));
    assert_eq!(r.dev.holds, 0);
    // A Hold the device refuses is not reported as a hold and is tried again.
    r.dev.refuse_hold = true;
    assert!(!r.h.watch_link(&mut r.dev, t0 + 191), "refused Hold");
    let flags0 = match r.req(&Request::GetStatus) {
        Response::Status(s) => s.flags,
        x => panic!("{x:?}"),
    };
    assert_eq!(flags0 & super::msg::FLAG_LINK_LOST, 0);
    r.dev.refuse_hold = false;
    // The GetStatus above was a frame: silence restarts from it (at t0 + 191).
    assert!(!r.h.watch_link(&mut r.dev, t0 + 191));
    assert!(r.h.watch_link(&mut r.dev, t0 + 292), "100 ms of silence");
    assert_eq!(r.dev.holds, 1);
    assert!(
        !r.h.watch_link(&mut r.dev, t0 + 500),
        "one Hold, not one per call"
    );
    let flags = |r: &mut Rig| match r.req(&Request::GetStatus) {
        Response::Status(s) => s.flags,
        x => panic!("{x:?}"),
    };
    assert_ne!(flags(&mut r) & super::msg::FLAG_LINK_LOST, 0);
    r.ack(&Request::Start);
    assert_eq!(flags(&mut r) & super::msg::FLAG_LINK_LOST, 0);
    // Wraps with the millisecond clock.
    r.ack(&Request::Stop);
    r.ack(&Request::Start);
    assert!(!r.h.watch_link(&mut r.dev, u32::MAX - 10));
    assert!(r.h.watch_link(&mut r.dev, 95));
}

/// A TestMove of an unknown profile is refused naming why; an accepted one is watched by
/// the link watchdog like a Start (a silent host holds the axes: the test ends).
#[test]
fn a_test_move_is_checked_and_watched_by_the_link_watchdog() {
    use super::msg::{motion_reason, TestMoveMsg};
    let mut r = loaded_rig();
    let test = |profile: u8| Request::TestMove {
        axis: 0,
        test: TestMoveMsg {
            profile,
            amplitude_um: 500,
            duration_ms: 1000,
            dwell_ms: 100,
            f_start_mhz: 0,
            f_end_mhz: 0,
        },
    };
    match r.req(&test(3)) {
        Response::Nak { nak, .. } => {
            assert_eq!(
                (nak.code, nak.detail2),
                (NakCode::Motion, motion_reason::TEST_SPEC)
            )
        }
        x => panic!("{x:?}"),
    }
    r.set_param(ParamId::LinkTimeoutMs, 100.0);
    r.ack(&test(0));
    let t0 = 1_000_000;
    assert!(
        !r.h.watch_link(&mut r.dev, t0),
        "the TestMove frame was seen"
    );
    assert!(r.h.watch_link(&mut r.dev, t0 + 101), "100 ms of silence");
    assert_eq!(r.dev.holds, 1);
    // A test that ended by itself leaves the slaves holding in Manual: the watch ends
    // there, no Hold and no link-lost flag for a host that went away afterwards.
    r.ack(&test(0));
    r.dev.manual_rest = true;
    let t1 = 2_000_000;
    assert!(!r.h.watch_link(&mut r.dev, t1));
    assert!(!r.h.watch_link(&mut r.dev, t1 + 500));
    assert_eq!(r.dev.holds, 1);
    match r.req(&Request::GetStatus) {
        Response::Status(st) => assert_eq!(st.flags & super::msg::FLAG_LINK_LOST, 0),
        x => panic!("{x:?}"),
    }
}

/// A set-position on an absolute axis is persisted (as its reference offset) by Save and
/// restored at boot; the link timeout too.
#[test]
fn set_position_offset_and_link_timeout_are_saved() {
    let mut r = loaded_rig();
    r.ack(&Request::SetPosition {
        axis: 0,
        pos_um: PosUm::from_num(250).to_bits(),
    });
    assert_eq!(r.dev.position, Some(PosUm::from_num(250)));
    assert_eq!(
        nak_code(&r.req(&Request::Home { axis: 3 })),
        NakCode::NoAxis
    );
    r.set_param(ParamId::LinkTimeoutMs, 250.0);
    r.ack(&Request::Save);
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut h2 = Handler::<S, N>::new(store);
    let mut dev2 = Mock::default();
    let hd = h2.boot(&mut dev2, &mut r.flash).unwrap();
    assert_eq!(hd.params, 2);
    // The mock's absolute offset is position − 1 µm.
    assert_eq!(dev2.offset, Some(249.0));
    // The restored timeout acts after a Start.
    dev2.running = true;
    let mut r2 = Rig::booted(h2, dev2, r.flash.clone());
    r2.ack(&Request::Start);
    assert!(!r2.h.watch_link(&mut r2.dev, 10));
    assert!(r2.h.watch_link(&mut r2.dev, 261));
}

/// A committed table that a later SetParam makes invalid is refused at
/// Activate (typed, naming the row), and nothing changes.
#[test]
fn activate_rechecks_the_limits_in_force() {
    let mut r = loaded_rig();
    // Table 3 rises to 1000 + 9·3000 µm = 28 mm.
    r.upload(3, &nodes(10, 3000)).unwrap();
    r.dev.max_um = 20_000;
    let before = r.dev.table.clone();
    match r.req(&Request::Activate { id: 3 }) {
        Response::Nak { nak, .. } => {
            assert_eq!(nak.code, NakCode::TableOutOfRange);
        }
        x => panic!("{x:?}"),
    }
    assert_eq!(r.dev.table, before, "the running table is unchanged");
    assert_eq!(r.h.active_id(), 2);
    // Deferred: armed while running, the limits narrowed, then refused at the safe point.
    r.dev.max_um = 0;
    r.ack(&Request::Start);
    assert_eq!(r.ack(&Request::Activate { id: 3 }), ACK_DEFERRED);
    r.dev.max_um = 20_000;
    r.dev.ended = true;
    assert_eq!(
        r.h.poll(&mut r.dev).map_err(|n| n.code),
        Err(NakCode::TableOutOfRange)
    );
    assert_eq!(r.h.active_id(), 2);
    assert_eq!(r.dev.table, before);
}

/// After a fallback boot (the newer slot refused), Save writes over
/// the refused slot and never erases the one that booted: a power cut at any point of that
/// Save still boots a table.
#[test]
fn save_after_a_fallback_boot_keeps_the_slot_that_booted() {
    let mut r = loaded_rig();
    // Slot 0 = table 1 (gen 1), slot 1 = table 2 (gen 2). Narrow the limits so table 2
    // (up to 2.35 mm) is refused at boot and table 1 (up to 1.9 mm) boots.
    let limited = || Mock {
        max_um: 2000,
        ..Mock::default()
    };
    let store = Store::new::<_, S, N>(&r.flash, 0, SLOT).unwrap();
    let mut h = Handler::<S, N>::new(store);
    let mut dev = limited();
    let hd = h.boot(&mut dev, &mut r.flash).unwrap();
    assert_eq!((hd.id, hd.slot), (1, 0));
    let image = r.flash.clone();
    let mut r2 = Rig::booted(h, dev, r.flash.clone());
    r2.ack(&Request::Save);
    // The new save went to slot 1; slot 0 (what booted) is intact.
    let mut dev3 = limited();
    let hd3 = Handler::<S, N>::new(store)
        .boot(&mut dev3, &mut r2.flash)
        .unwrap();
    assert_eq!((hd3.id, hd3.slot, hd3.generation), (1, 1, 3));
    assert_eq!(
        store.scan::<_, S, N>(&mut r2.flash, 0).map(|h| h.id),
        Some(1),
        "the slot that booted was kept"
    );
    // Every power cut during that Save leaves a bootable table.
    let total = image.mem.len();
    let mut cuts = 0;
    // A Save here is ≈ 120 operations (one sector erase, then the slot word by word).
    for cut in 0..160 {
        let mut f = image.clone();
        f.cut_after(cut);
        let store = Store::new::<_, S, N>(&f, 0, SLOT).unwrap();
        let mut hh = Handler::<S, N>::new(store);
        let mut d = limited();
        let _ = hh.boot(&mut d, &mut f);
        let mut rr = Rig {
            h: hh,
            dev: d,
            flash: f,
            seq: 0,
        };
        assert!(matches!(rr.req(&Request::Hello), Response::Info(_)));
        let _ = rr.req(&Request::Save);
        rr.flash.power_on();
        let mut d2 = limited();
        assert!(
            Handler::<S, N>::new(store)
                .boot(&mut d2, &mut rr.flash)
                .is_some(),
            "no bootable table after a cut at flash operation {cut} (flash of {total} B)"
        );
        cuts += 1;
    }
    assert!(cuts >= 160);
}
