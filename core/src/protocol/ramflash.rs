//! A NOR flash in RAM for host tests and the virtual board, with a power switch.
//!
//! Erase sets bytes to 0xFF; program ANDs the data into the array (NOR can only clear
//! bits). Every byte erased or programmed costs one unit of the power budget: with
//! [`RamFlash::cut_after`]`(k)` the k-th byte operation is the last that happens, the
//! operation in progress stops there half done, and every later operation fails until
//! [`RamFlash::power_on`] — a power cut at any byte.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use std::vec::Vec;

/// Program unit, bytes (as the STM32F4 with 32-bit parallelism).
pub const WRITE_SIZE: usize = 4;
/// Erase unit, bytes (uniform, unlike the F4's 16/64/128 KiB sectors).
pub const ERASE_SIZE: usize = 1024;

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RamFlashError {
    /// Misaligned or out of bounds.
    Kind(NorFlashErrorKind),
    /// The power is off.
    PowerCut,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::Kind(k) => *k,
            Self::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

/// The flash array and its power budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RamFlash {
    /// The bytes.
    pub mem: Vec<u8>,
    budget: Option<usize>,
    /// Bytes erased or programmed since creation (all operations, counted by byte).
    pub ops: usize,
}

impl RamFlash {
    /// An erased flash of `size` bytes (a multiple of [`ERASE_SIZE`]).
    pub fn new(size: usize) -> Self {
        Self {
            mem: std::vec![0xFF; size],
            budget: None,
            ops: 0,
        }
    }

    /// Lets `k` more byte operations happen, then cuts the power.
    pub fn cut_after(&mut self, k: usize) {
        self.budget = Some(k);
    }

    /// Restores the power (unlimited budget).
    pub fn power_on(&mut self) {
        self.budget = None;
    }

    fn spend(&mut self) -> Result<(), RamFlashError> {
        match &mut self.budget {
            Some(0) => Err(RamFlashError::PowerCut),
            Some(k) => {
                *k -= 1;
                self.ops += 1;
                Ok(())
            }
            None => {
                self.ops += 1;
                Ok(())
            }
        }
    }
}

impl ErrorType for RamFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        embedded_storage::nor_flash::check_read(self, offset, bytes.len())
            .map_err(RamFlashError::Kind)?;
        let o = offset as usize;
        bytes.copy_from_slice(&self.mem[o..o + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        embedded_storage::nor_flash::check_erase(self, from, to).map_err(RamFlashError::Kind)?;
        for i in from as usize..to as usize {
            self.spend()?;
            self.mem[i] = 0xFF;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        embedded_storage::nor_flash::check_write(self, offset, bytes.len())
            .map_err(RamFlashError::Kind)?;
        for (i, b) in bytes.iter().enumerate() {
            self.spend()?;
            self.mem[offset as usize + i] &= *b;
        }
        Ok(())
    }
}
