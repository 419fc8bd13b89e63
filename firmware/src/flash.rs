//! The table store's flash: sectors 10 and 11 of the STM32F407's single bank.
//!
//! | slot | sector | address | offset from 0x0800_0000 | size |
//! |---|---|---|---|---|
//! | 0 | 10 | 0x080C_0000 | 0xC_0000 | 128 KiB |
//! | 1 | 11 | 0x080E_0000 | 0xE_0000 | 128 KiB |
//!
//! `memory.x` gives the program sectors 0–9 (768 KiB) only, so the linker never places
//! code there. [`SlotFlash`] wraps embassy-stm32's blocking [`Flash`] driver (the
//! `embedded-storage` `NorFlash` traits: offsets from the start of flash, `WRITE_SIZE`
//! 4 bytes, `ERASE_SIZE` 128 KiB, the largest sector) and refuses every write or erase
//! outside the two slots, so a protocol bug can never touch the program.
//!
//! **Erasing stalls the CPU.** The F407 has one flash bank: while a sector erases every
//! instruction fetch from flash waits, the tick interrupt included. A 128 KiB sector
//! takes 1 s typical, 2 s maximum at x32 parallelism, and 2 s / 4 s at x8 (DS8626
//! t_ERASE128KB) — embassy-stm32 0.6's `blocking_erase` leaves `FLASH_CR.PSIZE` at x8
//! (its word writes reset it to 0), so this module erases itself, by register, at x32
//! ([`erase_sector_x32`]; x32 needs VDD ≥ 2.7 V: the board runs at 3.3 V). The protocol
//! handler only accepts Save while every axis is idle (valves at null, power off), and
//! the erase runs inside [`crate::tick::stalled`], which re-checks that inside its
//! critical section, lengthens the watchdog for the pause and resynchronises the tick
//! afterwards. Programming a 32-bit word stalls a fetch for 16 µs typical (100 µs
//! maximum): the tick is late by that much at most, far below the 1.5-period overrun
//! threshold at 1 kHz. After every program and erase the flash data cache is reset
//! (`crate::flash_acr`), so a read-back never sees a stale cached line.

use embassy_stm32::flash::{Blocking, Error, Flash};
use embassy_stm32::pac;
use embassy_stm32::pac::flash::vals::Psize;
use embedded_storage::nor_flash::ReadNorFlash;
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind};

/// Offset of slot 0 (sector 10) from the start of flash.
pub const SLOT0_OFFSET: u32 = 0x000C_0000;
/// Size of one slot (one 128 KiB sector).
pub const SLOT_BYTES: u32 = 128 * 1024;
/// End of slot 1 (sector 11), exclusive: the end of the 1 MiB flash.
const SLOTS_END: u32 = SLOT0_OFFSET + 2 * SLOT_BYTES;

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum SlotFlashError {
    /// The driver's error.
    Driver(Error),
    /// A write or erase outside sectors 10–11.
    OutsideSlots,
    /// An erase while an axis is following or holding (refused inside the tick's
    /// critical section, `crate::tick::stalled`).
    NotIdle,
}

impl NorFlashError for SlotFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SlotFlashError::Driver(Error::Unaligned) => NorFlashErrorKind::NotAligned,
            SlotFlashError::Driver(Error::Size) | SlotFlashError::OutsideSlots => {
                NorFlashErrorKind::OutOfBounds
            }
            SlotFlashError::NotIdle => NorFlashErrorKind::Other,
            SlotFlashError::Driver(_) => NorFlashErrorKind::Other,
        }
    }
}

/// The whole flash for reading, sectors 10–11 for writing and erasing.
pub struct SlotFlash {
    inner: Flash<'static, Blocking>,
}

impl SlotFlash {
    /// Wraps the blocking driver.
    pub fn new(inner: Flash<'static, Blocking>) -> Self {
        Self { inner }
    }
}

fn in_slots(from: u32, len: u32) -> Result<(), SlotFlashError> {
    let end = from.checked_add(len).ok_or(SlotFlashError::OutsideSlots)?;
    if from >= SLOT0_OFFSET && end <= SLOTS_END {
        Ok(())
    } else {
        Err(SlotFlashError::OutsideSlots)
    }
}

impl ErrorType for SlotFlash {
    type Error = SlotFlashError;
}

impl ReadNorFlash for SlotFlash {
    const READ_SIZE: usize = <Flash<'static, Blocking> as ReadNorFlash>::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.inner
            .blocking_read(offset, bytes)
            .map_err(SlotFlashError::Driver)
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl NorFlash for SlotFlash {
    const WRITE_SIZE: usize = <Flash<'static, Blocking> as NorFlash>::WRITE_SIZE;
    const ERASE_SIZE: usize = <Flash<'static, Blocking> as NorFlash>::ERASE_SIZE;

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let len = u32::try_from(bytes.len()).map_err(|_| SlotFlashError::OutsideSlots)?;
        in_slots(offset, len)?;
        let r = self
            .inner
            .blocking_write(offset, bytes)
            .map_err(SlotFlashError::Driver);
        crate::flash_acr::reset_data_cache();
        r
    }

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        in_slots(from, to.saturating_sub(from))?;
        if !from.is_multiple_of(SLOT_BYTES) || !to.is_multiple_of(SLOT_BYTES) {
            return Err(SlotFlashError::Driver(Error::Unaligned));
        }
        let mut at = from;
        while at < to {
            let snb = sector_of(at).ok_or(SlotFlashError::OutsideSlots)?;
            defmt::info!(
                "erasing flash sector {=u8} at 0x{=u32:08x} (x32, tick paused)",
                snb,
                at
            );
            let t0 = cortex_m::peripheral::DWT::cycle_count();
            let r = crate::tick::stalled(|| erase_sector_x32(snb))
                .map_err(|_| SlotFlashError::NotIdle)?;
            crate::flash_acr::reset_data_cache();
            let cycles = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(t0);
            let ms = cycles / (crate::consts::SYSCLK_HZ / 1000);
            defmt::info!("sector {=u8} erased in {=u32} ms", snb, ms);
            r.map_err(SlotFlashError::Driver)?;
            at = at.saturating_add(SLOT_BYTES);
        }
        Ok(())
    }
}

/// The sector number of a 128 KiB sector at `offset` from the start of flash (sectors 5
/// … 11 of the F407's single bank start at 0x2_0000 · (n − 4)).
fn sector_of(offset: u32) -> Option<u8> {
    if offset < 0x2_0000 || !offset.is_multiple_of(0x2_0000) {
        return None;
    }
    u8::try_from(offset / 0x2_0000 + 4)
        .ok()
        .filter(|n| (5..=11).contains(n))
}

/// Erases sector `snb` at x32 parallelism by register (RM0090 §3.6.3): unlock, wait
/// until not busy, clear the error flags, SER + SNB + PSIZE = x32, STRT, wait until not
/// busy (the CPU's own fetches stall meanwhile), read the errors, lock. Call only inside
/// [`crate::tick::stalled`].
fn erase_sector_x32(snb: u8) -> Result<(), Error> {
    let f = pac::FLASH;
    if f.cr().read().lock() {
        f.keyr().write_value(0x4567_0123);
        f.keyr().write_value(0xCDEF_89AB);
    }
    while f.sr().read().bsy() {}
    // The error flags are write-1-to-clear: writing back what was read clears them.
    f.sr().modify(|_| {});
    f.cr().write(|w| {
        w.set_ser(true);
        w.set_snb(snb);
        w.set_psize(Psize::PSIZE32);
    });
    f.cr().modify(|w| w.set_strt(true));
    while f.sr().read().bsy() {}
    let sr = f.sr().read();
    f.cr().write(|w| w.set_ser(false));
    f.sr().modify(|_| {});
    f.cr().modify(|w| w.set_lock(true));
    if sr.pgserr() {
        Err(Error::Seq)
    } else if sr.pgperr() {
        Err(Error::Parallelism)
    } else if sr.pgaerr() {
        Err(Error::Unaligned)
    } else if sr.wrperr() {
        Err(Error::Protected)
    } else if sr.operr() {
        Err(Error::Prog)
    } else {
        Ok(())
    }
}
