//! Commissioning messages' bodies: the fault history with the link's statistics
//! (`GetFaults` → `Faults`) and the loop-rate capture (`CaptureArm`, `GetCapture` →
//! `Capture`). Layouts in `PROTOCOL.md` §3.

use super::wire::{Reader, Writer};
use crate::runtime::{CaptureRow, Channel, FaultEvent, Phase, Trigger, FAULT_HISTORY_LEN};
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// One event of the fault history ([`FaultEvent`] on the wire).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultEventMsg {
    /// The fault's 16-bit code (`kind << 8 | index`).
    pub code: u16,
    /// Tick number when it was raised.
    pub tick: u32,
    /// The value that tripped it (unit by kind: [`FaultEvent`]).
    pub value: i32,
    /// Its limit (same unit).
    pub limit: i32,
}

impl From<&FaultEvent> for FaultEventMsg {
    fn from(e: &FaultEvent) -> Self {
        Self {
            code: e.fault.code(),
            tick: e.tick,
            value: e.value,
            limit: e.limit,
        }
    }
}

/// The host link as the board saw it since boot (wrapping counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkStats {
    /// Frames received whole (COBS and CRC good).
    pub frames: u32,
    /// Frames that were not: bad COBS, truncated, oversized or a CRC mismatch.
    pub bad_frames: u32,
    /// Requests (whole frames) refused with a Nak.
    pub naks: u32,
}

/// `Faults`: the fault history, oldest first, and the link's statistics.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultsMsg {
    /// Up to [`FAULT_HISTORY_LEN`] events, oldest first.
    pub events: Vec<FaultEventMsg, FAULT_HISTORY_LEN>,
    /// The link's statistics.
    pub link: LinkStats,
}

/// `VirtualMaster` operations (a test board's simulated master; a real board's master
/// is an encoder and refuses them with `NoVirtualMaster`).
pub mod master_op {
    /// Only report the master's state.
    pub const QUERY: u8 = 0;
    /// Run (from where it is).
    pub const START: u8 = 1;
    /// Stand still where it is.
    pub const STOP: u8 = 2;
    /// Back to the start of its profile (standing still).
    pub const REWIND: u8 = 3;
}

/// `MasterState`: a test board's simulated master.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MasterStateMsg {
    /// It runs.
    pub running: bool,
    /// Its time along the profile, s.
    pub time_s: f32,
    /// Its position, master units (degrees for the rotary table).
    pub position: f32,
    /// When its profile arrives at rest at its end, s.
    pub end_s: f32,
    /// It has arrived at the end (it stands still there until rewound).
    pub at_end: bool,
    /// Speed relative to the profile (1 = as specified).
    pub speed_scale: f32,
}

/// Bytes of capture rows one `Capture` message carries at most.
pub const CAPTURE_DATA_MAX: usize = 256;

/// Bytes of one capture row on the wire for `axes` slaves: master i32, flags u8, then per
/// slave target i32, actual i32, DAC i16, pressure A u16, pressure B u16 (little-endian;
/// units of [`CaptureRow`]).
pub const fn capture_row_len(axes: usize) -> usize {
    14usize.saturating_mul(axes).saturating_add(5)
}

/// `Capture`: where the capture is, and rows `offset ..` of a finished one.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CaptureMsg {
    /// 0 never armed, 1 armed, 2 triggered (recording after the trigger), 3 done.
    pub phase: u8,
    /// Rows before the trigger row (row `pre` is the trigger's tick, t = 0).
    pub pre: u32,
    /// Rows of the finished capture (0 until done).
    pub rows: u32,
    /// Tick number of the trigger row.
    pub trigger_tick: u32,
    /// Rows the board's ring holds.
    pub capacity: u32,
    /// Index of the first row in `data`.
    pub offset: u32,
    /// Whole rows of [`capture_row_len`] bytes.
    pub data: Vec<u8, CAPTURE_DATA_MAX>,
}

/// `CaptureArm`'s body: the trigger ([`trigger_from_wire`]) and the ticks to keep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CaptureArmMsg {
    /// Trigger kind.
    pub trigger: u8,
    /// Channel kind of a level trigger.
    pub channel: u8,
    /// Slave of a level trigger's channel.
    pub axis: u8,
    /// Level, in the channel's stored unit.
    pub value: i32,
    /// Ticks to keep before the trigger.
    pub pre: u32,
    /// Ticks to record after it.
    pub post: u32,
}

impl CaptureArmMsg {
    /// The body that arms `trigger` with `pre` and `post` ticks.
    pub const fn new(trigger: Trigger, pre: u32, post: u32) -> Self {
        let (trigger, channel, axis, value) = trigger_to_wire(trigger);
        Self {
            trigger,
            channel,
            axis,
            value,
            pre,
            post,
        }
    }
}

/// The wire code of a capture phase.
pub const fn phase_code(p: Phase) -> u8 {
    match p {
        Phase::Idle => 0,
        Phase::Armed => 1,
        Phase::Triggered => 2,
        Phase::Done => 3,
    }
}

/// `CaptureArm`'s trigger from its wire fields (kind 0 now, 1 fault, 2 state change,
/// 3 command, 4 above, 5 below; the level kinds name a channel by
/// [`Channel::from_wire`]). `None`: not a trigger.
pub const fn trigger_from_wire(kind: u8, channel: u8, axis: u8, value: i32) -> Option<Trigger> {
    Some(match kind {
        0 => Trigger::Now,
        1 => Trigger::Fault,
        2 => Trigger::StateChange,
        3 => Trigger::Command,
        4 | 5 => {
            let Some(channel) = Channel::from_wire(channel, axis) else {
                return None;
            };
            if kind == 4 {
                Trigger::Above { channel, value }
            } else {
                Trigger::Below { channel, value }
            }
        }
        _ => return None,
    })
}

/// The wire fields (kind, channel, axis, value) of a trigger.
pub const fn trigger_to_wire(t: Trigger) -> (u8, u8, u8, i32) {
    match t {
        Trigger::Now => (0, 0, 0, 0),
        Trigger::Fault => (1, 0, 0, 0),
        Trigger::StateChange => (2, 0, 0, 0),
        Trigger::Command => (3, 0, 0, 0),
        Trigger::Above { channel, value } => {
            let (c, a) = channel.to_wire();
            (4, c, a, value)
        }
        Trigger::Below { channel, value } => {
            let (c, a) = channel.to_wire();
            (5, c, a, value)
        }
    }
}

/// Appends one row in its wire layout; `None` if `w` is full.
pub fn put_capture_row<const S: usize>(
    w: &mut Writer<'_>,
    row: &CaptureRow<S>,
    flags: u8,
) -> Option<()> {
    w.i32(row.master)?;
    w.u8(flags)?;
    for k in 0..S {
        w.i32(*row.target_um.get(k)?)?;
        w.i32(*row.actual_um.get(k)?)?;
        w.i16(*row.dac.get(k)?)?;
        let [a, b] = *row.pressure_cbar.get(k)?;
        w.u16(a)?;
        w.u16(b)?;
    }
    Some(())
}

/// One slave's channels of a decoded capture row (units of [`CaptureRow`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaptureAxis {
    /// Target, I24F8 µm raw.
    pub target_um: i32,
    /// Position, I24F8 µm raw.
    pub actual_um: i32,
    /// DAC code, LSB.
    pub dac: i16,
    /// Chamber A, B pressure, centibar.
    pub pressure_cbar: [u16; 2],
}

/// A decoded capture row (the host's view: any number of slaves up to 8).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CaptureLine {
    /// Master, whole counts.
    pub master: i32,
    /// Flags ([`crate::runtime::TickSample::flags`]).
    pub flags: u8,
    /// Per slave.
    pub axes: Vec<CaptureAxis, { super::msg::MAX_AXES }>,
}

/// Reads one row of `axes` slaves; `None` if `r` ends early or `axes` > 8.
pub fn take_capture_row(r: &mut Reader<'_>, axes: usize) -> Option<CaptureLine> {
    let mut line = CaptureLine {
        master: r.i32()?,
        flags: r.u8()?,
        axes: Vec::new(),
    };
    for _ in 0..axes {
        let a = CaptureAxis {
            target_um: r.i32()?,
            actual_um: r.i32()?,
            dac: r.i16()?,
            pressure_cbar: [r.u16()?, r.u16()?],
        };
        line.axes.push(a).ok()?;
    }
    Some(line)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_round_trips_in_its_wire_layout() {
        let row = CaptureRow::<2> {
            master: -7,
            target_um: [1 << 20, -3],
            actual_um: [5, i32::MIN],
            dac: [2047, -2047],
            pressure_cbar: [[25_000, 1], [0, u16::MAX]],
        };
        let mut buf = [0u8; 64];
        let mut w = Writer::new(&mut buf);
        put_capture_row(&mut w, &row, 0x2B).unwrap();
        assert_eq!(w.len(), capture_row_len(2));
        let mut r = Reader::new(&buf[..capture_row_len(2)]);
        let l = take_capture_row(&mut r, 2).unwrap();
        assert_eq!((l.master, l.flags), (-7, 0x2B));
        assert_eq!(l.axes[1].actual_um, i32::MIN);
        assert_eq!(l.axes[0].pressure_cbar, [25_000, 1]);
        assert_eq!(l.axes[1].dac, -2047);
        // One byte short: no row.
        let mut r = Reader::new(&buf[..capture_row_len(2) - 1]);
        assert_eq!(take_capture_row(&mut r, 2), None);
        // A full writer refuses the row.
        let mut small = [0u8; 10];
        assert_eq!(put_capture_row(&mut Writer::new(&mut small), &row, 0), None);
    }

    #[test]
    fn triggers_round_trip_and_unknown_ones_are_refused() {
        let ts = [
            Trigger::Now,
            Trigger::Fault,
            Trigger::StateChange,
            Trigger::Command,
            Trigger::Above {
                channel: Channel::Error(1),
                value: -5,
            },
            Trigger::Below {
                channel: Channel::Master,
                value: 9,
            },
        ];
        for t in ts {
            let (k, c, a, v) = trigger_to_wire(t);
            assert_eq!(trigger_from_wire(k, c, a, v), Some(t));
        }
        assert_eq!(trigger_from_wire(6, 0, 0, 0), None);
        assert_eq!(trigger_from_wire(4, 9, 0, 0), None);
    }
}
