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
//! **Erasing stalls the CPU.** The F407 has one flash bank: while a sector erases
//! (1 s typical, 2 s maximum for 128 KiB at x32 parallelism) every instruction fetch
//! from flash waits, the tick interrupt included. The protocol handler therefore only
//! accepts Save while every axis is idle (valves at null, power off), and the erase runs
//! inside [`crate::tick::stalled`], which lengthens the watchdog for the pause and
//! resynchronises the tick afterwards. Programming a 32-bit word stalls a fetch for
//! 16 µs typical (100 µs maximum): the tick is late by that much at most, far below the
//! 1.5-period overrun threshold at 1 kHz.

use embassy_stm32::flash::{Blocking, Error, Flash};
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
}

impl NorFlashError for SlotFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SlotFlashError::Driver(Error::Unaligned) => NorFlashErrorKind::NotAligned,
            SlotFlashError::Driver(Error::Size) | SlotFlashError::OutsideSlots => {
                NorFlashErrorKind::OutOfBounds
            }
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
        self.inner
            .blocking_write(offset, bytes)
            .map_err(SlotFlashError::Driver)
    }

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        in_slots(from, to.saturating_sub(from))?;
        let inner = &mut self.inner;
        defmt::info!(
            "erasing flash 0x{=u32:08x}..0x{=u32:08x} (tick paused)",
            from,
            to
        );
        crate::tick::stalled(|| inner.blocking_erase(from, to)).map_err(SlotFlashError::Driver)
    }
}
