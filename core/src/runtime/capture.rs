//! Triggered capture at the loop rate: a RAM ring of every tick's sample, frozen around a
//! trigger — the board's oscilloscope.
//!
//! Armed, the ring records every tick ([`Capture::push`], called by the tick's glue with
//! the tick's [`TickSample`]); the first tick on which the [`Trigger`] holds is the
//! trigger row (t = 0), and `post` further ticks are recorded after it; then the capture
//! is [`Phase::Done`] and keeps its rows until the next [`Capture::arm`]. Up to `pre`
//! ticks before the trigger are kept (fewer if the trigger came sooner after arming).
//! `pre + 1 + post` must fit the ring.
//!
//! Per tick and slave the ring keeps target and actual position (I24F8 µm raw, ±8.39 m,
//! 3.9 nm), the valve DAC code (LSB, 0 = null), both chamber pressures (centibar, u16:
//! 0.01 bar, 0 … 655.35 bar, saturating); per tick the master (whole counts, wrapping i32) and a flags
//! byte ([`TickSample::flags`]: state, hold reason, valve power, E-stop, a command
//! applied). The
//! following error is target − actual (not stored). A row is 4 + 14·S bytes (32 B for
//! the board's two slaves) plus the flags byte, so the board's 2 048 rows — 2.048 s at
//! 1 kHz — take 67 584 B (the firmware keeps the rows in the F407's 64 KiB CCM RAM).
//!
//! Triggers ([`Trigger`]): `now` (the first recorded tick), `fault` (entering Fault),
//! `state` (any change of the state bits), `command` (a tick that applied a host
//! command — one the runtime refused does not count), and a level on one channel (`above` / `below` a raw value, in the
//! channel's unit as stored: [`Channel`]).

use super::tick::{TickSample, FLAG_COMMAND, STATE_MASK};

/// One recorded tick (see the module docs for units).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CaptureRow<const S: usize> {
    /// Master, whole counts (the I48F16 master's integer part, wrapping).
    pub master: i32,
    /// Per slave: target, I24F8 µm raw.
    pub target_um: [i32; S],
    /// Per slave: measured position, I24F8 µm raw.
    pub actual_um: [i32; S],
    /// Per slave: valve DAC code, LSB.
    pub dac: [i16; S],
    /// Per slave: chamber A and B pressure, centibar.
    pub pressure_cbar: [[u16; 2]; S],
}

impl<const S: usize> CaptureRow<S> {
    /// An all-zero row.
    pub const ZERO: Self = Self {
        master: 0,
        target_um: [0; S],
        actual_um: [0; S],
        dac: [0; S],
        pressure_cbar: [[0; 2]; S],
    };

    fn of(s: &TickSample<S>) -> Self {
        Self {
            // The integer part of I48F16, wrapping as a 32-bit encoder counter does.
            master: (s.master >> 16) as i32,
            target_um: s.target_um,
            actual_um: s.actual_um,
            dac: s.dac,
            pressure_cbar: s.pressure_cbar,
        }
    }

    /// A channel's value in its stored unit (`None`: no such slave).
    pub fn channel(&self, c: Channel) -> Option<i32> {
        let i = |a: u8| usize::from(a);
        Some(match c {
            Channel::Master => self.master,
            Channel::Target(a) => *self.target_um.get(i(a))?,
            Channel::Actual(a) => *self.actual_um.get(i(a))?,
            Channel::Error(a) => self
                .target_um
                .get(i(a))?
                .wrapping_sub(*self.actual_um.get(i(a))?),
            Channel::Dac(a) => i32::from(*self.dac.get(i(a))?),
            Channel::PressureA(a) => i32::from(self.pressure_cbar.get(i(a))?[0]),
            Channel::PressureB(a) => i32::from(self.pressure_cbar.get(i(a))?[1]),
        })
    }
}

/// A recorded channel; its unit is the row's: I24F8 µm raw for target, actual and error
/// (target − actual), LSB for the DAC code, centibar for pressures, counts for the master.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Channel {
    /// Master, counts.
    Master,
    /// Slave target.
    Target(u8),
    /// Slave position.
    Actual(u8),
    /// Slave following error.
    Error(u8),
    /// Valve DAC code.
    Dac(u8),
    /// Chamber A pressure.
    PressureA(u8),
    /// Chamber B pressure.
    PressureB(u8),
}

impl Channel {
    /// Wire form: (kind, slave). Kinds 0 master, 1 target, 2 actual, 3 error, 4 DAC,
    /// 5 pressure A, 6 pressure B.
    pub const fn to_wire(self) -> (u8, u8) {
        match self {
            Channel::Master => (0, 0),
            Channel::Target(a) => (1, a),
            Channel::Actual(a) => (2, a),
            Channel::Error(a) => (3, a),
            Channel::Dac(a) => (4, a),
            Channel::PressureA(a) => (5, a),
            Channel::PressureB(a) => (6, a),
        }
    }

    /// From the wire form (`None`: unknown kind).
    pub const fn from_wire(kind: u8, axis: u8) -> Option<Self> {
        Some(match kind {
            0 => Channel::Master,
            1 => Channel::Target(axis),
            2 => Channel::Actual(axis),
            3 => Channel::Error(axis),
            4 => Channel::Dac(axis),
            5 => Channel::PressureA(axis),
            6 => Channel::PressureB(axis),
            _ => return None,
        })
    }
}

/// What starts the post-trigger part of a capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Trigger {
    /// The first tick recorded after arming.
    Now,
    /// The first tick in Fault after a tick that was not.
    Fault,
    /// The first tick whose state bits differ from the tick before.
    StateChange,
    /// The first tick that applied a host command.
    Command,
    /// The first tick on which the channel is above `value` (its stored unit).
    Above {
        /// The channel.
        channel: Channel,
        /// The level.
        value: i32,
    },
    /// The first tick on which the channel is below `value`.
    Below {
        /// The channel.
        channel: Channel,
        /// The level.
        value: i32,
    },
}

/// Where a capture is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Phase {
    /// Never armed.
    Idle,
    /// Recording, waiting for the trigger.
    Armed,
    /// Triggered, recording the post-trigger ticks.
    Triggered,
    /// Complete: the rows are kept until the next arm.
    Done,
}

/// Why [`Capture::arm`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CaptureError {
    /// `pre + 1 + post` exceeds the ring (its capacity in rows).
    TooLong {
        /// Rows the ring holds.
        capacity: u32,
    },
    /// The trigger names a slave the board does not have.
    NoChannel,
}

/// A capture's state and where its rows are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CaptureInfo {
    /// Phase.
    pub phase: Phase,
    /// Ticks kept before the trigger row.
    pub pre: u32,
    /// Rows of the finished capture (`pre + 1 + post`; 0 until [`Phase::Done`]).
    pub rows: u32,
    /// Tick number of the trigger row.
    pub trigger_tick: u32,
    /// Rows the ring holds.
    pub capacity: u32,
}

/// The capture ring over storage the board provides (`rows` and `flags` of equal length;
/// the firmware's are statics in CCM RAM, so nothing this large is ever on a stack).
pub struct Capture<'a, const S: usize> {
    rows: &'a mut [CaptureRow<S>],
    flags: &'a mut [u8],
    trigger: Trigger,
    phase: Phase,
    pre: u32,
    post: u32,
    /// Next ring index to write.
    head: usize,
    /// Rows written since the arm (saturates at the capacity).
    filled: usize,
    /// Ring index of the trigger row.
    trigger_at: usize,
    trigger_tick: u32,
    post_left: u32,
    /// The previous tick's flags (state-change and fault edges; kept across an arm).
    last_flags: Option<u8>,
}

impl<'a, const S: usize> Capture<'a, S> {
    /// A capture over `rows` and `flags` (the shorter length is the capacity).
    pub fn new(rows: &'a mut [CaptureRow<S>], flags: &'a mut [u8]) -> Self {
        Self {
            rows,
            flags,
            trigger: Trigger::Now,
            phase: Phase::Idle,
            pre: 0,
            post: 0,
            head: 0,
            filled: 0,
            trigger_at: 0,
            trigger_tick: 0,
            post_left: 0,
            last_flags: None,
        }
    }

    /// Rows the ring holds.
    pub fn capacity(&self) -> usize {
        self.rows.len().min(self.flags.len())
    }

    /// Arms a new capture (the previous one's rows are dropped).
    pub fn arm(&mut self, trigger: Trigger, pre: u32, post: u32) -> Result<(), CaptureError> {
        let cap = self.capacity();
        let capacity = u32::try_from(cap).unwrap_or(u32::MAX);
        let total = pre.checked_add(post).and_then(|n| n.checked_add(1));
        if total.is_none_or(|n| n > capacity) {
            return Err(CaptureError::TooLong { capacity });
        }
        if let Trigger::Above { channel, .. } | Trigger::Below { channel, .. } = trigger {
            if CaptureRow::<S>::ZERO.channel(channel).is_none() {
                return Err(CaptureError::NoChannel);
            }
        }
        *self = Self {
            rows: core::mem::take(&mut self.rows),
            flags: core::mem::take(&mut self.flags),
            trigger,
            phase: Phase::Armed,
            pre,
            post,
            last_flags: self.last_flags,
            ..Self::new(&mut [], &mut [])
        };
        Ok(())
    }

    /// Where the capture is.
    pub fn info(&self) -> CaptureInfo {
        let done = self.phase == Phase::Done;
        CaptureInfo {
            phase: self.phase,
            pre: self.pre_kept(),
            rows: if done {
                self.pre_kept().saturating_add(1).saturating_add(self.post)
            } else {
                0
            },
            trigger_tick: self.trigger_tick,
            capacity: u32::try_from(self.capacity()).unwrap_or(u32::MAX),
        }
    }

    /// Ticks before the trigger row that are kept: `pre`, or fewer if the trigger came
    /// sooner after the arm.
    fn pre_kept(&self) -> u32 {
        if matches!(self.phase, Phase::Idle | Phase::Armed) {
            return 0;
        }
        // `filled` counts the trigger row and the post rows recorded so far.
        let recorded_post = self.post.saturating_sub(self.post_left);
        let before = self
            .filled
            .saturating_sub(1)
            .saturating_sub(recorded_post as usize);
        self.pre.min(u32::try_from(before).unwrap_or(u32::MAX))
    }

    /// Records one tick (the tick's glue calls this every tick).
    #[inline]
    pub fn push(&mut self, s: &TickSample<S>) {
        // Every tick's flags, armed or not: a fault in the first tick after the arm is
        // still an edge.
        let prev = self.last_flags.replace(s.flags);
        if !matches!(self.phase, Phase::Armed | Phase::Triggered) {
            return;
        }
        let cap = self.capacity();
        let at = self.head;
        let row = CaptureRow::of(s);
        if let (Some(r), Some(f)) = (self.rows.get_mut(at), self.flags.get_mut(at)) {
            *r = row;
            *f = s.flags;
        }
        self.head = at.saturating_add(1).checked_rem(cap).unwrap_or(0);
        self.filled = self.filled.saturating_add(1).min(cap);
        match self.phase {
            Phase::Armed if self.fires(&row, s.flags, prev) => {
                self.phase = Phase::Triggered;
                self.trigger_at = at;
                self.trigger_tick = s.tick;
                self.post_left = self.post;
                // Rows beyond `pre` before the trigger are not kept in the count.
                let keep = usize::try_from(self.pre).unwrap_or(usize::MAX);
                self.filled = self.filled.min(keep.saturating_add(1));
                if self.post == 0 {
                    self.phase = Phase::Done;
                }
            }
            Phase::Triggered => {
                self.post_left = self.post_left.saturating_sub(1);
                if self.post_left == 0 {
                    self.phase = Phase::Done;
                }
            }
            _ => {}
        }
    }

    fn fires(&self, row: &CaptureRow<S>, flags: u8, prev: Option<u8>) -> bool {
        let state = flags & STATE_MASK;
        match self.trigger {
            Trigger::Now => true,
            Trigger::Fault => state == FAULT_STATE && prev.is_some_and(|p| p & STATE_MASK != state),
            Trigger::StateChange => prev.is_some_and(|p| p & STATE_MASK != state),
            Trigger::Command => flags & FLAG_COMMAND != 0,
            Trigger::Above { channel, value } => row.channel(channel).is_some_and(|v| v > value),
            Trigger::Below { channel, value } => row.channel(channel).is_some_and(|v| v < value),
        }
    }

    /// Row `k` of the finished capture (0 = `pre` ticks before the trigger) and its
    /// flags; `None` unless [`Phase::Done`] and `k` < [`CaptureInfo::rows`].
    pub fn row(&self, k: u32) -> Option<(CaptureRow<S>, u8)> {
        let info = self.info();
        if info.phase != Phase::Done || k >= info.rows {
            return None;
        }
        let cap = self.capacity();
        // trigger_at − pre + k, modulo the ring (all < cap, so no overflow in the sum).
        let back = usize::try_from(info.pre).ok()?;
        let idx = self
            .trigger_at
            .checked_add(cap)?
            .checked_sub(back)?
            .checked_add(usize::try_from(k).ok()?)?
            .checked_rem(cap)?;
        Some((*self.rows.get(idx)?, *self.flags.get(idx)?))
    }
}

/// The Fault state in a flags byte's state bits ([`super::tick::STATE_MASK`]).
const FAULT_STATE: u8 = 3;

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;

    fn sample(tick: u32, state: u8, err_um: i32) -> TickSample<2> {
        TickSample {
            tick,
            master: i64::from(tick) << 16,
            target_um: [err_um << 8, 0],
            actual_um: [0, i32::try_from(tick).unwrap()],
            dac: [1, -1],
            pressure_cbar: [[10_000, 5_000], [0, 0]],
            flags: state,
        }
    }

    fn ring(n: usize) -> (vec::Vec<CaptureRow<2>>, vec::Vec<u8>) {
        (vec![CaptureRow::ZERO; n], vec![0; n])
    }

    #[test]
    fn pre_and_post_ticks_around_a_fault() {
        let (mut r, mut f) = ring(100);
        let mut c = Capture::new(&mut r, &mut f);
        assert_eq!(c.info().phase, Phase::Idle);
        c.push(&sample(0, 1, 0)); // not armed: not recorded
        c.arm(Trigger::Fault, 20, 10).unwrap();
        for t in 1..=200 {
            // Following (1) until tick 150, then Fault (3).
            c.push(&sample(t, if t >= 150 { 3 } else { 1 }, 0));
        }
        let i = c.info();
        assert_eq!(i.phase, Phase::Done);
        assert_eq!((i.pre, i.rows, i.trigger_tick), (20, 31, 150));
        let ticks: vec::Vec<i32> = (0..31).map(|k| c.row(k).unwrap().0.master).collect();
        assert_eq!(ticks, (130..=160).collect::<vec::Vec<i32>>());
        assert_eq!(
            c.row(20).unwrap().1,
            3,
            "the trigger row is the first in Fault"
        );
        assert_eq!(c.row(19).unwrap().1, 1);
        assert_eq!(c.row(31), None);
        // Channels in their stored units.
        let (row, _) = c.row(0).unwrap();
        assert_eq!(row.channel(Channel::PressureB(0)), Some(5_000));
        assert_eq!(row.channel(Channel::Actual(1)), Some(130));
        assert_eq!(row.channel(Channel::Dac(1)), Some(-1));
        assert_eq!(row.channel(Channel::Dac(2)), None);
    }

    #[test]
    fn a_trigger_soon_after_the_arm_keeps_fewer_pre_ticks_and_the_ring_wraps() {
        let (mut r, mut f) = ring(16);
        let mut c = Capture::new(&mut r, &mut f);
        c.arm(Trigger::Now, 5, 3).unwrap();
        for t in 0..10 {
            c.push(&sample(t, 0, 0));
        }
        let i = c.info();
        assert_eq!((i.pre, i.rows, i.trigger_tick), (0, 4, 0));
        // A level trigger after the ring has wrapped several times.
        let err = Channel::Error(0);
        c.arm(
            Trigger::Above {
                channel: err,
                value: 256 * 50,
            },
            9,
            6,
        )
        .unwrap();
        for t in 0..100 {
            c.push(&sample(t, 1, if t >= 77 { 60 } else { 10 }));
        }
        let i = c.info();
        assert_eq!((i.pre, i.rows, i.trigger_tick), (9, 16, 77));
        let m: vec::Vec<i32> = (0..16).map(|k| c.row(k).unwrap().0.master).collect();
        assert_eq!(m, (68..=83).collect::<vec::Vec<i32>>());
        // Below, state change and command.
        c.arm(
            Trigger::Below {
                channel: err,
                value: 0,
            },
            0,
            0,
        )
        .unwrap();
        c.push(&sample(1, 1, 5));
        c.push(&sample(2, 1, -1));
        assert_eq!(c.info().trigger_tick, 2);
        c.arm(Trigger::StateChange, 1, 1).unwrap();
        for (t, s) in [(5, 1), (6, 1), (7, 0), (8, 0)] {
            c.push(&sample(t, s, 0));
        }
        assert_eq!((c.info().trigger_tick, c.info().rows), (7, 3));
        c.arm(Trigger::Command, 0, 0).unwrap();
        c.push(&sample(1, 0, 0));
        c.push(&sample(2, FLAG_COMMAND, 0));
        assert_eq!(c.info().trigger_tick, 2);
    }

    #[test]
    fn a_fault_in_the_first_tick_after_the_arm_is_an_edge_but_a_standing_one_is_not() {
        let (mut r, mut f) = ring(16);
        let mut c = Capture::new(&mut r, &mut f);
        c.push(&sample(1, 1, 0)); // following, not armed
        c.arm(Trigger::Fault, 2, 2).unwrap();
        c.push(&sample(2, 3, 0));
        assert_eq!(
            (c.info().phase, c.info().trigger_tick),
            (Phase::Triggered, 2)
        );
        c.arm(Trigger::Fault, 2, 2).unwrap();
        for t in 3..20 {
            c.push(&sample(t, 3, 0)); // in Fault all along
        }
        assert_eq!(c.info().phase, Phase::Armed);
    }

    #[test]
    fn a_capture_longer_than_the_ring_or_on_a_missing_slave_is_refused() {
        let (mut r, mut f) = ring(16);
        let mut c = Capture::new(&mut r, &mut f);
        assert_eq!(
            c.arm(Trigger::Now, 10, 6),
            Err(CaptureError::TooLong { capacity: 16 })
        );
        assert_eq!(
            c.arm(Trigger::Now, u32::MAX, 1),
            Err(CaptureError::TooLong { capacity: 16 })
        );
        let ch = Channel::Error(2);
        assert_eq!(
            c.arm(
                Trigger::Above {
                    channel: ch,
                    value: 0
                },
                1,
                1
            ),
            Err(CaptureError::NoChannel)
        );
        assert_eq!(c.info().phase, Phase::Idle, "nothing changed");
        assert!(c.arm(Trigger::Now, 10, 5).is_ok());
        // Not done yet: no rows to read.
        assert_eq!(c.row(0), None);
        // An empty ring is never armed.
        let mut c0: Capture<'_, 2> = Capture::new(&mut [], &mut []);
        assert!(c0.arm(Trigger::Now, 0, 0).is_err());
        c0.push(&sample(0, 0, 0));
        for k in 1..7 {
            assert_eq!(Channel::from_wire(k, 1).map(Channel::to_wire), Some((k, 1)));
        }
        assert_eq!(Channel::from_wire(0, 1), Some(Channel::Master));
        assert_eq!(Channel::from_wire(7, 0), None);
    }
}
