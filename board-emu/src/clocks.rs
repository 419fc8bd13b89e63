//! RCC and PWR (RM0090 §7, §5): the clock tree's enable/ready handshakes, the reset
//! flags that survive a reset (RCC_CSR), and the regulator's VOS ready bit.
//!
//! Oscillators and the PLL are ready as soon as they are switched on (the firmware's
//! waits end at once); the system clock switch (CFGR.SWS) follows CFGR.SW. The emulator's
//! time base is the core clock at 168 MHz from reset on (the first ≈ 100 µs of the real
//! board run at 16 MHz HSI): the cycle model does not slow the boot's first steps.

/// RCC_CSR reset flags.
pub mod csr {
    /// Pin reset.
    pub const PINRSTF: u32 = 1 << 26;
    /// Power-on reset.
    pub const PORRSTF: u32 = 1 << 27;
    /// Software reset.
    pub const SFTRSTF: u32 = 1 << 28;
    /// Independent watchdog reset.
    pub const IWDGRSTF: u32 = 1 << 29;
    /// Brown-out reset.
    pub const BORRSTF: u32 = 1 << 25;
}

/// Offsets RCC implements (RM0090 §7.3.24), with reset values.
/// 0x8C (DCKCFGR) exists on the F42x/43x only; embassy reads it on every F4 and the
/// F407 reads it as zero (reserved).
const RCC_REGS: [(u32, u32); 25] = [
    (0x00, 0x0000_0083),
    (0x04, 0x2400_3010),
    (0x08, 0),
    (0x0C, 0),
    (0x10, 0),
    (0x14, 0),
    (0x18, 0),
    (0x20, 0),
    (0x24, 0),
    (0x30, 0x0010_0000),
    (0x34, 0),
    (0x38, 0),
    (0x40, 0),
    (0x44, 0),
    (0x50, 0x7E67_91FF),
    (0x54, 0xF1),
    (0x58, 1),
    (0x60, 0x36FE_C9FF),
    (0x64, 0x0007_5F33),
    (0x70, 0),
    (0x74, 0x0E00_0000),
    (0x80, 0),
    (0x84, 0x2000_3000),
    (0x88, 0),
    (0x8C, 0),
];

/// RCC and PWR.
#[derive(Debug, Clone)]
pub struct Clocks {
    rcc: [u32; 25],
    pwr: [u32; 2],
}

impl Clocks {
    /// At power-on (`csr_flags`: the reset flags this reset leaves in RCC_CSR).
    pub fn new(csr_flags: u32) -> Self {
        let mut rcc = RCC_REGS.map(|r| r.1);
        if let Some(i) = Self::index(0x74) {
            rcc[i] = csr_flags;
        }
        Self {
            rcc,
            pwr: [0x0000_C000, 0],
        }
    }

    fn index(off: u32) -> Option<usize> {
        RCC_REGS.iter().position(|r| r.0 == off)
    }

    /// The reset flags (RCC_CSR[31:24]).
    pub fn reset_flags(&self) -> u32 {
        Self::index(0x74).map_or(0, |i| self.rcc[i] & 0xFE00_0000)
    }

    /// An RCC read.
    pub fn rcc_read(&self, off: u32) -> Option<u32> {
        let v = self.rcc[Self::index(off)?];
        Some(match off {
            0x00 => {
                // Ready bits follow their enables: HSI, HSE, PLL, PLLI2S.
                let mut r = v & !((1 << 1) | (1 << 17) | (1 << 25) | (1 << 27));
                for (on, rdy) in [(0, 1), (16, 17), (24, 25), (26, 27)] {
                    if v & (1 << on) != 0 {
                        r |= 1 << rdy;
                    }
                }
                r
            }
            0x08 => (v & !0xC) | ((v & 3) << 2),
            0x70 => (v & !2) | ((v & 1) << 1),
            0x74 => (v & !2) | ((v & 1) << 1),
            _ => v,
        })
    }

    /// An RCC write.
    pub fn rcc_write(&mut self, off: u32, v: u32) -> Option<()> {
        let i = Self::index(off)?;
        self.rcc[i] = match off {
            // RMVF clears the reset flags.
            0x74 if v & (1 << 24) != 0 => v & 0x0000_00FF,
            0x74 => (self.rcc[i] & 0xFE00_0000) | (v & 0x0000_00FF),
            _ => v,
        };
        Some(())
    }

    /// A PWR read (CR, CSR with VOSRDY set).
    pub fn pwr_read(&self, off: u32) -> Option<u32> {
        match off {
            0x00 => Some(self.pwr[0]),
            0x04 => Some(self.pwr[1] | (1 << 14)),
            _ => None,
        }
    }

    /// A PWR write.
    pub fn pwr_write(&mut self, off: u32, v: u32) -> Option<()> {
        match off {
            0x00 => self.pwr[0] = v,
            0x04 => self.pwr[1] = v & 0x0000_0300,
            _ => return None,
        }
        Some(())
    }
}
