//! A NOR flash in RAM that behaves like the STM32F407's at a power cut — for host tests,
//! the power-cut benchmark and the virtual board.
//!
//! What it models (RM0090 §3.5–3.6, and what a cut does to real cells):
//! - **Sector erase**: [`ERASE_SIZE`] bytes at a time, one operation per sector. The F407's
//!   sectors are 16–128 KiB; the model's 2 KiB keeps 10⁵ cut sequences fast and changes
//!   nothing else: a slot is one sector in core's tests, as on the board.
//! - **Word program**: [`WRITE_SIZE`] = 4 bytes (x32 parallelism), one operation per word;
//!   programming only clears bits (`old & new`).
//! - **A cut mid-operation**: with [`RamFlash::cut_after`]`(k)`, k operations complete, the
//!   next is cut half done, and every later one fails until [`RamFlash::power_on`]. A cut
//!   erase leaves the sector undefined: each 0 bit may have risen to 1 or not, and may
//!   be left *weak* — the magic possibly intact. A cut program leaves each bit it was
//!   clearing cleared, not cleared or weak.
//! - **Weak cells** read 0 or 1 at random on every read (a cell charged halfway reads
//!   differently from one boot to the next). A full erase or a completed program of 0 into
//!   a weak bit makes it solid again.
//!
//! The randomness is a seeded xorshift ([`RamFlash::with_seed`]): every run is
//! reproducible.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use std::vec::Vec;

/// Program unit, bytes (the F407 at 2.7–3.6 V: x32 parallelism, one word).
pub const WRITE_SIZE: usize = 4;
/// Erase unit, bytes (one sector of the model; see the module docs).
pub const ERASE_SIZE: usize = 2048;

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

/// One flash operation, as [`RamFlash::trace`] records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashOp {
    /// A sector erase at this address.
    Erase(u32),
    /// A word program at this address.
    Program(u32),
}

/// The flash array, its weak cells and its power budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RamFlash {
    /// The bytes (the solid value of weak bits is undefined).
    pub mem: Vec<u8>,
    /// Per byte, the bits that read at random.
    weak: Vec<u8>,
    budget: Option<usize>,
    /// The power is off (after a cut, until [`RamFlash::power_on`]).
    off: bool,
    /// Operations (sector erases and word programs) completed since creation.
    pub ops: usize,
    /// When `Some`, every operation is appended (for tests that aim a cut).
    pub trace: Option<Vec<FlashOp>>,
    rng: u64,
}

impl RamFlash {
    /// An erased flash of `size` bytes (a multiple of [`ERASE_SIZE`]), seed 1.
    pub fn new(size: usize) -> Self {
        Self::with_seed(size, 1)
    }

    /// An erased flash whose cut and weak-cell randomness starts from `seed`.
    pub fn with_seed(size: usize, seed: u64) -> Self {
        Self {
            mem: std::vec![0xFF; size],
            weak: std::vec![0; size],
            budget: None,
            off: false,
            ops: 0,
            trace: None,
            rng: seed | 1,
        }
    }

    /// Lets `k` more operations complete, then cuts the power in the next one.
    pub fn cut_after(&mut self, k: usize) {
        self.budget = Some(k);
    }

    /// Restores the power (unlimited budget).
    pub fn power_on(&mut self) {
        self.budget = None;
        self.off = false;
    }

    /// Bytes holding at least one weak bit.
    pub fn weak_bytes(&self) -> usize {
        self.weak.iter().filter(|w| **w != 0).count()
    }

    fn rand(&mut self) -> u64 {
        // xorshift64*
        let mut x = self.rng;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.rng = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn rand_byte(&mut self) -> u8 {
        (self.rand() >> 56) as u8
    }

    /// How far a cut operation got, 0 … 65 535 (uniform).
    fn progress(&mut self) -> u32 {
        (self.rand() >> 48) as u32
    }

    /// Of the bits `changing` in one byte of an operation cut at `progress`: those that
    /// changed solidly and those left weak. A bit's own threshold u is uniform; it
    /// changed if u < progress − w, is weak within ±w of the progress (w = 15 %), else
    /// unchanged: early cuts change few bits, late cuts most, and either leaves some weak.
    fn partial(&mut self, changing: u8, progress: u32) -> (u8, u8) {
        const W: u32 = 65_536 * 15 / 100;
        let (mut done, mut weak) = (0u8, 0u8);
        for bit in 0..8 {
            let m = 1u8 << bit;
            if changing & m == 0 {
                continue;
            }
            let u = (self.rand() >> 48) as u32;
            if u + W < progress {
                done |= m;
            } else if u < progress + W {
                weak |= m;
            }
        }
        (done, weak)
    }

    /// Takes one operation from the budget: `Ok(true)` it completes, `Ok(false)` it is the
    /// one the cut interrupts, `Err` the power is already off.
    fn spend(&mut self, op: FlashOp) -> Result<bool, RamFlashError> {
        if self.off {
            return Err(RamFlashError::PowerCut);
        }
        let complete = match &mut self.budget {
            Some(0) => {
                // This operation is cut; nothing runs after it.
                self.off = true;
                false
            }
            Some(k) => {
                *k -= 1;
                true
            }
            None => true,
        };
        if let Some(t) = &mut self.trace {
            t.push(op);
        }
        if complete {
            self.ops += 1;
        }
        Ok(complete)
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
        for (i, b) in bytes.iter_mut().enumerate() {
            let w = self.weak[o + i];
            *b = if w == 0 {
                self.mem[o + i]
            } else {
                (self.mem[o + i] & !w) | (self.rand_byte() & w)
            };
        }
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
        for sector in (from as usize..to as usize).step_by(ERASE_SIZE) {
            let range = sector..sector + ERASE_SIZE;
            if self.spend(FlashOp::Erase(sector as u32))? {
                self.mem[range.clone()].fill(0xFF);
                self.weak[range].fill(0);
            } else {
                // Cut: the erase got a random way; each 0 bit rose, stayed or is weak.
                let progress = self.progress();
                for i in range {
                    let zeros = !self.mem[i];
                    let (done, weak) = self.partial(zeros, progress);
                    self.mem[i] |= done;
                    self.weak[i] |= weak;
                }
                return Err(RamFlashError::PowerCut);
            }
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        embedded_storage::nor_flash::check_write(self, offset, bytes.len())
            .map_err(RamFlashError::Kind)?;
        for (k, word) in bytes.chunks(WRITE_SIZE).enumerate() {
            let at = offset as usize + k * WRITE_SIZE;
            if self.spend(FlashOp::Program(at as u32))? {
                for (i, b) in word.iter().enumerate() {
                    self.mem[at + i] &= *b;
                    // A programmed 0 is solid.
                    self.weak[at + i] &= *b;
                }
            } else {
                // Cut: the program got a random way; each bit being cleared is
                // cleared, not, or weak.
                let progress = self.progress();
                for (i, b) in word.iter().enumerate() {
                    let clearing = !*b & self.mem[at + i];
                    let (done, weak) = self.partial(clearing, progress);
                    self.mem[at + i] &= !done;
                    self.weak[at + i] |= weak;
                }
                return Err(RamFlashError::PowerCut);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn program_clears_bits_and_a_cut_leaves_weak_bits() {
        let mut f = RamFlash::with_seed(2 * ERASE_SIZE, 7);
        f.write(0, &[0x0F, 0xF0, 0x00, 0xFF]).unwrap();
        f.write(0, &[0xFF, 0x0F, 0xFF, 0xFF]).unwrap();
        assert_eq!(&f.mem[..4], &[0x0F, 0x00, 0x00, 0xFF]);
        assert_eq!(f.ops, 2);
        // Cut the third program: the word is left between 0xFFFF_FFFF and 0.
        let mut cut = 0;
        for seed in 1..50 {
            let mut g = RamFlash::with_seed(ERASE_SIZE, seed);
            g.cut_after(0);
            assert_eq!(g.write(8, &[0; 4]), Err(RamFlashError::PowerCut));
            assert_eq!(g.write(12, &[0; 4]), Err(RamFlashError::PowerCut));
            assert_eq!(&g.mem[12..16], &[0xFF; 4], "nothing after the cut");
            cut += g.weak_bytes();
            // A completed program of 0 makes the word solid.
            g.power_on();
            g.write(8, &[0; 4]).unwrap();
            assert_eq!(g.weak_bytes(), 0);
            let mut b = [1u8; 4];
            g.read(8, &mut b).unwrap();
            assert_eq!(b, [0; 4]);
        }
        assert!(cut > 0, "some cut programs leave weak bits");
    }

    #[test]
    fn weak_bits_read_differently_and_erase_is_per_sector() {
        let mut f = RamFlash::with_seed(2 * ERASE_SIZE, 3);
        f.write(0, &[0; ERASE_SIZE]).unwrap();
        f.write(ERASE_SIZE as u32, &[0; 4]).unwrap();
        let ops = f.ops;
        f.cut_after(0);
        assert_eq!(
            f.erase(0, 2 * ERASE_SIZE as u32),
            Err(RamFlashError::PowerCut)
        );
        assert_eq!(f.ops, ops, "the cut erase did not complete");
        assert_eq!(
            &f.mem[ERASE_SIZE..ERASE_SIZE + 4],
            &[0; 4],
            "next sector untouched"
        );
        assert!(f.weak_bytes() > 0);
        let (mut a, mut b) = ([0u8; 64], [0u8; 64]);
        f.read(0, &mut a).unwrap();
        f.read(0, &mut b).unwrap();
        assert_ne!(a, b, "weak cells read differently");
        f.power_on();
        f.erase(0, ERASE_SIZE as u32).unwrap();
        assert_eq!(f.weak_bytes(), 0);
        assert!(f.mem[..ERASE_SIZE].iter().all(|b| *b == 0xFF));
    }
}
