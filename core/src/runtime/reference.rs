//! Position reference of the slave axes: where each cylinder *is*, for tables that are
//! absolute.
//!
//! An incremental encoder counts from wherever the cylinder sat at power-up, so after a
//! reset the measured position is `count · scale + slave_offset_um` with an unknown
//! error. Each slave therefore has a reference mode ([`ReferenceMode`]):
//!
//! - `Absolute`: the count *is* the position (an absolute encoder, or a simulated one);
//!   referenced from boot. A set-position on it changes its offset, which the protocol
//!   layer persists with Save.
//! - `Incremental`: unreferenced at boot; Start (and Hold from Idle) are refused with
//!   `CommandError::NotReferenced` until it is referenced by
//!   - **set-position** (`Command::SetPosition`): the operator states where the axis
//!     is; the reference offset becomes stated − measured;
//!   - **homing** (`Command::Home`): armed, then the next edge of the axis' reference
//!     input or encoder index (the board latches the count in hardware,
//!     `EncoderInput::reference_edges`) makes the position at that count the axis'
//!     home position (`RuntimeConfig::home_position_um`). The move across the
//!     reference is the operator's (jog, or the machine's manual valve): the runtime
//!     does not move an axis it cannot yet place.
//!
//! Units: µm, `I24F8` ([`PosUm`]); the reference offset is added to the configured
//! `slave_offset_um`, saturating (range ±8.39 m).

use crate::units::PosUm;

/// How a slave's position is referenced (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReferenceMode {
    /// The count is the position: referenced from boot.
    #[default]
    Absolute,
    /// Counts from power-up: referenced by set-position or homing.
    Incremental,
}

/// One slave's reference state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RefState {
    /// The position is not known.
    #[default]
    Unreferenced,
    /// Homing armed: waiting for the reference edge.
    Homing,
    /// The position is known.
    Referenced,
}

/// Every slave's reference: mode, state and offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct References<const S: usize> {
    mode: [ReferenceMode; S],
    state: [RefState; S],
    /// Added to every measured position, µm.
    offset_um: [PosUm; S],
    /// Position at the reference edge, µm.
    home_um: [PosUm; S],
}

impl<const S: usize> References<S> {
    /// At boot: absolute slaves referenced, incremental ones not; offsets 0.
    pub fn new(mode: [ReferenceMode; S], home_um: [PosUm; S]) -> Self {
        let mut state = [RefState::Unreferenced; S];
        for (s, m) in state.iter_mut().zip(mode.iter()) {
            if *m == ReferenceMode::Absolute {
                *s = RefState::Referenced;
            }
        }
        Self {
            mode,
            state,
            offset_um: [PosUm::ZERO; S],
            home_um,
        }
    }

    /// The reference offsets, µm.
    pub fn offsets(&self) -> &[PosUm; S] {
        &self.offset_um
    }

    /// Each slave's position at its reference edge (where homing references it), µm.
    pub fn home_um(&self) -> &[PosUm; S] {
        &self.home_um
    }

    /// Sets where homing references slave `axis` (from its next edge on; a slave
    /// already referenced keeps its offset); `None` for no such axis.
    pub fn set_home(&mut self, axis: u8, home_um: PosUm) -> Option<()> {
        *self.home_um.get_mut(usize::from(axis))? = home_um;
        Some(())
    }

    /// Drops slave `axis`' reference if it is incremental (its offset no longer means
    /// anything, e.g. after its encoder scale changed); an absolute slave keeps it.
    /// `None` for no such axis.
    pub fn drop_incremental(&mut self, axis: u8) -> Option<()> {
        let i = usize::from(axis);
        if *self.mode.get(i)? == ReferenceMode::Incremental {
            *self.state.get_mut(i)? = RefState::Unreferenced;
            *self.offset_um.get_mut(i)? = PosUm::ZERO;
        }
        Some(())
    }

    /// Every slave's state.
    pub fn states(&self) -> &[RefState; S] {
        &self.state
    }

    /// The first slave that is not referenced, if any.
    pub fn first_unreferenced(&self) -> Option<u8> {
        self.state
            .iter()
            .position(|s| *s != RefState::Referenced)
            .and_then(|i| u8::try_from(i).ok())
    }

    /// Set-position: slave `axis` is at `stated_um` while it measures `measured_um`
    /// (with the present offset). Returns the new offset; `None` for no such axis.
    pub fn set_position(
        &mut self,
        axis: u8,
        measured_um: PosUm,
        stated_um: PosUm,
    ) -> Option<PosUm> {
        let i = usize::from(axis);
        let (off, st) = (self.offset_um.get_mut(i)?, self.state.get_mut(i)?);
        let raw = measured_um.saturating_sub(*off);
        *off = stated_um.saturating_sub(raw);
        *st = RefState::Referenced;
        Some(*off)
    }

    /// Sets slave `axis`' offset directly (a persisted offset of an absolute axis,
    /// restored at boot); `None` for no such axis.
    pub fn restore_offset(&mut self, axis: u8, offset_um: PosUm) -> Option<()> {
        let i = usize::from(axis);
        *self.offset_um.get_mut(i)? = offset_um;
        *self.state.get_mut(i)? = RefState::Referenced;
        Some(())
    }

    /// Arms homing of slave `axis` (its reference is dropped until the edge comes);
    /// `None` for no such axis.
    pub fn arm_home(&mut self, axis: u8) -> Option<()> {
        *self.state.get_mut(usize::from(axis))? = RefState::Homing;
        Some(())
    }

    /// A reference edge of slave `i` latched at raw position `raw_um` (the count's
    /// position without the reference offset): if homing is armed, the axis is
    /// referenced there. Returns whether it was.
    pub fn on_edge(&mut self, i: usize, raw_um: PosUm) -> bool {
        let (Some(st), Some(off), Some(home)) = (
            self.state.get_mut(i),
            self.offset_um.get_mut(i),
            self.home_um.get(i),
        ) else {
            return false;
        };
        if *st != RefState::Homing {
            return false;
        }
        *off = home.saturating_sub(raw_um);
        *st = RefState::Referenced;
        true
    }

    /// Whether slave `axis` is absolute (its offset is worth persisting).
    pub fn is_absolute(&self, axis: u8) -> bool {
        self.mode.get(usize::from(axis)) == Some(&ReferenceMode::Absolute)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn um(x: i32) -> PosUm {
        PosUm::from_num(x)
    }

    #[test]
    fn set_position_and_homing() {
        let mut r = References::<2>::new(
            [ReferenceMode::Incremental, ReferenceMode::Absolute],
            [um(1000), um(0)],
        );
        assert_eq!(r.first_unreferenced(), Some(0));
        // Measured 40 µm (offset 0) while the operator says 250 mm.
        assert_eq!(r.set_position(0, um(40), um(250_000)), Some(um(249_960)));
        assert_eq!(r.first_unreferenced(), None);
        // A second set-position is relative to the raw count, not to the last one.
        assert_eq!(r.set_position(0, um(250_010), um(100)), Some(um(50)));
        // Homing: unreferenced until the edge; an edge not armed changes nothing.
        assert!(!r.on_edge(0, um(7)));
        r.arm_home(0).unwrap();
        assert_eq!(r.first_unreferenced(), Some(0));
        assert!(r.on_edge(0, um(-20)));
        assert_eq!(r.offsets()[0], um(1020));
        assert_eq!(r.states()[0], RefState::Referenced);
        assert!(r.is_absolute(1) && !r.is_absolute(0));
        assert_eq!(r.set_position(2, um(0), um(0)), None);
        assert_eq!(r.arm_home(9), None);
        assert!(!r.on_edge(5, um(0)));
    }
}
