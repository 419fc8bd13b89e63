//! Faults of the runtime: what they are, their codes, and the set of causes seen.
//!
//! A fault drives every valve to its null output in the tick that detects it, drops the
//! valve-power enable and latches: the runtime stays in `Fault` until a `ClearFault`
//! command arrives *and* the cause is gone (see [`super::machine`]).
//!
//! Every fault has a 16-bit code `kind << 8 | index` (index = axis or encoder channel,
//! 0 where there is none), printed in hex on the host and in defmt logs:
//!
//! | code | fault | raised when | cleared when |
//! |---|---|---|---|
//! | `0x0100` | E-stop | the E-stop input is active (any state) | input released |
//! | `0x0200` | watchdog | the board booted from an independent-watchdog reset | at once (the reset is over) |
//! | `0x0300` | tick overrun | a tick was still running when the next period began, or a period was skipped | the tick that clears has no overrun |
//! | `0x0400` | master stalled | following, the master has moved and then stood still (< `stall_min_move_counts`) for `stall_timeout_s` | at once (no longer following) |
//! | `0x05cc` | encoder jump, channel `cc` (0 = master, 1… = slaves) | one tick's count change exceeds the channel's plausible maximum | the tick that clears has no jump |
//! | `0x06aa` | following error, slave `aa` (0-based) | following or holding, \|target − position\| > the axis limit | at once (not controlling) |
//! | `0x07aa` | controller fault on slave `aa` | the control law flags the axis (e.g. output saturated too long) | at once (not controlling) |
//! | `0x0800` | pressure input | `pressure_required` and the pressure inputs stopped updating (an ADC overrun stopped its DMA) | the tick that clears has live pressures again (the board restarts the converter) |

/// One fault cause.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// The E-stop input is active.
    EStop,
    /// The board came out of an independent-watchdog reset.
    Watchdog,
    /// The tick overran its period (or a period was skipped).
    Overrun,
    /// Following, the master stopped moving for longer than the stall timeout.
    MasterStalled,
    /// An implausible encoder step in one tick.
    EncoderJump {
        /// Encoder channel: 0 = master, 1 + i = slave i.
        channel: u8,
    },
    /// |target − position| beyond the slave's limit.
    FollowingError {
        /// Slave axis (0-based).
        axis: u8,
    },
    /// The control law reported a fault on a slave.
    Controller {
        /// Slave axis (0-based).
        axis: u8,
    },
    /// The pressure inputs stopped updating while a law that depends on them runs.
    PressureInput,
}

/// The kind of a fault, without its index (bit position in a [`FaultSet`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FaultKind {
    /// See [`Fault::EStop`].
    EStop = 1,
    /// See [`Fault::Watchdog`].
    Watchdog = 2,
    /// See [`Fault::Overrun`].
    Overrun = 3,
    /// See [`Fault::MasterStalled`].
    MasterStalled = 4,
    /// See [`Fault::EncoderJump`].
    EncoderJump = 5,
    /// See [`Fault::FollowingError`].
    FollowingError = 6,
    /// See [`Fault::Controller`].
    Controller = 7,
    /// [`Fault::PressureInput`].
    PressureInput = 8,
}

impl Fault {
    /// The fault's kind.
    pub const fn kind(self) -> FaultKind {
        match self {
            Fault::EStop => FaultKind::EStop,
            Fault::Watchdog => FaultKind::Watchdog,
            Fault::Overrun => FaultKind::Overrun,
            Fault::MasterStalled => FaultKind::MasterStalled,
            Fault::EncoderJump { .. } => FaultKind::EncoderJump,
            Fault::FollowingError { .. } => FaultKind::FollowingError,
            Fault::Controller { .. } => FaultKind::Controller,
            Fault::PressureInput => FaultKind::PressureInput,
        }
    }

    /// The axis or channel index (0 for faults without one).
    pub const fn index(self) -> u8 {
        match self {
            Fault::EncoderJump { channel } => channel,
            Fault::FollowingError { axis } | Fault::Controller { axis } => axis,
            _ => 0,
        }
    }

    /// The 16-bit code `kind << 8 | index` (see the module table).
    pub const fn code(self) -> u16 {
        ((self.kind() as u16) << 8) | self.index() as u16
    }

    /// A short name for people and JSON (`following_error`, `encoder_jump`, …).
    pub const fn name(self) -> &'static str {
        match self {
            Fault::EStop => "estop",
            Fault::Watchdog => "watchdog",
            Fault::Overrun => "overrun",
            Fault::MasterStalled => "master_stalled",
            Fault::EncoderJump { .. } => "encoder_jump",
            Fault::FollowingError { .. } => "following_error",
            Fault::Controller { .. } => "controller",
            Fault::PressureInput => "pressure_input",
        }
    }

    /// The slave axis the fault names, if it names one (an encoder jump on channel
    /// 1 + i names slave i; channel 0 is the master).
    pub const fn slave(self) -> Option<u8> {
        match self {
            Fault::FollowingError { axis } | Fault::Controller { axis } => Some(axis),
            Fault::EncoderJump { channel } => channel.checked_sub(1),
            _ => None,
        }
    }

    /// The fault with this code, if it is one.
    pub const fn from_code(code: u16) -> Option<Fault> {
        let index = (code & 0xff) as u8;
        let f = match code >> 8 {
            1 => Fault::EStop,
            2 => Fault::Watchdog,
            3 => Fault::Overrun,
            4 => Fault::MasterStalled,
            5 => Fault::EncoderJump { channel: index },
            6 => Fault::FollowingError { axis: index },
            7 => Fault::Controller { axis: index },
            8 => Fault::PressureInput,
            _ => return None,
        };
        if f.code() == code {
            Some(f)
        } else {
            None
        }
    }
}

/// The set of fault kinds seen since the fault latched (bit `kind` set).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultSet(pub u16);

impl FaultSet {
    /// No fault.
    pub const EMPTY: FaultSet = FaultSet(0);

    /// Adds a fault's kind.
    pub fn insert(&mut self, f: Fault) {
        self.0 |= 1u16 << (f.kind() as u16);
    }

    /// Whether a kind is in the set.
    pub const fn contains(self, k: FaultKind) -> bool {
        self.0 & (1u16 << (k as u16)) != 0
    }

    /// Whether the set is empty.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// The latched (first) fault and the tick that detected it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    /// The first cause.
    pub fault: Fault,
    /// Tick counter value when it latched.
    pub tick: u32,
}

/// Most events [`FaultHistory`] keeps.
pub const FAULT_HISTORY_LEN: usize = 16;

/// One fault as it was raised: the cause, the tick, and the value that tripped it with
/// its limit. Units by kind: following error — I24F8 µm raw (target − position, signed,
/// and the limit it exceeded: the law's own when the law flagged the axis, else the
/// runtime's); encoder jump — counts (the tick's signed step and the channel's plausible
/// maximum); master stalled — ticks (the stall timeout, as both: the master stood still
/// that long);
/// controller fault — the axis' following error and its limit at that tick, I24F8 µm
/// raw (for context); every other kind — 0 and 0 (a state, not a value: E-stop,
/// watchdog, overrun, pressure input).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultEvent {
    /// The cause.
    pub fault: Fault,
    /// Tick counter value when it was raised.
    pub tick: u32,
    /// The value that tripped it (unit by kind, above).
    pub value: i32,
    /// The limit it exceeded (unit by kind, above).
    pub limit: i32,
}

/// The last [`FAULT_HISTORY_LEN`] fault events, oldest first when read: the latching
/// cause of every fault, and each further kind seen while latched (a cause that stays
/// present is one event, not one per tick). Cleared only by a power cycle.
pub type FaultHistory = heapless::HistoryBuf<FaultEvent, FAULT_HISTORY_LEN>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_are_distinct() {
        let all = [
            Fault::EStop,
            Fault::Watchdog,
            Fault::Overrun,
            Fault::MasterStalled,
            Fault::EncoderJump { channel: 0 },
            Fault::EncoderJump { channel: 2 },
            Fault::FollowingError { axis: 1 },
            Fault::Controller { axis: 3 },
            Fault::PressureInput,
        ];
        for (i, a) in all.iter().enumerate() {
            assert_eq!(Fault::from_code(a.code()), Some(*a));
            for b in all.iter().skip(i + 1) {
                assert_ne!(a.code(), b.code());
            }
        }
        assert_eq!(Fault::EStop.code(), 0x0100);
        assert_eq!(Fault::EncoderJump { channel: 2 }.code(), 0x0502);
        assert_eq!(Fault::FollowingError { axis: 1 }.code(), 0x0601);
        assert_eq!(Fault::from_code(0x0101), None);
        assert_eq!(Fault::PressureInput.code(), 0x0800);
        assert_eq!(Fault::from_code(0x0900), None);
        assert_eq!(Fault::from_code(0), None);
    }

    #[test]
    fn set_collects_kinds() {
        let mut s = FaultSet::EMPTY;
        assert!(s.is_empty());
        s.insert(Fault::EStop);
        s.insert(Fault::FollowingError { axis: 1 });
        assert!(s.contains(FaultKind::EStop));
        assert!(s.contains(FaultKind::FollowingError));
        assert!(!s.contains(FaultKind::Overrun));
    }
}
