//! Two flash slots holding the active table and the changed parameters, so neither is
//! ever lost.
//!
//! Each slot is `slot_size` bytes (a multiple of the flash's erase size) at
//! `base + slot · slot_size`, slot ∈ {0, 1}. Layout (little-endian):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 12 | 0xFF (pads the magic to a 16-byte program unit) |
//! | 12 | 4 | magic `0x32545948` ("HYT2"), **written last**, its last byte last |
//! | 16 | 4 | generation: 1 + the newest valid slot's generation at save time |
//! | 20 | 4 | table id |
//! | 24 | 2 | columns |
//! | 26 | 2 | rows |
//! | 28 | 2 | parameter records P (the SetParams accepted since boot, [`ParamOverrides`]) |
//! | 30 | 2 | 0 (reserved) |
//! | 32 | 6 · P | records: `u8 axis · u8 param id · f32 value` |
//! | 32 + 6P | rows · (8 + 4·columns) | rows, as on the wire ([`super::msg::row_len`]) |
//! | 32 + 6P + L | 4 | CRC-32 of bytes 16 … 32 + 6P + L − 1 |
//!
//! **Save** ([`Store::save_keeping`]) erases the slot that is not the one to keep (the
//! handler passes the slot that booted or was saved last; without one, the slot that
//! does not hold the newest valid table), writes bytes 16 … end, then the magic — the
//! slot's **commit record** —, then reads the slot back and checks it; only then is the
//! Save acknowledged. **Boot** ([`super::Handler::boot`]) takes the valid slot with the
//! highest generation (valid: magic, CRC, columns = S, rows ≤ N, P ≤ S ·
//! [`ParamId::COUNT`]), applies its parameters as one set, and installs its table if it
//! passes the [`CamTable`] rules with the resulting limits; otherwise the other slot.
//! Then it makes what it read permanent: the commit record of the slot that booted is
//! programmed again ([`Store::confirm`]) and that of a slot that did not read as valid
//! is programmed to zero ([`Store::revoke`]).
//!
//! Why this survives the F407's flash (modelled in `ramflash`, measured by the
//! power-cut benchmark in `powercut_tests`): a cut erase leaves its sector undefined and
//! a cut program leaves the word half programmed, with weak cells that read differently
//! from one read to the next. The slot being written is never the slot that booted, so a
//! cut anywhere in a Save leaves that slot intact; the new slot's data is complete and
//! verified before its commit record is programmed, so only the commit record can be
//! half done — and a half-done commit record is settled at the next boot, one way or the
//! other, by confirm or revoke. Programming a word again over programmed content only
//! clears bits (RM0090 allows it; nothing but 1 → 0 changes).
//! Slots of the first layout ("HYT1", no parameters) are not valid in this one.
//!
//! Generations are compared as plain `u32`: at one save per second that is 136 years,
//! far beyond the flash's 10 000 erase cycles.

use super::frame::{Crc32, CRC32};
use super::msg::{row_len, ParamId};
use super::overrides::{ParamOverrides, ParamRecord, RECORD_LEN};
use super::wire::{Reader, Writer};
use crate::table::{CamTable, Node};
use embedded_storage::nor_flash::NorFlash;
use heapless::Vec;

/// Magic of a complete slot.
pub const MAGIC: u32 = 0x3254_5948;
/// Bytes before the parameter records.
pub const HEADER: usize = 32;
/// Size of the magic's program unit (a flash's WRITE_SIZE must divide it).
const MAGIC_UNIT: usize = 16;
/// Write buffer, bytes (a multiple of every supported WRITE_SIZE).
const BUF: usize = 64;

/// Why the store could not be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// Slot size not a multiple of ERASE_SIZE, WRITE_SIZE not dividing 16, the slots beyond
    /// the flash, or a full table of N rows with every parameter not fitting a slot.
    Geometry,
    /// The flash driver returned an error (or the power went).
    Flash,
    /// The written slot did not read back as written.
    Verify,
}

/// A valid slot's header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotHeader {
    /// Slot index, 0 or 1.
    pub slot: u8,
    /// Generation.
    pub generation: u32,
    /// Table id.
    pub id: u32,
    /// Rows.
    pub rows: u16,
    /// Parameter records.
    pub params: u16,
}

/// The two-slot store: where the slots are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Store {
    base: u32,
    slot_size: u32,
}

impl Store {
    /// No slots: a store not yet attached to a flash (the starting value of a handler
    /// that is a static, see `Handler::new`). Every read of it finds no valid slot and
    /// every save is refused with [`StoreError::Geometry`]; [`Store::new`] never returns
    /// it (a slot has at least one erase unit).
    pub const UNATTACHED: Self = Self {
        base: 0,
        slot_size: 0,
    };

    /// Checks the geometry for a flash `F` holding tables of up to `N` rows of `S` columns.
    pub fn new<F: NorFlash, const S: usize, const N: usize>(
        flash: &F,
        base: u32,
        slot_size: u32,
    ) -> Result<Self, StoreError> {
        let g = StoreError::Geometry;
        let size = usize::try_from(slot_size).map_err(|_| g)?;
        let need = row_len(S)
            .checked_mul(N)
            .and_then(|b| b.checked_add(HEADER + 4))
            .and_then(|b| b.checked_add(max_records(S).checked_mul(RECORD_LEN)?))
            .ok_or(g)?;
        let end = u64::from(base).saturating_add(u64::from(slot_size).saturating_mul(2));
        let ok = F::ERASE_SIZE > 0
            && F::WRITE_SIZE > 0
            && size.is_multiple_of(F::ERASE_SIZE)
            && MAGIC_UNIT.is_multiple_of(F::WRITE_SIZE)
            && BUF.is_multiple_of(F::WRITE_SIZE)
            && usize::try_from(base).is_ok_and(|b| b.is_multiple_of(F::ERASE_SIZE))
            && need <= size
            && end <= flash.capacity() as u64;
        if ok {
            Ok(Self { base, slot_size })
        } else {
            Err(g)
        }
    }

    fn slot_base(&self, slot: u8) -> u32 {
        if slot == 0 {
            self.base
        } else {
            self.base.saturating_add(self.slot_size)
        }
    }

    /// Reads a slot's header and checks its magic and CRC (the rows are streamed, not kept).
    pub fn scan<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
        slot: u8,
    ) -> Option<SlotHeader> {
        self.walk::<F, S, N>(flash, slot, |_| Some(()), |_| Some(()))
    }

    /// Reads a valid slot's parameter records into `params` and its rows into `nodes`
    /// (both empty if the slot is not valid).
    pub fn read_slot<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
        slot: u8,
        nodes: &mut Vec<Node<S>, N>,
        params: &mut ParamOverrides,
    ) -> Option<SlotHeader> {
        nodes.clear();
        params.clear();
        let h = self.walk::<F, S, N>(
            flash,
            slot,
            |r| params.record(r.axis, r.param, r.value).then_some(()),
            |n| nodes.push(n).ok(),
        );
        if h.is_none() {
            nodes.clear();
            params.clear();
        }
        h
    }

    fn walk<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
        slot: u8,
        mut each_param: impl FnMut(ParamRecord) -> Option<()>,
        mut each: impl FnMut(Node<S>) -> Option<()>,
    ) -> Option<SlotHeader> {
        if self.slot_size == 0 {
            return None;
        }
        let at = self.slot_base(slot);
        let mut hdr = [0u8; HEADER];
        flash.read(at, &mut hdr).ok()?;
        let mut r = Reader::new(&hdr);
        r.bytes(MAGIC_UNIT - 4)?;
        if r.u32()? != MAGIC {
            return None;
        }
        let mut crc = CRC32.digest();
        crc.update(hdr.get(MAGIC_UNIT..)?);
        let generation = r.u32()?;
        let id = r.u32()?;
        let columns = r.u16()?;
        let rows = r.u16()?;
        let params = r.u16()?;
        if usize::from(columns) != S
            || usize::from(rows) > N
            // 0 rows: settings saved without a table; 1 row is never a table.
            || rows == 1
            || usize::from(params) > max_records(S)
        {
            return None;
        }
        let mut off = at.checked_add(u32::try_from(HEADER).ok()?)?;
        for _ in 0..params {
            let mut rec = [0u8; RECORD_LEN];
            flash.read(off, &mut rec).ok()?;
            crc.update(&rec);
            each_param(ParamRecord::read(&mut Reader::new(&rec))?)?;
            off = off.checked_add(RECORD_LEN as u32)?;
        }
        let rl = row_len(S);
        let step = u32::try_from(rl).ok()?;
        let mut row = [0u8; super::msg::row_len(super::msg::MAX_AXES)];
        for _ in 0..rows {
            let buf = row.get_mut(..rl)?;
            flash.read(off, buf).ok()?;
            crc.update(buf);
            each(super::msg::read_row::<S>(&mut Reader::new(buf))?)?;
            off = off.checked_add(step)?;
        }
        let mut c = [0u8; 4];
        flash.read(off, &mut c).ok()?;
        (u32::from_le_bytes(c) == crc.finalize()).then_some(SlotHeader {
            slot,
            generation,
            id,
            rows,
            params,
        })
    }

    /// The newest valid slot, by generation.
    pub fn newest<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
    ) -> Option<SlotHeader> {
        let a = self.scan::<F, S, N>(flash, 0);
        let b = self.scan::<F, S, N>(flash, 1);
        match (a, b) {
            (Some(a), Some(b)) => Some(if b.generation > a.generation { b } else { a }),
            (a, b) => a.or(b),
        }
    }

    /// The valid slots, newest (highest generation) first: the order boot tries them.
    pub fn newest_first<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
    ) -> [Option<SlotHeader>; 2] {
        let a = self.scan::<F, S, N>(flash, 0);
        let b = self.scan::<F, S, N>(flash, 1);
        match (a, b) {
            (Some(x), Some(y)) if y.generation > x.generation => [b, a],
            _ => [a, b],
        }
    }

    /// Re-programs the commit record of `slot` (the one that booted). A commit record cut
    /// while it was programmed can read as complete on one boot and not on the next (weak
    /// cells); programming it again completes it, so the next boot reads what this one
    /// did. Programming the same value again only clears bits that should be clear.
    pub fn confirm<F: NorFlash>(&self, flash: &mut F, slot: u8) -> Result<(), StoreError> {
        self.write_commit(flash, slot, MAGIC)
    }

    /// Programs the commit record of `slot` (one that did not read as valid at boot) to
    /// zero, so a half-programmed record can never read as complete later and boot a
    /// table the board did not boot before. Zero only clears bits: any content allows it.
    pub fn revoke<F: NorFlash>(&self, flash: &mut F, slot: u8) -> Result<(), StoreError> {
        self.write_commit(flash, slot, 0)
    }

    fn write_commit<F: NorFlash>(
        &self,
        flash: &mut F,
        slot: u8,
        word: u32,
    ) -> Result<(), StoreError> {
        if self.slot_size == 0 {
            return Err(StoreError::Geometry);
        }
        let mut unit = [0xFFu8; MAGIC_UNIT];
        unit.get_mut(MAGIC_UNIT - 4..)
            .ok_or(StoreError::Geometry)?
            .copy_from_slice(&word.to_le_bytes());
        flash
            .write(self.slot_base(slot), &unit)
            .map_err(|_| StoreError::Flash)
    }

    /// Saves `table` under `id`, with the parameter records `params`, into the slot not
    /// holding the newest valid table.
    pub fn save<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
        id: u32,
        table: &CamTable<S, N>,
        params: &ParamOverrides,
    ) -> Result<SlotHeader, StoreError> {
        self.save_keeping(flash, None, id, Some(table), params)
    }

    /// [`Store::save`], but never into slot `keep` (the slot that booted, or the last one
    /// saved: the one that boots now); `None`: into the slot not holding the newest valid
    /// table. The generation is one above the newest valid slot's either way, so the new
    /// slot is the one the next boot tries first. `table: None` saves the settings alone
    /// (a slot of 0 rows, id [`super::msg::NO_TABLE`]: settings saved before any table).
    pub fn save_keeping<F: NorFlash, const S: usize, const N: usize>(
        &self,
        flash: &mut F,
        keep: Option<u8>,
        id: u32,
        table: Option<&CamTable<S, N>>,
        params: &ParamOverrides,
    ) -> Result<SlotHeader, StoreError> {
        if self.slot_size == 0 {
            return Err(StoreError::Geometry);
        }
        let newest = self.newest::<F, S, N>(flash);
        let slot = match (keep, newest) {
            (Some(0), _) => 1,
            (Some(_), _) => 0,
            (None, Some(h)) if h.slot == 0 => 1,
            (None, _) => 0,
        };
        let generation = newest.map_or(1, |h| h.generation.saturating_add(1));
        let rows = u16::try_from(table.map_or(0, |t| t.len())).map_err(|_| StoreError::Geometry)?;
        let n_params = u16::try_from(params.len()).map_err(|_| StoreError::Geometry)?;
        if params.len() > max_records(S) {
            return Err(StoreError::Geometry);
        }
        let at = self.slot_base(slot);
        let fl = StoreError::Flash;
        flash
            .erase(at, at.checked_add(self.slot_size).ok_or(fl)?)
            .map_err(|_| fl)?;
        let mut out = Chunked::<F> {
            buf: [0xFF; BUF],
            fill: 0,
            at: at.checked_add(MAGIC_UNIT as u32).ok_or(fl)?,
            crc: CRC32.digest(),
            _f: core::marker::PhantomData,
        };
        let mut hdr = [0u8; HEADER - MAGIC_UNIT];
        let mut w = Writer::new(&mut hdr);
        w.u32(generation).ok_or(fl)?;
        w.u32(id).ok_or(fl)?;
        w.u16(S as u16).ok_or(fl)?;
        w.u16(rows).ok_or(fl)?;
        w.u16(n_params).ok_or(fl)?;
        w.u16(0).ok_or(fl)?;
        out.put(flash, &hdr, true)?;
        for p in params.iter() {
            let mut rec = [0u8; RECORD_LEN];
            p.write(&mut Writer::new(&mut rec))
                .ok_or(StoreError::Geometry)?;
            out.put(flash, &rec, true)?;
        }
        for n in table
            .into_iter()
            .flat_map(|t| (0..t.len()).map(|i| t.node(i)))
        {
            let n = n.ok_or(StoreError::Geometry)?;
            let mut row = [0u8; super::msg::row_len(super::msg::MAX_AXES)];
            let mut w = Writer::new(&mut row);
            super::msg::write_row(&mut w, &n).ok_or(StoreError::Geometry)?;
            let len = w.len();
            out.put(flash, row.get(..len).ok_or(fl)?, true)?;
        }
        let crc = out.crc.clone().finalize();
        out.put(flash, &crc.to_le_bytes(), false)?;
        out.flush(flash)?;
        self.write_commit(flash, slot, MAGIC)?;
        match self.scan::<F, S, N>(flash, slot) {
            Some(h)
                if h.generation == generation
                    && h.id == id
                    && h.rows == rows
                    && h.params == n_params =>
            {
                Ok(h)
            }
            _ => Err(StoreError::Verify),
        }
    }
}

/// Most parameter records a slot of an `S`-axis board holds: every parameter of every
/// axis.
const fn max_records(s: usize) -> usize {
    s.saturating_mul(ParamId::COUNT)
}

/// Buffers writes into WRITE_SIZE-aligned program operations.
struct Chunked<F> {
    buf: [u8; BUF],
    fill: usize,
    at: u32,
    crc: Crc32,
    _f: core::marker::PhantomData<F>,
}

impl<F: NorFlash> Chunked<F> {
    fn put(&mut self, flash: &mut F, mut bytes: &[u8], in_crc: bool) -> Result<(), StoreError> {
        if in_crc {
            self.crc.update(bytes);
        }
        while !bytes.is_empty() {
            let room = BUF.saturating_sub(self.fill);
            let take = room.min(bytes.len());
            let (now, rest) = bytes.split_at(take);
            let end = self.fill.saturating_add(take);
            self.buf
                .get_mut(self.fill..end)
                .ok_or(StoreError::Flash)?
                .copy_from_slice(now);
            self.fill = end;
            bytes = rest;
            if self.fill == BUF {
                self.flush(flash)?;
            }
        }
        Ok(())
    }

    /// Writes the buffered bytes, padded with 0xFF to a WRITE_SIZE multiple.
    fn flush(&mut self, flash: &mut F) -> Result<(), StoreError> {
        if self.fill == 0 {
            return Ok(());
        }
        let len = self
            .fill
            .div_ceil(F::WRITE_SIZE)
            .saturating_mul(F::WRITE_SIZE)
            .min(BUF);
        if let Some(pad) = self.buf.get_mut(self.fill..len) {
            pad.fill(0xFF);
        }
        let data = self.buf.get(..len).ok_or(StoreError::Flash)?;
        flash.write(self.at, data).map_err(|_| StoreError::Flash)?;
        self.at = self
            .at
            .checked_add(u32::try_from(len).map_err(|_| StoreError::Flash)?)
            .ok_or(StoreError::Flash)?;
        self.fill = 0;
        self.buf = [0xFF; BUF];
        Ok(())
    }
}
