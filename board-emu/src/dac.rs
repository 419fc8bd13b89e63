//! DAC1 (RM0090 §14): channels 1 and 2 (PA4, PA5), 12-bit right/left aligned and 8-bit
//! holding registers, dual registers, software trigger. The output (DOR) follows the
//! holding register at once unless the channel's trigger is enabled.

/// The DAC.
#[derive(Debug, Clone, Default)]
pub struct Dac {
    cr: u32,
    dhr: [u32; 2],
    dor: [u32; 2],
    sr: u32,
    /// Writes to the output registers since reset, per channel.
    pub writes: [u64; 2],
}

impl Dac {
    /// The 12-bit output code of channel `ch` (0/1), `None` if the channel is off.
    pub fn output(&self, ch: usize) -> Option<u16> {
        let en = self.cr & (1 << (16 * ch)) != 0;
        en.then(|| self.dor[ch] as u16)
    }

    fn load(&mut self, ch: usize, v: u32) {
        self.dhr[ch] = v & 0xFFF;
        let ten = self.cr & (1 << (16 * ch + 2)) != 0;
        if !ten {
            self.dor[ch] = self.dhr[ch];
            self.writes[ch] += 1;
        }
    }

    /// A read.
    pub fn read(&self, off: u32) -> Option<u32> {
        Some(match off {
            0x00 => self.cr,
            0x04 => 0,
            0x08 => self.dhr[0],
            0x0C => self.dhr[0] << 4,
            0x10 => self.dhr[0] >> 4,
            0x14 => self.dhr[1],
            0x18 => self.dhr[1] << 4,
            0x1C => self.dhr[1] >> 4,
            0x20 => self.dhr[0] | (self.dhr[1] << 16),
            0x24 => (self.dhr[0] << 4) | (self.dhr[1] << 20),
            0x28 => (self.dhr[0] >> 4) | ((self.dhr[1] >> 4) << 8),
            0x2C => self.dor[0],
            0x30 => self.dor[1],
            0x34 => self.sr,
            _ => return None,
        })
    }

    /// A write.
    pub fn write(&mut self, off: u32, v: u32) -> Option<()> {
        match off {
            0x00 => self.cr = v,
            0x04 => {
                for ch in 0..2 {
                    if v & (1 << ch) != 0 {
                        self.dor[ch] = self.dhr[ch];
                        self.writes[ch] += 1;
                    }
                }
            }
            0x08 => self.load(0, v),
            0x0C => self.load(0, v >> 4),
            0x10 => self.load(0, (v & 0xFF) << 4),
            0x14 => self.load(1, v),
            0x18 => self.load(1, v >> 4),
            0x1C => self.load(1, (v & 0xFF) << 4),
            0x20 => {
                self.load(0, v);
                self.load(1, v >> 16);
            }
            0x24 => {
                self.load(0, (v & 0xFFFF) >> 4);
                self.load(1, v >> 20);
            }
            0x28 => {
                self.load(0, (v & 0xFF) << 4);
                self.load(1, ((v >> 8) & 0xFF) << 4);
            }
            0x2C | 0x30 => {}
            0x34 => self.sr &= !v,
            _ => return None,
        }
        Some(())
    }
}
