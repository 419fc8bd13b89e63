//! GPIO ports A–I (RM0090 §8): mode, pulls, output data with BSRR, input data from the
//! board's inputs (the E-stop chain on PE8) or the pins' own output and pulls.

/// One port.
#[derive(Debug, Clone)]
pub struct Port {
    /// MODER, OTYPER, OSPEEDR, PUPDR, IDR (unused), ODR, BSRR (write-only), LCKR, AFRL, AFRH.
    regs: [u32; 10],
    /// Levels driven from outside on input pins (`Some(level)`), per pin.
    pub external: [Option<bool>; 16],
}

impl Port {
    /// Port `n` (0 = A) at reset.
    pub fn new(n: usize) -> Self {
        let mut regs = [0; 10];
        match n {
            0 => {
                regs[0] = 0xA800_0000;
                regs[3] = 0x6400_0000;
            }
            1 => {
                regs[0] = 0x0000_0280;
                regs[2] = 0x0000_00C0;
                regs[3] = 0x0000_0100;
            }
            _ => {}
        }
        Self {
            regs,
            external: [None; 16],
        }
    }

    /// The output data register.
    pub fn odr(&self) -> u32 {
        self.regs[5]
    }

    /// Whether `pin` is configured as an output.
    pub fn is_output(&self, pin: usize) -> bool {
        (self.regs[0] >> (2 * pin)) & 3 == 1
    }

    fn idr(&self) -> u32 {
        (0..16).fold(0, |acc, pin| {
            let mode = (self.regs[0] >> (2 * pin)) & 3;
            let level = match (mode, self.external[pin]) {
                (1, _) | (2, None) => self.regs[5] & (1 << pin) != 0,
                (_, Some(l)) => l,
                _ => (self.regs[3] >> (2 * pin)) & 3 == 1, // pull-up reads 1
            };
            acc | (u32::from(level) << pin)
        })
    }

    /// A read.
    pub fn read(&self, off: u32) -> Option<u32> {
        match off {
            0x10 => Some(self.idr()),
            0x18 => Some(0),
            0x00..=0x24 => self.regs.get((off / 4) as usize).copied(),
            _ => None,
        }
    }

    /// A write.
    pub fn write(&mut self, off: u32, v: u32) -> Option<()> {
        match off {
            0x10 => {}
            // BSRR: BRx then BSx (BSx has priority, RM0090 §8.4.7).
            0x18 => self.regs[5] = (self.regs[5] & !(v >> 16)) | (v & 0xFFFF),
            0x00..=0x24 => *self.regs.get_mut((off / 4) as usize)? = v,
            _ => return None,
        }
        Some(())
    }
}
