//! ADC1 (RM0090 §13): regular sequence scan (SQR1–3, up to 16 conversions), continuous
//! mode, software start, per-channel sampling time (SMPR1/2), DMA requests, overrun. A
//! conversion takes (sampling + 12) ADC clocks; the ADC clock is APB2 (84 MHz) divided by
//! ADC_CCR.ADCPRE (2/4/6/8). Channel inputs are 12-bit codes set by the board
//! ([`Adc::input`]).

/// Sampling times in ADC clocks by SMP code.
const SMP: [u64; 8] = [3, 15, 28, 56, 84, 112, 144, 480];

/// ADC1 and the common registers.
#[derive(Debug, Clone)]
pub struct Adc {
    regs: [u32; 20],
    common: [u32; 3],
    /// Input code of each channel (0–18).
    pub input: [u16; 19],
    running: bool,
    seq_pos: usize,
    next_done: u64,
    /// Conversions completed since reset.
    pub conversions: u64,
}

/// A conversion's result for the DMA.
pub struct Conversion {
    /// The 12-bit code.
    pub code: u16,
    /// When it completed (core cycle).
    pub at: u64,
}

const SR: usize = 0;
const CR2: usize = 2;
const SMPR1: usize = 3;
const SMPR2: usize = 4;
const SQR1: usize = 11;
const DR: usize = 19;

impl Adc {
    /// At reset.
    pub fn new() -> Self {
        Self {
            regs: [0; 20],
            common: [0; 3],
            input: [0; 19],
            running: false,
            seq_pos: 0,
            next_done: 0,
            conversions: 0,
        }
    }

    fn seq_len(&self) -> usize {
        ((self.regs[SQR1] >> 20) & 0xF) as usize + 1
    }

    fn seq_channel(&self, k: usize) -> usize {
        let (reg, shift) = match k {
            0..=5 => (13, 5 * k),
            6..=11 => (12, 5 * (k - 6)),
            _ => (11, 5 * (k - 12)),
        };
        ((self.regs[reg] >> shift) & 0x1F) as usize
    }

    fn conv_cycles(&self, ch: usize) -> u64 {
        // Channels 0–18 exist; a higher SQ code converts channel 18's time.
        let ch = ch.min(18);
        let smp = if ch >= 10 {
            (self.regs[SMPR1] >> (3 * (ch - 10))) & 7
        } else {
            (self.regs[SMPR2] >> (3 * ch)) & 7
        };
        let pre = 2 * (u64::from((self.common[1] >> 16) & 3) + 1);
        // Core cycles per ADC clock: 168 MHz / (84 MHz / pre).
        (SMP[smp as usize] + 12) * 2 * pre
    }

    /// Core cycles of the next conversion.
    pub fn conversion_cycles(&self) -> u64 {
        self.conv_cycles(self.seq_channel(self.seq_pos))
    }

    /// Whether DMA requests are enabled (CR2.DMA) and no overrun stopped them.
    pub fn dma_enabled(&self) -> bool {
        self.regs[CR2] & (1 << 8) != 0 && self.regs[SR] & (1 << 5) == 0
    }

    /// The next conversion's completion, if converting.
    pub fn next_event(&self) -> Option<u64> {
        self.running.then_some(self.next_done)
    }

    /// Completes the conversions due by `now`; `serve(conv)` is the DMA: it returns
    /// whether it took the result (a refused request with DMA on is an overrun).
    pub fn sync(&mut self, now: u64, serve: &mut dyn FnMut(Conversion) -> bool) {
        while self.running && self.next_done <= now {
            let ch = self.seq_channel(self.seq_pos);
            let code = self.input.get(ch).copied().unwrap_or(0) & 0xFFF;
            let at = self.next_done;
            self.regs[DR] = u32::from(code);
            self.regs[SR] |= 2; // EOC
            self.conversions += 1;
            if self.dma_enabled() && !serve(Conversion { code, at }) {
                self.regs[SR] |= 1 << 5; // OVR: DMA requests stop
            }
            self.seq_pos += 1;
            if self.seq_pos >= self.seq_len() {
                self.seq_pos = 0;
                if self.regs[CR2] & 2 == 0 {
                    self.running = false;
                    break;
                }
            }
            let next = self.seq_channel(self.seq_pos);
            self.next_done = at + self.conv_cycles(next);
        }
    }

    /// A read.
    pub fn read(&mut self, off: u32) -> Option<u32> {
        match off {
            0x300 => Some(self.regs[SR] & 0x3F),
            0x304 => Some(self.common[1]),
            0x308 => Some(0),
            0x4C => {
                self.regs[SR] &= !2;
                Some(self.regs[DR])
            }
            0x00..=0x48 => Some(
                self.regs[(off / 4) as usize] | if off == 0 && self.running { 1 << 4 } else { 0 },
            ),
            _ => None,
        }
    }

    /// A write.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Option<()> {
        match off {
            0x00 => self.regs[SR] &= v, // rc_w0
            0x08 => {
                self.regs[CR2] = v & !(1 << 30);
                if v & 1 == 0 {
                    self.running = false;
                } else if v & (1 << 30) != 0 && !self.running {
                    self.running = true;
                    self.seq_pos = 0;
                    self.next_done = now + self.conv_cycles(self.seq_channel(0));
                }
            }
            0x304 => self.common[1] = v,
            0x300 | 0x308 | 0x4C => {}
            _ if off <= 0x48 => self.regs[(off / 4) as usize] = v,
            _ => return None,
        }
        Some(())
    }
}

impl Default for Adc {
    fn default() -> Self {
        Self::new()
    }
}
