//! The 1 MiB flash and its interface (RM0090 §3): unlock with the two keys, program with
//! CR.PG at the parallelism CR.PSIZE selects, sector erase with CR.SER/SNB/STRT, SR's
//! busy and error flags; timing from DS8626 (typical values): a program access 16 µs, a
//! 16/64/128 KiB sector erase 400/1200/2000 ms at x8, 300/700/1300 ms at x16, 250/550/1000
//! ms at x32 or x64.
//!
//! A power cut ([`Flash::power_cut`]) during an erase leaves the part of the sector the
//! erase had reached erased and the rest as it was, with the word at the boundary
//! scrambled; during a program access it leaves the target bits half programmed (the
//! new value's cleared bits in the lower half of the access). Bits only go from 1 to 0
//! by programming, as on the part.

/// Flash base address.
pub const BASE: u32 = 0x0800_0000;
/// Flash size, bytes.
pub const SIZE: usize = 1 << 20;

/// Sector `n`'s offset and size.
pub fn sector(n: u32) -> Option<(usize, usize)> {
    Some(match n {
        0..=3 => (n as usize * 0x4000, 0x4000),
        4 => (0x1_0000, 0x1_0000),
        5..=11 => (0x2_0000 * (n as usize - 4), 0x2_0000),
        _ => return None,
    })
}

#[derive(Debug, Clone, Copy)]
enum Op {
    Erase {
        sector: u32,
        start: u64,
        end: u64,
    },
    Program {
        off: usize,
        old: u32,
        new: u32,
        bytes: usize,
        end: u64,
    },
}

/// The flash.
#[derive(Debug, Clone)]
pub struct Flash {
    /// The array.
    pub mem: Vec<u8>,
    acr: u32,
    cr: u32,
    sr: u32,
    optcr: u32,
    key_step: u8,
    op: Option<Op>,
    /// Erases and program accesses done (for the tests).
    pub erases: u32,
    /// Program accesses done.
    pub programs: u64,
    /// When the last erase ended (core cycle).
    pub erase_done_at: Option<u64>,
}

const SYSCLK: u64 = 168_000_000;

impl Flash {
    /// An erased flash.
    pub fn new() -> Self {
        Self {
            mem: vec![0xFF; SIZE],
            acr: 0,
            cr: 0x8000_0000,
            sr: 0,
            optcr: 0x0FFF_AAED,
            key_step: 0,
            op: None,
            erases: 0,
            programs: 0,
            erase_done_at: None,
        }
    }

    /// A reset: the interface registers at their reset values (CR locked, ACR and SR
    /// clear), the array and the counters kept.
    pub fn reset_registers(&mut self) {
        self.acr = 0;
        self.cr = 0x8000_0000;
        self.sr = 0;
        self.key_step = 0;
    }

    /// FLASH_ACR: LATENCY (wait states), PRFTEN, ICEN, DCEN.
    pub fn acr(&self) -> u32 {
        self.acr
    }

    fn psize_bytes(&self) -> usize {
        1 << ((self.cr >> 8) & 3)
    }

    /// Completes an operation whose time has come.
    pub fn sync(&mut self, now: u64) {
        match self.op {
            Some(Op::Erase { sector: s, end, .. }) if now >= end => {
                if let Some((o, n)) = sector(s) {
                    self.mem[o..o + n].fill(0xFF);
                }
                self.erases += 1;
                self.erase_done_at = Some(end);
                self.finish();
            }
            Some(Op::Program {
                off,
                old,
                new,
                bytes,
                end,
            }) if now >= end => {
                let v = old & new;
                for k in 0..bytes {
                    self.mem[off + k] = (v >> (8 * k)) as u8;
                }
                self.programs += 1;
                self.finish();
            }
            _ => {}
        }
    }

    fn finish(&mut self) {
        self.op = None;
        self.sr |= 1; // EOP
    }

    /// Whether an operation is in progress; its end cycle.
    pub fn busy_until(&self) -> Option<u64> {
        match self.op {
            Some(Op::Erase { end, .. }) | Some(Op::Program { end, .. }) => Some(end),
            None => None,
        }
    }

    /// The power goes at `now`: an operation in progress is left half done.
    pub fn power_cut(&mut self, now: u64) {
        match self.op.take() {
            Some(Op::Erase {
                sector: s,
                start,
                end,
            }) => {
                if let Some((o, n)) = sector(s) {
                    let frac = (now.saturating_sub(start)) as f64 / (end - start).max(1) as f64;
                    let done = ((n as f64 * frac) as usize).min(n) & !3;
                    self.mem[o..o + done].fill(0xFF);
                    if done < n {
                        let w = &mut self.mem[o + done..o + done + 4];
                        for (k, b) in w.iter_mut().enumerate() {
                            *b ^= 0x5A ^ (k as u8 * 0x11);
                        }
                    }
                }
            }
            Some(Op::Program {
                off,
                old,
                new,
                bytes,
                ..
            }) => {
                let half = if bytes >= 2 {
                    (1u32 << (8 * bytes / 2)) - 1
                } else {
                    0x0F
                };
                let v = old & (new | !half);
                for k in 0..bytes {
                    self.mem[off + k] = (v >> (8 * k)) as u8;
                }
            }
            None => {}
        }
    }

    /// A read of the array at `off`.
    pub fn read_mem(&self, off: usize, size: usize) -> u32 {
        (0..size).fold(0, |acc, k| {
            acc | u32::from(self.mem.get(off + k).copied().unwrap_or(0xFF)) << (8 * k)
        })
    }

    /// A CPU write into the array: a program access if CR.PG is set and the size matches
    /// PSIZE; otherwise an error flag and no change.
    pub fn write_mem(&mut self, off: usize, size: usize, v: u32, now: u64) {
        self.sync(now);
        if self.cr & 1 == 0 || self.cr & 0x8000_0000 != 0 {
            self.sr |= 1 << 7; // PGSERR
            return;
        }
        if size != self.psize_bytes() {
            self.sr |= 1 << 6; // PGPERR
            return;
        }
        if !off.is_multiple_of(size) || off + size > SIZE {
            self.sr |= 1 << 5; // PGAERR
            return;
        }
        if self.op.is_some() {
            // The part stalls the bus until the operation ends: the caller (the bus) has
            // synced to `now`, so an operation still running here is a second access
            // inside the first one's time — treated as its end.
            if let Some(end) = self.busy_until() {
                self.sync(end);
            }
        }
        let old = self.read_mem(off, size);
        self.op = Some(Op::Program {
            off,
            old,
            new: v,
            bytes: size,
            end: now + 16 * SYSCLK / 1_000_000,
        });
    }

    /// An interface register read.
    pub fn read(&mut self, off: u32, now: u64) -> Option<u32> {
        self.sync(now);
        Some(match off {
            0x00 => self.acr,
            0x04 | 0x08 => 0,
            0x0C => self.sr | if self.op.is_some() { 1 << 16 } else { 0 },
            0x10 => self.cr,
            0x14 => self.optcr,
            _ => return None,
        })
    }

    /// An interface register write.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Option<()> {
        self.sync(now);
        match off {
            0x00 => self.acr = v & 0x1F0F,
            0x04 => {
                self.key_step = match (self.key_step, v) {
                    (0, 0x4567_0123) => 1,
                    (1, 0xCDEF_89AB) => {
                        self.cr &= !0x8000_0000;
                        0
                    }
                    _ => 0,
                };
            }
            0x08 => {}
            0x0C => self.sr &= !(v & 0xF3), // rc_w1
            0x10 => {
                if self.cr & 0x8000_0000 != 0 {
                    // Locked: only LOCK stays; writes are ignored.
                    return Some(());
                }
                self.cr = v & 0x8301_03FF;
                if v & (1 << 16) != 0 && v & 2 != 0 && self.op.is_none() {
                    let s = (v >> 3) & 0xF;
                    let kib = sector(s).map_or(0, |x| x.1 / 1024);
                    let ms: u64 = match (kib, (v >> 8) & 3) {
                        (16, 0) => 400,
                        (16, 1) => 300,
                        (16, _) => 250,
                        (64, 0) => 1200,
                        (64, 1) => 700,
                        (64, _) => 550,
                        (_, 0) => 2000,
                        (_, 1) => 1300,
                        _ => 1000,
                    };
                    self.op = Some(Op::Erase {
                        sector: s,
                        start: now,
                        end: now + ms * SYSCLK / 1000,
                    });
                    self.cr &= !(1 << 16);
                }
            }
            0x14 => self.optcr = v,
            _ => return None,
        }
        Some(())
    }

    /// The sector a pending erase targets.
    pub fn erasing(&self) -> Option<u32> {
        match self.op {
            Some(Op::Erase { sector, .. }) => Some(sector),
            _ => None,
        }
    }
}

impl Default for Flash {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unlocked() -> Flash {
        let mut f = Flash::new();
        f.write(0x04, 0x4567_0123, 0).unwrap();
        f.write(0x04, 0xCDEF_89AB, 0).unwrap();
        f
    }

    #[test]
    fn program_only_clears_bits_and_needs_pg_and_the_right_size() {
        let mut f = unlocked();
        let off = 0xC_0000;
        f.write_mem(off, 4, 0x1234_5678, 0);
        assert_ne!(f.read(0x0C, 0).unwrap() & (1 << 7), 0, "PG clear: PGSERR");
        f.write(0x10, (2 << 8) | 1, 0).unwrap(); // PSIZE x32, PG
        f.write_mem(off, 2, 0, 0);
        assert_ne!(
            f.read(0x0C, 0).unwrap() & (1 << 6),
            0,
            "x16 access at x32: PGPERR"
        );
        f.write_mem(off, 4, 0x1234_5678, 0);
        assert_ne!(f.read(0x0C, 0).unwrap() & (1 << 16), 0, "busy");
        f.sync(16 * 168);
        assert_eq!(f.read_mem(off, 4), 0x1234_5678);
        f.write_mem(off, 4, 0xFFFF_0000, 16 * 168);
        f.sync(32 * 168);
        assert_eq!(f.read_mem(off, 4), 0x1234_0000, "bits only go from 1 to 0");
    }

    #[test]
    fn a_cut_erase_leaves_the_rest_of_the_sector_and_a_scrambled_boundary() {
        let mut f = unlocked();
        let (o, n) = sector(10).unwrap();
        f.mem[o..o + n].fill(0);
        f.write(0x10, (2 << 8) | (10 << 3) | 2 | (1 << 16), 0)
            .unwrap(); // x32, SER, SNB 10, STRT
        let end = f.busy_until().unwrap();
        assert_eq!(end, 168_000_000, "1 s at x32");
        f.power_cut(end / 4);
        let erased = f.mem[o..o + n].iter().take_while(|&&b| b == 0xFF).count();
        assert_eq!(erased, n / 4);
        assert_ne!(&f.mem[o + n / 4..o + n / 4 + 4], &[0, 0, 0, 0]);
        assert!(f.mem[o + n / 4 + 4..o + n].iter().all(|&b| b == 0));
        assert_eq!(f.busy_until(), None);
    }
}
