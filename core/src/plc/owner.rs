//! Control ownership: only one side moves the machine at a time.
//!
//! A board is reached from its serial host (`host-sim`) and from a PLC (Modbus; later a
//! CANopen master). Reads are always allowed. A motion command or a settings write from
//! a side that does not own the machine is refused and changes nothing — over Modbus
//! with exception 01 (ILLEGAL FUNCTION: "the server is in the wrong state to process a
//! request of this type", Modbus Application Protocol v1.1b3 §7), [`OwnerError::MODBUS_EXCEPTION`].
//!
//! Rules ([`Ownership::take`]):
//! - a side takes ownership when nobody owns the machine, or it already owns it;
//! - it takes it from the other side only while the machine is Idle or Fault (nothing
//!   moves), or when the other side has timed out (the serial link's `link/timeout_ms`,
//!   the PLC's heartbeat `plc/heartbeat_ms`: [`Heartbeat`]) — the axes are then holding;
//! - the owner releases it by writing "none"; another side cannot release it.

/// A side that can own the machine (its value in the `owner` register).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u16)]
pub enum Side {
    /// Nobody: motion and settings writes are refused from every side.
    None = 0,
    /// The serial host (`host-sim`).
    Host = 1,
    /// The PLC (Modbus).
    Plc = 2,
}

impl Side {
    /// The side of a register value (0, 1, 2), `None` for another value.
    pub const fn from_register(v: u16) -> Option<Self> {
        match v {
            0 => Some(Self::None),
            1 => Some(Self::Host),
            2 => Some(Self::Plc),
            _ => None,
        }
    }
}

/// Why an ownership change or a write was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OwnerError {
    /// `owner` owns the machine: the asking side may read, not move or configure it.
    NotOwner {
        /// Who owns it.
        owner: Side,
    },
    /// The machine moves under the other side, which has not timed out.
    Busy {
        /// Who owns it.
        owner: Side,
    },
}

impl OwnerError {
    /// The Modbus exception code of a refusal: 01 ILLEGAL FUNCTION (the server is in the
    /// wrong state for this request).
    pub const MODBUS_EXCEPTION: u8 = 0x01;
}

/// What the machine is doing, as ownership needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MachineNow {
    /// Idle or Fault: nothing moves.
    pub at_rest: bool,
    /// The current owner's link has timed out (its axes hold).
    pub owner_timed_out: bool,
}

/// Who owns the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ownership {
    owner: Side,
}

impl Ownership {
    /// Nobody owns the machine (the state at power-up).
    pub const NONE: Self = Self { owner: Side::None };

    /// The owner.
    pub const fn owner(&self) -> Side {
        self.owner
    }

    /// `side` asks to own the machine (`Side::None`: `side` releases it). See the module
    /// docs for the rules; on an error nothing changes.
    pub fn take(&mut self, side: Side, wants: Side, now: MachineNow) -> Result<(), OwnerError> {
        let owner = self.owner;
        match wants {
            Side::None if owner == side || owner == Side::None => {
                self.owner = Side::None;
                Ok(())
            }
            Side::None => Err(OwnerError::NotOwner { owner }),
            w if w != side => Err(OwnerError::NotOwner { owner }),
            _ if owner == side || owner == Side::None => {
                self.owner = side;
                Ok(())
            }
            _ if now.at_rest || now.owner_timed_out => {
                self.owner = side;
                Ok(())
            }
            _ => Err(OwnerError::Busy { owner }),
        }
    }

    /// Whether `side` may move or configure the machine.
    pub fn may_write(&self, side: Side) -> Result<(), OwnerError> {
        if side != Side::None && self.owner == side {
            Ok(())
        } else {
            Err(OwnerError::NotOwner { owner: self.owner })
        }
    }
}

/// The PLC's heartbeat: the PLC writes a changing value to `heartbeat`; no change for
/// `plc/heartbeat_ms` means the PLC is gone. Times are a wrapping millisecond clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Heartbeat {
    last: u16,
    last_ms: u32,
    lost: bool,
}

impl Heartbeat {
    /// A heartbeat last seen at `now_ms` with value 0.
    pub const fn new(now_ms: u32) -> Self {
        Self {
            last: 0,
            last_ms: now_ms,
            lost: false,
        }
    }

    /// The PLC wrote `value` at `now_ms`: a changed value restarts the timeout and clears
    /// a loss; the same value again is no heartbeat.
    pub fn write(&mut self, value: u16, now_ms: u32) {
        if value != self.last {
            self.last = value;
            self.last_ms = now_ms;
            self.lost = false;
        }
    }

    /// Restarts the timeout at `now_ms` (the PLC took the machine or started a motion:
    /// the time before does not count against it).
    pub fn restart(&mut self, now_ms: u32) {
        self.last_ms = now_ms;
        self.lost = false;
    }

    /// Checks at `now_ms` against `timeout_ms` (0: never lost). Returns `true` once, when
    /// the heartbeat is lost.
    pub fn watch(&mut self, now_ms: u32, timeout_ms: u32) -> bool {
        if timeout_ms == 0 || self.lost {
            return false;
        }
        self.lost = now_ms.wrapping_sub(self.last_ms) >= timeout_ms;
        self.lost
    }

    /// Whether the heartbeat is lost now.
    pub const fn lost(&self) -> bool {
        self.lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MOVING: MachineNow = MachineNow {
        at_rest: false,
        owner_timed_out: false,
    };
    const AT_REST: MachineNow = MachineNow {
        at_rest: true,
        owner_timed_out: false,
    };

    #[test]
    fn one_side_at_a_time() {
        let mut o = Ownership::NONE;
        assert_eq!(
            o.may_write(Side::Plc),
            Err(OwnerError::NotOwner { owner: Side::None })
        );
        o.take(Side::Plc, Side::Plc, MOVING).unwrap();
        assert_eq!(o.owner(), Side::Plc);
        assert_eq!(o.may_write(Side::Plc), Ok(()));
        assert_eq!(
            o.may_write(Side::Host),
            Err(OwnerError::NotOwner { owner: Side::Plc })
        );
        // the host cannot take it while the machine moves under a live PLC
        assert_eq!(
            o.take(Side::Host, Side::Host, MOVING),
            Err(OwnerError::Busy { owner: Side::Plc })
        );
        assert_eq!(o.owner(), Side::Plc, "a refusal changes nothing");
        // nor release it, nor give it to someone else
        assert!(o.take(Side::Host, Side::None, AT_REST).is_err());
        assert!(o.take(Side::Host, Side::Plc, AT_REST).is_err());
        // at rest, or once the PLC timed out, it may
        o.take(Side::Host, Side::Host, AT_REST).unwrap();
        assert_eq!(o.owner(), Side::Host);
        let gone = MachineNow {
            at_rest: false,
            owner_timed_out: true,
        };
        o.take(Side::Plc, Side::Plc, gone).unwrap();
        assert_eq!(o.owner(), Side::Plc);
        // the owner releases it
        o.take(Side::Plc, Side::None, MOVING).unwrap();
        assert_eq!(o.owner(), Side::None);
        assert_eq!(OwnerError::MODBUS_EXCEPTION, 1);
        assert_eq!(Side::from_register(2), Some(Side::Plc));
        assert_eq!(Side::from_register(3), None);
    }

    #[test]
    fn a_heartbeat_that_stops_changing_is_lost_once() {
        let mut h = Heartbeat::new(0);
        h.write(1, 10);
        assert!(!h.watch(500, 1000) && !h.watch(1009, 1000));
        h.write(1, 1005); // the same value is no heartbeat
        assert!(h.watch(1010, 1000), "lost 1000 ms after the last change");
        assert!(h.lost() && !h.watch(1020, 1000), "reported once");
        h.write(2, 1030);
        assert!(!h.lost());
        assert!(!h.watch(2000, 1000));
        h.restart(u32::MAX - 5);
        assert!(!h.watch(100, 1000), "the clock wraps");
        let mut off = Heartbeat::new(0);
        assert!(!off.watch(u32::MAX / 2, 0));
    }
}
