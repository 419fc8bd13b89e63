//! The parameters changed by SetParam since boot, kept so that Save can store them with
//! the table and boot can apply them again.
//!
//! A record is `(axis, param, value)`; a later SetParam of the same `(axis, param)`
//! replaces the earlier value (a board-wide parameter ignores the axis byte: it is kept under
//! axis 0). On flash a record is 6 bytes: `u8 axis · u8 param id · f32 value` (LE).

use super::msg::{ParamId, MAX_AXES};
use super::wire::{Reader, Writer};
use heapless::Vec;

/// Bytes of one record in a flash slot.
pub const RECORD_LEN: usize = 6;
/// Most records any board can hold: every parameter of every axis.
pub const MAX_RECORDS: usize = MAX_AXES * ParamId::COUNT;

/// One accepted SetParam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRecord {
    /// Slave axis (0 for MasterSpeedPerS).
    pub axis: u8,
    /// Which parameter.
    pub param: ParamId,
    /// Value, in the parameter's engineering unit (see [`ParamId`]).
    pub value: f32,
}

impl ParamRecord {
    /// Writes the 6-byte form.
    pub fn write(&self, w: &mut Writer<'_>) -> Option<()> {
        w.u8(self.axis)?;
        w.u8(self.param as u8)?;
        w.f32(self.value)
    }

    /// Reads the 6-byte form (`None` for an unknown parameter id).
    pub fn read(r: &mut Reader<'_>) -> Option<Self> {
        let axis = r.u8()?;
        let param = ParamId::from_u8(r.u8()?)?;
        let value = r.f32()?;
        Some(Self { axis, param, value })
    }
}

/// The parameters changed since boot, at most one record per `(axis, param)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamOverrides {
    recs: Vec<ParamRecord, MAX_RECORDS>,
}

impl ParamOverrides {
    /// No record.
    pub const fn new() -> Self {
        Self { recs: Vec::new() }
    }

    /// Records an accepted SetParam, replacing an earlier value of the same parameter.
    /// Returns `false` only if the set is full with other parameters (it cannot be with
    /// axes below [`MAX_AXES`]).
    pub fn record(&mut self, axis: u8, param: ParamId, value: f32) -> bool {
        // Both Kv (id 4) is kept as the two it sets, so a saved set replays in any order
        // (Kv, Kv−, Kv again must leave Kv− at the last Kv).
        if param == ParamId::KvLsbPerUmS {
            return self.record(axis, ParamId::KvPosLsbPerUmS, value)
                && self.record(axis, ParamId::KvNegLsbPerUmS, value);
        }
        // A board-wide parameter ignores the axis byte: one record, under axis 0.
        let axis = match param.info().scope {
            super::settings::Scope::Board => 0,
            super::settings::Scope::Axis => axis,
        };
        let rec = ParamRecord { axis, param, value };
        match self
            .recs
            .iter_mut()
            .find(|r| r.axis == axis && r.param == param)
        {
            Some(r) => {
                *r = rec;
                true
            }
            None => self.recs.push(rec).is_ok(),
        }
    }

    /// The records, in the order first set.
    pub fn as_slice(&self) -> &[ParamRecord] {
        &self.recs
    }

    /// The records, in the order first set.
    pub fn iter(&self) -> impl Iterator<Item = &ParamRecord> {
        self.recs.iter()
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.recs.len()
    }

    /// No record?
    pub fn is_empty(&self) -> bool {
        self.recs.is_empty()
    }

    /// Forgets every record.
    pub fn clear(&mut self) {
        self.recs.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_board_wide_parameter_is_one_record_whatever_the_axis_byte() {
        let mut o = ParamOverrides::new();
        assert!(o.record(1, ParamId::MasterFilterHz, 12.0));
        assert!(o.record(7, ParamId::MasterFilterHz, 9.0));
        assert!(o.record(1, ParamId::KpLsbPerUm, 0.5));
        let recs: std::vec::Vec<_> = o.iter().map(|r| (r.axis, r.param, r.value)).collect();
        assert_eq!(
            recs,
            [
                (0, ParamId::MasterFilterHz, 9.0),
                (1, ParamId::KpLsbPerUm, 0.5)
            ]
        );
    }

    #[test]
    fn a_later_value_replaces_an_earlier_one() {
        let mut o = ParamOverrides::new();
        assert!(o.record(1, ParamId::KpLsbPerUm, 0.5));
        assert!(o.record(0, ParamId::KpLsbPerUm, 0.7));
        assert!(o.record(1, ParamId::KpLsbPerUm, 0.9));
        // The master speed is one parameter whatever the axis byte says.
        assert!(o.record(3, ParamId::MasterSpeedPerS, 100.0));
        assert!(o.record(0, ParamId::MasterSpeedPerS, 200.0));
        let v: std::vec::Vec<_> = o.iter().map(|r| (r.axis, r.param, r.value)).collect();
        assert_eq!(
            v,
            [
                (1, ParamId::KpLsbPerUm, 0.9),
                (0, ParamId::KpLsbPerUm, 0.7),
                (0, ParamId::MasterSpeedPerS, 200.0)
            ]
        );
    }

    #[test]
    fn records_roundtrip_and_unknown_ids_are_refused() {
        let rec = ParamRecord {
            axis: 2,
            param: ParamId::ValveNullLsb,
            value: -12.5,
        };
        let mut b = [0u8; RECORD_LEN];
        let mut w = Writer::new(&mut b);
        rec.write(&mut w).unwrap();
        assert_eq!(w.len(), RECORD_LEN);
        assert_eq!(ParamRecord::read(&mut Reader::new(&b)), Some(rec));
        b[1] = 200;
        assert_eq!(ParamRecord::read(&mut Reader::new(&b)), None);
    }

    #[test]
    fn every_parameter_of_every_axis_fits() {
        let mut o = ParamOverrides::new();
        for a in 0..MAX_AXES as u8 {
            for p in 0..=255u8 {
                if let Some(p) = ParamId::from_u8(p) {
                    assert!(o.record(a, p, 1.0));
                }
            }
        }
        // A board-wide parameter is kept once.
        let board = super::super::settings::PARAMS
            .iter()
            .filter(|i| i.scope == super::super::settings::Scope::Board)
            .count();
        assert_eq!(board, 11);
        // … and both Kv (id 4) as the two it sets, not a record of its own.
        assert_eq!(o.len(), MAX_AXES * (ParamId::COUNT - board - 1) + board);
        assert!(o.iter().all(|r| r.param != ParamId::KvLsbPerUmS));
    }
}
