//! Messages: type codes, payload layouts (all little-endian) and Nak codes.
//!
//! Requests (host → board) and responses (board → host) share the frame format of
//! [`super::frame`]. Every request is answered by exactly one response carrying the
//! request's `seq`: `Ack`, `Nak`, or for `Hello`/`GetStatus` an `Info`/`Status`.
//! `Telemetry` frames are unsolicited; their `seq` is the board's own telemetry counter.
//! Byte-by-byte layouts are in `PROTOCOL.md` at the repository root.

pub use super::settings::ParamId;
use super::wire::{Reader, Writer};
use crate::table::{Node, TableError};
use crate::units::{Master, PosUm};
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// Protocol version reported in `Info`.
pub const PROTOCOL_VERSION: u8 = 9;
/// Most axes a `Status`/`Telemetry` message can describe.
pub const MAX_AXES: usize = 8;
/// "No table" in id fields.
pub const NO_TABLE: u32 = u32::MAX;

/// Message type codes.
pub mod ty {
    /// Request: open a session, get [`super::Info`].
    pub const HELLO: u8 = 0x01;
    /// Request: get [`super::StatusMsg`].
    pub const GET_STATUS: u8 = 0x02;
    /// Request: start an upload into the inactive bank.
    pub const TABLE_BEGIN: u8 = 0x10;
    /// Request: rows of the upload.
    pub const TABLE_CHUNK: u8 = 0x11;
    /// Request: end the upload, check its CRC, validate the table.
    pub const TABLE_COMMIT: u8 = 0x12;
    /// Request: drop the upload.
    pub const TABLE_ABORT: u8 = 0x13;
    /// Request: make a committed table active (at a safe point).
    pub const ACTIVATE: u8 = 0x14;
    /// Request: Idle → Following.
    pub const START: u8 = 0x20;
    /// Request: → Idle (valves to null).
    pub const STOP: u8 = 0x21;
    /// Request: Following → Holding.
    pub const HOLD: u8 = 0x22;
    /// Request: clear a latched fault.
    pub const CLEAR_FAULT: u8 = 0x23;
    /// Request: set-position — a slave is at a stated position (Idle or Fault).
    pub const SET_POSITION: u8 = 0x24;
    /// Request: arm homing of a slave (referenced at its next reference edge).
    pub const HOME: u8 = 0x25;
    /// Request: jog a slave (renew every 100 ms: the deadman stops it after 300 ms).
    pub const JOG: u8 = 0x26;
    /// Request: move a slave to a position by the S-curve.
    pub const MOVE_TO: u8 = 0x27;
    /// Request: move every slave to the table at the present master, then follow.
    pub const APPROACH: u8 = 0x28;
    /// [`super::Request::TestMove`].
    pub const TEST_MOVE: u8 = 0x29;
    /// Request: set one parameter.
    pub const SET_PARAM: u8 = 0x30;
    /// Request: persist the active table to flash.
    pub const SAVE: u8 = 0x31;
    /// Request: telemetry every N ticks (0 = off).
    pub const SET_TELEMETRY: u8 = 0x32;
    /// Request: read one parameter.
    pub const GET_PARAM: u8 = 0x33;
    /// Request: the fault history and link statistics ([`super::Response::Faults`]).
    pub const GET_FAULTS: u8 = 0x34;
    /// Request: arm the loop-rate capture.
    pub const CAPTURE_ARM: u8 = 0x40;
    /// Request: the capture's state and rows ([`super::Response::Capture`]).
    pub const GET_CAPTURE: u8 = 0x41;
    /// Request: a test board's simulated master ([`super::Response::MasterState`]).
    pub const VIRTUAL_MASTER: u8 = 0x42;
    /// Take or release control ownership (`crate::plc::owner`).
    pub const OWNER: u8 = 0x35;
    /// Response: done.
    pub const ACK: u8 = 0x80;
    /// Response: refused, nothing changed.
    pub const NAK: u8 = 0x81;
    /// Response to Hello.
    pub const INFO: u8 = 0x82;
    /// Response to GetStatus.
    pub const STATUS: u8 = 0x83;
    /// Unsolicited telemetry sample.
    pub const TELEMETRY: u8 = 0x84;
    /// Response to GetParam.
    pub const PARAM: u8 = 0x85;
    /// Response: the fault history and link statistics.
    pub const FAULTS: u8 = 0x86;
    /// Response: the capture's state and rows.
    pub const CAPTURE: u8 = 0x87;
    /// Response: a test board's simulated master.
    pub const MASTER_STATE: u8 = 0x88;
}

/// Why a request was refused (`Nak` code byte). Nothing changed on the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum NakCode {
    /// Unknown message type.
    UnknownType = 1,
    /// Frame shorter than header + CRC, or payload shorter than its type needs.
    Truncated = 2,
    /// Frame longer than the receive buffer.
    Oversized = 3,
    /// CRC mismatch.
    Crc = 4,
    /// Not valid COBS.
    Framing = 5,
    /// `seq` is neither the expected one nor a repeat of the last accepted one.
    OutOfOrder = 6,
    /// `seq` repeats the last accepted request (already done; not done twice).
    Duplicate = 7,
    /// Payload longer than its type allows.
    Length = 8,
    /// No session: send Hello first.
    NoSession = 9,
    /// Chunk/Commit without a TableBegin.
    NoUpload = 10,
    /// Chunk offset differs from the rows received so far (`detail` = expected offset).
    ChunkOffset = 11,
    /// More rows than announced, or announced rows beyond the capacity (`detail` = capacity).
    TooManyRows = 12,
    /// Column count differs from the board's axes (`detail` = the board's count).
    Columns = 13,
    /// Commit before all announced rows arrived (`detail` = rows received).
    Incomplete = 14,
    /// The whole-table CRC in Commit does not match the rows received.
    TableCrc = 15,
    /// Table rejected: fewer than 2 rows.
    TableTooFewNodes = 16,
    /// Table rejected: more rows than the capacity.
    TableTooManyNodes = 17,
    /// Table rejected: master not strictly monotonic at row `detail`.
    TableNotMonotonic = 18,
    /// Table rejected: segment length at row `detail`.
    TableSegmentLength = 19,
    /// Table rejected: row `detail`, axis `detail2` outside its range.
    TableOutOfRange = 20,
    /// Table rejected: row `detail`, axis `detail2` faster than the axis can move.
    TableTooSteep = 21,
    /// Table rejected: the configured master speed is not positive.
    TableMasterSpeed = 22,
    /// Activate: no committed table with this id.
    UnknownTable = 23,
    /// The command needs every axis idle (Save, SetParam, Activate while a table runs).
    NotIdle = 24,
    /// The runtime refused the command in its present state (`detail` = state code).
    BadState = 25,
    /// SetParam: unknown parameter id or axis.
    UnknownParam = 26,
    /// SetParam: value outside its valid range (`detail` = axis, `detail2` = param id).
    ParamRange = 27,
    /// Save: no active table and no changed setting to save.
    NothingToSave = 28,
    /// Save: flash erase/write/verify failed.
    Flash = 29,
    /// Activate: the device refused the committed table (`detail` = 0: its law could not
    /// be built with the present parameters, 1: the runtime was not at a safe point). The
    /// running table and the active id are unchanged; the committed table is consumed.
    Refused = 30,
    /// Start (or Hold from Idle) while a slave is not referenced (detail: that slave):
    /// set its position or home it first.
    NotReferenced = 31,
    /// A command for a slave the board does not have (detail: the axis asked for).
    NoAxis = 32,
    /// SetParam of a parameter the board sets itself (the period, a reference offset:
    /// `detail` = axis, `detail2` = parameter id).
    ReadOnly = 33,
    /// Hello from a host of another protocol version (`detail` = the board's version).
    Version = 34,
    /// A payload that is not a valid body of its type (e.g. a varint longer than its
    /// integer).
    Malformed = 35,
    /// CaptureArm: pre + 1 + post rows exceed the ring (`detail` = its capacity in rows).
    CaptureTooLong = 36,
    /// CaptureArm: not a trigger (unknown kind or channel), or the board keeps no
    /// capture ring.
    CaptureTrigger = 37,
    /// VirtualMaster on a board whose master is a real encoder (or an unknown operation:
    /// `detail` = the operation).
    NoVirtualMaster = 38,
    /// Jog / MoveTo / Approach refused (`detail` = axis, `detail2` = why: see
    /// [`motion_reason`]).
    Motion = 39,
    /// Another side owns the machine (`crate::plc::owner`): `detail` = the owner (0
    /// none, 1 serial host, 2 PLC), `detail2` = 0 the asking side is not the owner, 1 the
    /// machine moves under a live owner (ownership cannot be taken now).
    NotOwner = 40,
}

/// `detail2` of a [`NakCode::Motion`] Nak.
pub mod motion_reason {
    /// A limit (speed, acceleration, jerk) is zero or unrepresentable at the period.
    pub const LIMITS: u8 = 1;
    /// The target is outside the axis' limits, or a jog points out of them.
    pub const OUTSIDE_LIMITS: u8 = 2;
    /// The axis is moving (a move starts only from rest).
    pub const MOVING: u8 = 3;
    /// The move cannot be planned (too long).
    pub const PLAN: u8 = 4;
    /// The speed is above the axis' `limits/max_speed_um_per_s`.
    pub const TOO_FAST: u8 = 5;
    /// A test move's profile, amplitude, duration, dwell or frequency is impossible.
    pub const TEST_SPEC: u8 = 6;
    /// A test move's step (`A`, PRBS `2A`) is not below the axis' following-error limit.
    pub const TEST_STEP: u8 = 7;
}

impl NakCode {
    /// From the wire byte.
    pub fn from_u8(b: u8) -> Option<Self> {
        use NakCode::*;
        const ALL: [NakCode; 40] = [
            UnknownType,
            Truncated,
            Oversized,
            Crc,
            Framing,
            OutOfOrder,
            Duplicate,
            Length,
            NoSession,
            NoUpload,
            ChunkOffset,
            TooManyRows,
            Columns,
            Incomplete,
            TableCrc,
            TableTooFewNodes,
            TableTooManyNodes,
            TableNotMonotonic,
            TableSegmentLength,
            TableOutOfRange,
            TableTooSteep,
            TableMasterSpeed,
            UnknownTable,
            NotIdle,
            BadState,
            UnknownParam,
            ParamRange,
            NothingToSave,
            Flash,
            Refused,
            NotReferenced,
            NoAxis,
            ReadOnly,
            Version,
            Malformed,
            CaptureTooLong,
            CaptureTrigger,
            NoVirtualMaster,
            Motion,
            NotOwner,
        ];
        ALL.iter().copied().find(|c| *c as u8 == b)
    }
}

/// A Nak: code plus two detail fields whose meaning depends on the code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Nak {
    /// What is wrong.
    pub code: NakCode,
    /// Row, offset, count or axis (see [`NakCode`]).
    pub detail: u16,
    /// Axis or parameter id (see [`NakCode`]).
    pub detail2: u8,
}

impl Nak {
    /// A Nak without details.
    pub const fn new(code: NakCode) -> Self {
        Self {
            code,
            detail: 0,
            detail2: 0,
        }
    }
    /// A Nak with details.
    pub const fn with(code: NakCode, detail: u16, detail2: u8) -> Self {
        Self {
            code,
            detail,
            detail2,
        }
    }
}

impl From<TableError> for Nak {
    fn from(e: TableError) -> Self {
        let r = |row: usize| u16::try_from(row).unwrap_or(u16::MAX);
        let a = |axis: usize| u8::try_from(axis).unwrap_or(u8::MAX);
        match e {
            TableError::TooFewNodes => Nak::new(NakCode::TableTooFewNodes),
            TableError::TooManyNodes { capacity } => {
                Nak::with(NakCode::TableTooManyNodes, r(capacity), 0)
            }
            TableError::NotMonotonic { row } => Nak::with(NakCode::TableNotMonotonic, r(row), 0),
            TableError::SegmentLength { row } => Nak::with(NakCode::TableSegmentLength, r(row), 0),
            TableError::OutOfRange { row, axis } => {
                Nak::with(NakCode::TableOutOfRange, r(row), a(axis))
            }
            TableError::TooSteep { row, axis } => {
                Nak::with(NakCode::TableTooSteep, r(row), a(axis))
            }
            TableError::MasterSpeed => Nak::new(NakCode::TableMasterSpeed),
        }
    }
}

/// Bytes of one table row on the wire: master `i64` (I48F16 raw) + `columns` × `i32`
/// (I24F8 µm raw).
pub const fn row_len(columns: usize) -> usize {
    columns.saturating_mul(4).saturating_add(8)
}

/// Writes one row.
pub fn write_row<const S: usize>(w: &mut Writer<'_>, n: &Node<S>) -> Option<()> {
    w.i64(n.master.to_bits())?;
    for x in &n.slave_um {
        w.i32(x.to_bits())?;
    }
    Some(())
}

/// Reads one row.
pub fn read_row<const S: usize>(r: &mut Reader<'_>) -> Option<Node<S>> {
    let master = Master::from_bits(r.i64()?);
    let mut slave_um = [PosUm::ZERO; S];
    for x in &mut slave_um {
        *x = PosUm::from_bits(r.i32()?);
    }
    Some(Node { master, slave_um })
}

/// A decoded request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request<'a> {
    /// Open a session.
    Hello,
    /// Ask for status.
    GetStatus,
    /// Start an upload.
    TableBegin {
        /// Table id chosen by the host (not [`NO_TABLE`]).
        id: u32,
        /// Slave columns.
        columns: u8,
        /// Rows that will follow.
        rows: u16,
    },
    /// Rows `offset .. offset + count`.
    TableChunk {
        /// Index of the first row.
        offset: u16,
        /// Rows in this chunk.
        count: u8,
        /// `count` rows of [`row_len`] bytes.
        data: &'a [u8],
    },
    /// End the upload: CRC-32 of every row's bytes in order.
    TableCommit {
        /// CRC-32 of the whole table.
        crc: u32,
    },
    /// Drop the upload.
    TableAbort,
    /// Activate a committed table.
    Activate {
        /// Its id.
        id: u32,
    },
    /// Start following.
    Start,
    /// Stop.
    Stop,
    /// Hold.
    Hold,
    /// Clear a latched fault.
    ClearFault,
    /// Set-position: slave `axis` is at `pos_um`.
    SetPosition {
        /// Slave axis (0-based).
        axis: u8,
        /// Where it is, `I24F8` µm raw.
        pos_um: i32,
    },
    /// Arm homing of slave `axis`.
    Home {
        /// Slave axis (0-based).
        axis: u8,
    },
    /// Jog slave `axis` at `speed` (0: brake to rest); the host renews it every 100 ms.
    Jog {
        /// Slave axis (0-based).
        axis: u8,
        /// Target speed, `I24F8` µm/s raw (signed).
        speed: i32,
        /// Acceleration and jerk (`vel_um_per_s` unused).
        limits: MotionLimitsMsg,
    },
    /// Move slave `axis` to `to_um` by the S-curve of `limits`.
    MoveTo {
        /// Slave axis (0-based).
        axis: u8,
        /// Target, `I24F8` µm raw.
        to_um: i32,
        /// Velocity, acceleration and jerk limits.
        limits: MotionLimitsMsg,
    },
    /// Move every slave to the table at the present master by the S-curve of `limits`,
    /// then follow.
    Approach {
        /// Velocity, acceleration and jerk limits.
        limits: MotionLimitsMsg,
    },
    /// The identification test move on slave `axis` (`runtime::test_move`).
    TestMove {
        /// Slave axis (0-based).
        axis: u8,
        /// The test.
        test: TestMoveMsg,
    },
    /// Set one parameter.
    SetParam {
        /// Axis (ignored by board-wide parameters).
        axis: u8,
        /// Raw parameter id (see [`ParamId`]).
        param: u8,
        /// Value in the parameter's unit.
        value: f32,
    },
    /// Persist the active table.
    Save,
    /// Telemetry every `decimation` ticks (0 = off).
    SetTelemetry {
        /// Ticks between samples.
        decimation: u16,
    },
    /// Read one parameter (answered by [`Response::Param`]).
    GetParam {
        /// Axis (ignored by board-wide parameters).
        axis: u8,
        /// Raw parameter id (see [`ParamId`]).
        param: u8,
    },
    /// The fault history and link statistics (answered by [`Response::Faults`]).
    GetFaults,
    /// Arm the loop-rate capture (the previous capture's rows are dropped).
    CaptureArm(super::diag::CaptureArmMsg),
    /// The capture's state, and up to `count` rows from `offset` of a finished one
    /// (answered by [`Response::Capture`]).
    GetCapture {
        /// First row.
        offset: u32,
        /// Most rows wanted (the board sends what fits one frame).
        count: u8,
    },
    /// A test board's simulated master: an operation ([`super::diag::master_op`]) and a
    /// speed scale (0: keep the present one); answered by [`Response::MasterState`].
    VirtualMaster {
        /// Operation.
        op: u8,
        /// Speed relative to the profile (0 = unchanged, else 0.01 … 100).
        speed_scale: f32,
    },
    /// Take (`side` 1, the serial host) or release (`side` 0) control ownership
    /// (`crate::plc::owner`); answered by Ack, or Nak [`NakCode::NotOwner`].
    Owner {
        /// The side wanted: 0 none (release), 1 the serial host.
        side: u8,
    },
}

impl<'a> Request<'a> {
    /// Decodes a request payload of type `ty` (its postcard body, see `PROTOCOL.md`).
    pub fn decode(ty: u8, payload: &'a [u8]) -> Result<Self, NakCode> {
        Ok(match ty {
            // Hello carries the host's protocol version: a host of another version (one of
            // version 2 sends an empty Hello) is refused with `Version`.
            ty::HELLO => match body::<u8>(payload) {
                Ok(PROTOCOL_VERSION) => Request::Hello,
                _ => return Err(NakCode::Version),
            },
            ty::GET_STATUS => unit(payload, Request::GetStatus)?,
            ty::TABLE_BEGIN => {
                let (id, columns, rows) = body(payload)?;
                Request::TableBegin { id, columns, rows }
            }
            ty::TABLE_CHUNK => {
                // The row length depends on the upload's columns: the handler checks it.
                let (offset, count, data) = body(payload)?;
                Request::TableChunk {
                    offset,
                    count,
                    data,
                }
            }
            ty::TABLE_COMMIT => Request::TableCommit {
                crc: body(payload)?,
            },
            ty::TABLE_ABORT => unit(payload, Request::TableAbort)?,
            ty::ACTIVATE => Request::Activate { id: body(payload)? },
            ty::START => unit(payload, Request::Start)?,
            ty::STOP => unit(payload, Request::Stop)?,
            ty::HOLD => unit(payload, Request::Hold)?,
            ty::CLEAR_FAULT => unit(payload, Request::ClearFault)?,
            ty::SET_POSITION => {
                let (axis, pos_um) = body(payload)?;
                Request::SetPosition { axis, pos_um }
            }
            ty::HOME => Request::Home {
                axis: body(payload)?,
            },
            ty::JOG => {
                let (axis, speed, limits) = body(payload)?;
                Request::Jog {
                    axis,
                    speed,
                    limits,
                }
            }
            ty::MOVE_TO => {
                let (axis, to_um, limits) = body(payload)?;
                Request::MoveTo {
                    axis,
                    to_um,
                    limits,
                }
            }
            ty::APPROACH => Request::Approach {
                limits: body(payload)?,
            },
            ty::TEST_MOVE => {
                let (axis, test) = body(payload)?;
                Request::TestMove { axis, test }
            }
            ty::SET_PARAM => {
                let (axis, param, value) = body(payload)?;
                Request::SetParam { axis, param, value }
            }
            ty::SAVE => unit(payload, Request::Save)?,
            ty::SET_TELEMETRY => Request::SetTelemetry {
                decimation: body(payload)?,
            },
            ty::GET_PARAM => {
                let (axis, param) = body(payload)?;
                Request::GetParam { axis, param }
            }
            ty::GET_FAULTS => unit(payload, Request::GetFaults)?,
            ty::CAPTURE_ARM => Request::CaptureArm(body(payload)?),
            ty::GET_CAPTURE => {
                let (offset, count) = body(payload)?;
                Request::GetCapture { offset, count }
            }
            ty::VIRTUAL_MASTER => {
                let (op, speed_scale) = body(payload)?;
                Request::VirtualMaster { op, speed_scale }
            }
            ty::OWNER => Request::Owner {
                side: body(payload)?,
            },
            _ => return Err(NakCode::UnknownType),
        })
    }

    /// The type code.
    pub fn ty(&self) -> u8 {
        match self {
            Request::Hello => ty::HELLO,
            Request::GetStatus => ty::GET_STATUS,
            Request::TableBegin { .. } => ty::TABLE_BEGIN,
            Request::TableChunk { .. } => ty::TABLE_CHUNK,
            Request::TableCommit { .. } => ty::TABLE_COMMIT,
            Request::TableAbort => ty::TABLE_ABORT,
            Request::Activate { .. } => ty::ACTIVATE,
            Request::Start => ty::START,
            Request::Stop => ty::STOP,
            Request::Hold => ty::HOLD,
            Request::ClearFault => ty::CLEAR_FAULT,
            Request::SetPosition { .. } => ty::SET_POSITION,
            Request::Home { .. } => ty::HOME,
            Request::Jog { .. } => ty::JOG,
            Request::MoveTo { .. } => ty::MOVE_TO,
            Request::Approach { .. } => ty::APPROACH,
            Request::TestMove { .. } => ty::TEST_MOVE,
            Request::SetParam { .. } => ty::SET_PARAM,
            Request::Save => ty::SAVE,
            Request::SetTelemetry { .. } => ty::SET_TELEMETRY,
            Request::GetParam { .. } => ty::GET_PARAM,
            Request::GetFaults => ty::GET_FAULTS,
            Request::CaptureArm(_) => ty::CAPTURE_ARM,
            Request::GetCapture { .. } => ty::GET_CAPTURE,
            Request::VirtualMaster { .. } => ty::VIRTUAL_MASTER,
            Request::Owner { .. } => ty::OWNER,
        }
    }

    /// Encodes the payload (postcard) into `buf`; returns its length.
    pub fn encode(&self, buf: &mut [u8]) -> Option<usize> {
        match *self {
            Request::Hello => put(&PROTOCOL_VERSION, buf),
            Request::GetStatus
            | Request::TableAbort
            | Request::Start
            | Request::Stop
            | Request::Hold
            | Request::ClearFault
            | Request::GetFaults
            | Request::Save => Some(0),
            Request::TableBegin { id, columns, rows } => put(&(id, columns, rows), buf),
            Request::TableChunk {
                offset,
                count,
                data,
            } => put(&(offset, count, data), buf),
            Request::TableCommit { crc } => put(&crc, buf),
            Request::Activate { id } => put(&id, buf),
            Request::SetPosition { axis, pos_um } => put(&(axis, pos_um), buf),
            Request::Home { axis } => put(&axis, buf),
            Request::Jog {
                axis,
                speed,
                limits,
            } => put(&(axis, speed, limits), buf),
            Request::MoveTo {
                axis,
                to_um,
                limits,
            } => put(&(axis, to_um, limits), buf),
            Request::Approach { limits } => put(&limits, buf),
            Request::TestMove { axis, test } => put(&(axis, test), buf),
            Request::SetParam { axis, param, value } => put(&(axis, param, value), buf),
            Request::SetTelemetry { decimation } => put(&decimation, buf),
            Request::GetParam { axis, param } => put(&(axis, param), buf),
            Request::CaptureArm(ref c) => put(c, buf),
            Request::GetCapture { offset, count } => put(&(offset, count), buf),
            Request::VirtualMaster { op, speed_scale } => put(&(op, speed_scale), buf),
            Request::Owner { side } => put(&side, buf),
        }
    }
}

/// A payload's postcard body: exactly the bytes of one `T` (`Truncated` if it ends
/// early, `Length` if bytes follow it, `Malformed` if they are not a `T`).
fn body<'a, T: Deserialize<'a>>(payload: &'a [u8]) -> Result<T, NakCode> {
    match postcard::take_from_bytes::<T>(payload) {
        Ok((v, [])) => Ok(v),
        Ok(_) => Err(NakCode::Length),
        Err(postcard::Error::DeserializeUnexpectedEnd) => Err(NakCode::Truncated),
        Err(_) => Err(NakCode::Malformed),
    }
}

/// A request without a body: its payload is empty.
fn unit<T>(payload: &[u8], req: T) -> Result<T, NakCode> {
    if payload.is_empty() {
        Ok(req)
    } else {
        Err(NakCode::Length)
    }
}

/// Writes `v` (postcard) into `buf`; its length.
fn put<T: Serialize + ?Sized>(v: &T, buf: &mut [u8]) -> Option<usize> {
    postcard::to_slice(v, buf).ok().map(|b| b.len())
}

/// `Info`: what the board is — its profile (slaves, table rows, chunk size, law buffers,
/// period and the periods it accepts, the longest segment) and the table limits in force.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Info {
    /// [`PROTOCOL_VERSION`].
    pub protocol: u8,
    /// Firmware version major, minor, patch.
    pub firmware: [u8; 3],
    /// Slave axes (table columns).
    pub axes: u8,
    /// Table capacity, rows.
    pub capacity_rows: u16,
    /// Most rows one TableChunk may carry.
    pub max_chunk_rows: u8,
    /// Control period, µs.
    pub period_us: u32,
    /// Id of the active table ([`NO_TABLE`] if none).
    pub active_id: u32,
    /// Law buffers (2: a new law is built beside the running one, then swapped).
    pub law_buffers: u8,
    /// Control periods the runtime accepts, µs.
    pub period_min_us: u32,
    /// See [`Info::period_min_us`].
    pub period_max_us: u32,
    /// Longest segment between two table rows, master counts.
    pub max_segment_counts: u32,
    /// The limits tables are validated against now (SetParam changes them).
    pub limits: InfoLimits,
}

/// The table limits in `Info` (raw fixed-point bits, as the board holds them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct InfoLimits {
    /// Fastest master speed, master counts/s, I48F16 raw.
    pub master_speed_per_s: i64,
    /// Per slave (the first [`Info::axes`] entries).
    pub axes: [AxisLimitsMsg; MAX_AXES],
}

/// One slave's table limits in `Info`: I24F8 raw µm and µm/s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AxisLimitsMsg {
    /// Lowest position, µm (I24F8 raw).
    pub min_um: i32,
    /// Highest position, µm (I24F8 raw).
    pub max_um: i32,
    /// Top speed, µm/s (I24F8 raw).
    pub max_speed_um_per_s: i32,
}

impl InfoLimits {
    /// The wire form of `l`.
    pub fn of<const S: usize>(l: &crate::table::TableLimits<S>) -> Self {
        let mut out = Self {
            master_speed_per_s: l.master_speed_per_s.to_bits(),
            ..Self::default()
        };
        for (o, a) in out.axes.iter_mut().zip(l.axes.iter()) {
            *o = AxisLimitsMsg {
                min_um: a.min_um.to_bits(),
                max_um: a.max_um.to_bits(),
                max_speed_um_per_s: a.max_speed_um_per_s.to_bits(),
            };
        }
        out
    }
}

/// `StatusMsg::flags`: a slave is not referenced (Start is refused).
pub const FLAG_UNREFERENCED: u8 = 1 << 5;
/// `StatusMsg::flags`: the host-link watchdog held the axes since the last Start.
pub const FLAG_LINK_LOST: u8 = 1 << 6;
/// `StatusMsg::flags`: the pressure inputs stopped updating this tick.
pub const FLAG_PRESSURE_STALE: u8 = 1 << 7;
/// `StatusMsg::inputs`: the E-stop input is active.
pub const INPUT_ESTOP: u8 = 1;
/// `StatusMsg::inputs`: valve power (the enable output) is on.
pub const INPUT_VALVE_POWER: u8 = 1 << 1;

/// Per-axis part of `Status`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AxisStatus {
    /// Measured position, I24F8 µm raw.
    pub pos_um: i32,
    /// Table target X(θ_f), I24F8 µm raw.
    pub target_um: i32,
    /// target − position, I24F8 µm raw.
    pub error_um: i32,
    /// Valve DAC code, LSB.
    pub dac: i16,
    /// Reference: 0 not referenced, 1 homing armed (waiting for the edge), 2 referenced.
    pub reference: u8,
    /// Manual motion (state Manual): 0 holding, 1 jogging, 2 moving by an S-curve.
    pub manual: u8,
    /// The gain backoff's level (`axis::backoff`): 0 the set gain, 1 … 4 the
    /// proportional gain at 0.36, 0.27, 0.20, 0.15 of it and the integral gain at 1,
    /// 0.75, 0.56, 0.42 (an oscillation was seen).
    pub backoff: u8,
    /// The feed-forward trim's learned ratio − 1 (`axis::ff_trim`) for negative and
    /// positive feed-forward, in 1/10 000 (−5 000 … +10 000: the ratio 0.5 … 2; 0 the
    /// calibrated gain or no trim).
    pub ff_trim: [i16; 2],
}

impl From<MotionLimitsMsg> for crate::runtime::MotionLimits {
    fn from(m: MotionLimitsMsg) -> Self {
        Self {
            vel_um_per_s: m.vel_um_per_s,
            acc_um_per_s2: m.acc_um_per_s2,
            jerk_um_per_s3: m.jerk_um_per_s3,
        }
    }
}

/// The limits of a manual motion (Jog, MoveTo, Approach), integers in µm-based units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MotionLimitsMsg {
    /// Velocity limit, µm/s.
    pub vel_um_per_s: u32,
    /// Acceleration limit, µm/s².
    pub acc_um_per_s2: u32,
    /// Jerk limit, µm/s³.
    pub jerk_um_per_s3: u32,
}

/// The body of a `TestMove` (`runtime::TestSpec` on the wire).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TestMoveMsg {
    /// 0 step, 1 chirp, 2 prbs (`runtime::TestProfile::code`).
    pub profile: u8,
    /// Amplitude, µm.
    pub amplitude_um: u32,
    /// Duration, ms.
    pub duration_ms: u32,
    /// Step / PRBS: time per level, ms.
    pub dwell_ms: u32,
    /// Chirp: start frequency, mHz.
    pub f_start_mhz: u32,
    /// Chirp: end frequency, mHz.
    pub f_end_mhz: u32,
}

impl TestMoveMsg {
    /// The runtime's spec (`None`: an unknown profile).
    pub fn spec(&self) -> Option<crate::runtime::TestSpec> {
        Some(crate::runtime::TestSpec {
            profile: crate::runtime::TestProfile::from_code(self.profile)?,
            amplitude_um: self.amplitude_um,
            duration_ms: self.duration_ms,
            dwell_ms: self.dwell_ms,
            f_start_mhz: self.f_start_mhz,
            f_end_mhz: self.f_end_mhz,
        })
    }

    /// The wire form of a spec.
    pub fn of(s: &crate::runtime::TestSpec) -> Self {
        Self {
            profile: s.profile.code(),
            amplitude_um: s.amplitude_um,
            duration_ms: s.duration_ms,
            dwell_ms: s.dwell_ms,
            f_start_mhz: s.f_start_mhz,
            f_end_mhz: s.f_end_mhz,
        }
    }
}

/// `Status`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StatusMsg {
    /// Runtime state: 0 Idle, 1 Following, 2 Holding, 3 Fault, 4 Manual.
    pub state: u8,
    /// Flags: bit 0 end of table, bit 1 activation pending, bit 2 upload in progress,
    /// bit 3 a committed table waits, bit 4 session open, bit 5 a slave is not
    /// referenced ([`FLAG_UNREFERENCED`]), bit 6 the host-link watchdog held the axes
    /// since the last Start ([`FLAG_LINK_LOST`]), bit 7 the pressure inputs are stale
    /// ([`FLAG_PRESSURE_STALE`]).
    pub flags: u8,
    /// Latched fault code (0 = none; the runtime's 16-bit codes).
    pub fault_code: u16,
    /// Axis of the fault (0xFF = board-wide or none).
    pub fault_axis: u8,
    /// Inputs and outputs: [`INPUT_ESTOP`], [`INPUT_VALVE_POWER`].
    pub inputs: u8,
    /// Active table id.
    pub active_id: u32,
    /// The active table's rows (0: none).
    pub active_rows: u16,
    /// CRC-32 of the active table's rows (as `TableCommit` carries it; 0: none).
    pub active_crc: u32,
    /// Committed (inactive) table id.
    pub committed_id: u32,
    /// Id of the table in the newest valid flash slot.
    pub saved_id: u32,
    /// The flash slot the board booted (0, 1; 0xFF: none).
    pub boot_slot: u8,
    /// Why that slot ([`super::handler::BootReason`] code).
    pub boot_reason: u8,
    /// Rows received of the upload in progress.
    pub upload_rows: u16,
    /// Ticks since boot.
    pub ticks: u32,
    /// Longest tick execution, ns.
    pub tick_max_ns: u32,
    /// Mean tick execution, ns.
    pub tick_mean_ns: u32,
    /// Ticks that overran their period.
    pub overruns: u32,
    /// Filtered master, I48F16 counts raw.
    pub master: i64,
    /// Who owns the machine: 0 none, 1 the serial host, 2 the PLC (`crate::plc::owner`).
    pub owner: u8,
    /// Per axis.
    pub axes: Vec<AxisStatus, MAX_AXES>,
}

/// Per-axis part of `Telemetry`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AxisSample {
    /// Target, I24F8 µm raw.
    pub target_um: i32,
    /// Actual, I24F8 µm raw.
    pub actual_um: i32,
    /// Valve command, DAC LSB.
    pub dac: i16,
}

/// `Telemetry`: one subsampled tick.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Telemetry {
    /// Tick number.
    pub tick: u32,
    /// Filtered master, I48F16 counts raw.
    pub master: i64,
    /// Per axis.
    pub axes: Vec<AxisSample, MAX_AXES>,
}

impl Telemetry {
    /// The telemetry of one tick's sample (the first [`MAX_AXES`] slaves).
    pub fn of_sample<const S: usize>(s: &crate::runtime::TickSample<S>) -> Self {
        let mut t = Self {
            tick: s.tick,
            master: s.master,
            axes: Vec::new(),
        };
        for ((&target_um, &actual_um), &dac) in s.target_um.iter().zip(&s.actual_um).zip(&s.dac) {
            // Beyond MAX_AXES slaves the rest is not reported (a board has at most 8).
            let _ = t.axes.push(AxisSample {
                target_um,
                actual_um,
                dac,
            });
        }
        t
    }
}

/// A decoded response.
#[derive(Clone, Debug, PartialEq)]
pub enum Response {
    /// Done. `flags` bit 0: Activate deferred to the next safe point.
    Ack {
        /// Request type acknowledged.
        req: u8,
        /// Flags.
        flags: u8,
    },
    /// Refused; nothing changed.
    Nak {
        /// Request type refused (0 when the frame could not be read).
        req: u8,
        /// Why.
        nak: Nak,
    },
    /// Answer to Hello.
    Info(Info),
    /// Answer to GetStatus.
    Status(StatusMsg),
    /// Unsolicited sample.
    Telemetry(Telemetry),
    /// Answer to GetFaults.
    Faults(super::diag::FaultsMsg),
    /// Answer to GetCapture.
    Capture(super::diag::CaptureMsg),
    /// Answer to VirtualMaster.
    MasterState(super::diag::MasterStateMsg),
    /// Answer to GetParam: the value in force.
    Param {
        /// Axis asked for (0 for a board-wide parameter).
        axis: u8,
        /// Raw parameter id.
        param: u8,
        /// Value in the parameter's unit.
        value: f32,
    },
}

impl Response {
    /// The type code.
    pub fn ty(&self) -> u8 {
        match self {
            Response::Ack { .. } => ty::ACK,
            Response::Nak { .. } => ty::NAK,
            Response::Info(_) => ty::INFO,
            Response::Status(_) => ty::STATUS,
            Response::Telemetry(_) => ty::TELEMETRY,
            Response::Param { .. } => ty::PARAM,
            Response::Faults(_) => ty::FAULTS,
            Response::Capture(_) => ty::CAPTURE,
            Response::MasterState(_) => ty::MASTER_STATE,
        }
    }

    /// Encodes the payload (postcard); returns its length.
    pub fn encode(&self, buf: &mut [u8]) -> Option<usize> {
        match self {
            Response::Ack { req, flags } => put(&(req, flags), buf),
            Response::Param { axis, param, value } => put(&(axis, param, value), buf),
            Response::Nak { req, nak } => put(&(req, nak.code as u8, nak.detail, nak.detail2), buf),
            Response::Info(i) => put(i, buf),
            Response::Status(s) => put(s, buf),
            Response::Telemetry(t) => put(t, buf),
            Response::Faults(f) => put(f, buf),
            Response::Capture(c) => put(c, buf),
            Response::MasterState(m) => put(m, buf),
        }
    }

    /// Decodes a response payload of type `t` (`None`: malformed).
    pub fn decode(t: u8, payload: &[u8]) -> Option<Self> {
        let ok = |r: Result<Self, NakCode>| r.ok();
        match t {
            ty::ACK => ok(body(payload).map(|(req, flags)| Response::Ack { req, flags })),
            ty::PARAM => {
                ok(
                    body(payload).map(|(axis, param, value)| Response::Param {
                        axis,
                        param,
                        value,
                    }),
                )
            }
            ty::NAK => {
                let (req, code, detail, detail2): (u8, u8, u16, u8) = match body(payload) {
                    Ok(n) => n,
                    // A version-2 board's Nak (its fixed layout: req, code, detail u16 LE,
                    // detail2), so a host of this version can say why an old board refused
                    // its Hello.
                    Err(_) => match *payload {
                        [req, code, d0, d1, d2] => (req, code, u16::from_le_bytes([d0, d1]), d2),
                        _ => return None,
                    },
                };
                let nak = Nak {
                    code: NakCode::from_u8(code)?,
                    detail,
                    detail2,
                };
                Some(Response::Nak { req, nak })
            }
            ty::INFO => match payload.first() {
                // Another version: only its first byte (the version, a postcard u8 in
                // every version), so the host can say which version the board speaks.
                Some(&v) if v != PROTOCOL_VERSION => Some(Response::Info(Info {
                    protocol: v,
                    ..Info::default()
                })),
                _ => {
                    let i: Info = body(payload).ok()?;
                    (usize::from(i.axes) <= MAX_AXES).then_some(Response::Info(i))
                }
            },
            ty::STATUS => ok(body(payload).map(Response::Status)),
            ty::TELEMETRY => ok(body(payload).map(Response::Telemetry)),
            ty::FAULTS => ok(body(payload).map(Response::Faults)),
            ty::CAPTURE => ok(body(payload).map(Response::Capture)),
            ty::MASTER_STATE => ok(body(payload).map(Response::MasterState)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nak_codes_roundtrip() {
        for b in 0..=255u8 {
            if let Some(c) = NakCode::from_u8(b) {
                assert_eq!(c as u8, b);
            }
        }
        assert_eq!(NakCode::from_u8(29), Some(NakCode::Flash));
        assert_eq!(NakCode::from_u8(0), None);
        assert_eq!(NakCode::from_u8(30), Some(NakCode::Refused));
        assert_eq!(NakCode::from_u8(31), Some(NakCode::NotReferenced));
        assert_eq!(NakCode::from_u8(32), Some(NakCode::NoAxis));
        assert_eq!(NakCode::from_u8(33), Some(NakCode::ReadOnly));
        assert_eq!(NakCode::from_u8(34), Some(NakCode::Version));
        assert_eq!(NakCode::from_u8(35), Some(NakCode::Malformed));
        assert_eq!(NakCode::from_u8(36), Some(NakCode::CaptureTooLong));
        assert_eq!(NakCode::from_u8(37), Some(NakCode::CaptureTrigger));
        assert_eq!(NakCode::from_u8(38), Some(NakCode::NoVirtualMaster));
        assert_eq!(NakCode::from_u8(39), Some(NakCode::Motion));
        assert_eq!(NakCode::from_u8(40), Some(NakCode::NotOwner));
        assert_eq!(NakCode::from_u8(41), None);
    }

    #[test]
    fn requests_roundtrip() {
        let data = [1u8; 32];
        let reqs = [
            Request::Hello,
            Request::TableBegin {
                id: 7,
                columns: 2,
                rows: 300,
            },
            Request::TableChunk {
                offset: 5,
                count: 2,
                data: &data,
            },
            Request::TableCommit { crc: 0xDEAD_BEEF },
            Request::Activate { id: 7 },
            Request::SetParam {
                axis: 1,
                param: 6,
                value: 2.5,
            },
            Request::SetTelemetry { decimation: 10 },
            Request::GetParam { axis: 1, param: 14 },
            Request::Save,
            Request::CaptureArm(crate::protocol::diag::CaptureArmMsg {
                trigger: 4,
                channel: 3,
                axis: 1,
                value: -12_800,
                pre: 500,
                post: 1500,
            }),
            Request::GetCapture {
                offset: 1999,
                count: 7,
            },
        ];
        for q in reqs {
            let mut b = [0u8; 64];
            let n = q.encode(&mut b).unwrap();
            assert_eq!(Request::decode(q.ty(), &b[..n]), Ok(q));
            // Hello: anything but this version's byte is another version.
            let short = if matches!(q, Request::Hello) {
                NakCode::Version
            } else {
                NakCode::Truncated
            };
            if n > 0 {
                assert_eq!(Request::decode(q.ty(), &b[..n - 1]), Err(short), "{q:?}");
            }
            let long = if matches!(q, Request::Hello) {
                NakCode::Version
            } else {
                NakCode::Length
            };
            assert_eq!(Request::decode(q.ty(), &b[..n + 1]), Err(long), "{q:?}");
        }
        assert_eq!(Request::decode(0x7F, &[]), Err(NakCode::UnknownType));
        // A version-2 host's Hello (empty) and a future version's are refused as such.
        assert_eq!(Request::decode(ty::HELLO, &[]), Err(NakCode::Version));
        assert_eq!(Request::decode(ty::HELLO, &[10]), Err(NakCode::Version));
        // A varint longer than its integer is not a body of its type.
        assert_eq!(
            Request::decode(ty::ACTIVATE, &[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01]),
            Err(NakCode::Malformed)
        );
    }

    #[test]
    fn responses_roundtrip() {
        let mut st = StatusMsg {
            state: 1,
            master: -5,
            ..Default::default()
        };
        st.axes
            .push(AxisStatus {
                pos_um: 1,
                target_um: 2,
                error_um: 3,
                dac: -4,
                reference: 2,
                manual: 1,
                backoff: 2,
                ff_trim: [-2_150, 300],
            })
            .unwrap();
        let mut tm = Telemetry {
            tick: 9,
            master: 1 << 40,
            axes: Vec::new(),
        };
        tm.axes
            .push(AxisSample {
                target_um: 1,
                actual_um: -2,
                dac: 3,
            })
            .unwrap();
        let rs = [
            Response::Ack { req: 1, flags: 1 },
            Response::Param {
                axis: 1,
                param: 14,
                value: -0.125,
            },
            Response::Nak {
                req: 2,
                nak: Nak::with(NakCode::TableTooSteep, 4, 1),
            },
            Response::Info(Info {
                protocol: PROTOCOL_VERSION,
                firmware: [0, 1, 0],
                axes: 2,
                capacity_rows: 1024,
                max_chunk_rows: 20,
                period_us: 1000,
                active_id: NO_TABLE,
                law_buffers: 2,
                period_min_us: 100,
                period_max_us: 1_000_000,
                max_segment_counts: 65_535,
                limits: InfoLimits {
                    master_speed_per_s: 10_000 << 16,
                    axes: {
                        let mut a = [AxisLimitsMsg::default(); MAX_AXES];
                        a[0] = AxisLimitsMsg {
                            min_um: 0,
                            max_um: 500_000 << 8,
                            max_speed_um_per_s: 200_000 << 8,
                        };
                        a[1] = AxisLimitsMsg {
                            min_um: -1,
                            max_um: 2,
                            max_speed_um_per_s: 3,
                        };
                        a
                    },
                },
            }),
            Response::Status(st),
            Response::Telemetry(tm),
            Response::Faults({
                let mut f = super::super::diag::FaultsMsg::default();
                f.events
                    .push(super::super::diag::FaultEventMsg {
                        code: 0x0601,
                        tick: 70_000,
                        value: -1 << 20,
                        limit: 2000 << 8,
                    })
                    .unwrap();
                f.link.frames = 300;
                f
            }),
            Response::Capture(super::super::diag::CaptureMsg {
                phase: 3,
                pre: 20,
                rows: 31,
                trigger_tick: 150,
                capacity: 2000,
                offset: 7,
                data: heapless::Vec::from_slice(&[1, 2, 3]).unwrap(),
            }),
        ];
        // A version-2 board's answer to this version's Hello (its fixed-layout Nak Length:
        // the Hello had a byte it did not expect) is read as such.
        assert_eq!(
            Response::decode(ty::NAK, &[ty::HELLO, 8, 0, 0, 0]),
            Some(Response::Nak {
                req: ty::HELLO,
                nak: Nak::new(NakCode::Length)
            })
        );
        // Another version's Info: only its version byte is read, so the host can say
        // which version the board speaks (version 2's first bytes here).
        let v2 = [2u8, 0, 3, 7, 1, 0, 4, 20, 0xE8, 3, 0, 0];
        match Response::decode(ty::INFO, &v2) {
            Some(Response::Info(i)) => {
                assert_eq!(i.protocol, 2);
                assert_eq!(i.axes, 0, "nothing else is taken from another version");
            }
            r => panic!("{r:?}"),
        }
        for r in rs {
            let mut b = [0u8; 256];
            let n = r.encode(&mut b).unwrap();
            assert_eq!(Response::decode(r.ty(), &b[..n]), Some(r.clone()));
            assert_eq!(Response::decode(r.ty(), &b[..n - 1]), None);
        }
    }
}
