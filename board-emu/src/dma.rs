//! DMA1/DMA2 (RM0090 §10): eight streams each with CR, NDTR, PAR, M0AR, M1AR, FCR, the
//! interrupt status/clear registers, circular mode, half- and full-transfer flags and
//! their interrupts. Transfers are made by the peripherals' requests
//! ([`Dma::to_memory`], [`Dma::from_memory`]); memory is written through the bus's
//! pending writes (the emulator applies them to the CPU's RAM).

/// One stream.
#[derive(Debug, Clone, Default)]
pub struct Stream {
    /// SxCR.
    pub cr: u32,
    ndtr: u32,
    /// NDTR as programmed (reloaded in circular mode).
    reload: u32,
    par: u32,
    m0ar: u32,
    m1ar: u32,
    fcr: u32,
    /// Items transferred in this round.
    pos: u32,
    /// Memory-to-peripheral: the bytes read at enable (the firmware does not change a
    /// buffer under an active transfer).
    pub tx_data: Vec<u8>,
}

/// A DMA controller.
#[derive(Debug, Clone)]
pub struct Dma {
    /// The streams.
    pub streams: [Stream; 8],
    isr: [u32; 2],
    /// Interrupt lines of the eight streams.
    pub irqs: [usize; 8],
}

/// Flag bit offsets of streams 0–3 within LISR (4–7 within HISR).
const FLAG_SHIFT: [u32; 4] = [0, 6, 16, 22];
const TCIF: u32 = 1 << 5;
const HTIF: u32 = 1 << 4;

/// What the bus must do in memory after a DMA register access.
#[derive(Debug, Clone)]
pub enum MemAction {
    /// Write bytes at an address.
    Write(u32, Vec<u8>),
    /// Read `len` bytes at an address into stream `stream`'s `tx_data` of controller
    /// `ctrl` (0 = DMA1).
    Snapshot {
        /// Controller.
        ctrl: usize,
        /// Stream.
        stream: usize,
        /// Address.
        addr: u32,
        /// Length.
        len: u32,
    },
}

impl Dma {
    /// A controller with its streams' interrupt lines.
    pub fn new(irqs: [usize; 8]) -> Self {
        Self {
            streams: Default::default(),
            isr: [0; 2],
            irqs,
        }
    }

    fn flags(&self, s: usize) -> u32 {
        (self.isr[s / 4] >> FLAG_SHIFT[s % 4]) & 0x3D
    }

    fn set_flags(&mut self, s: usize, f: u32) {
        self.isr[s / 4] |= f << FLAG_SHIFT[s % 4];
    }

    /// Whether stream `s` is enabled on request channel `chsel`.
    pub fn active(&self, s: usize, chsel: u32) -> bool {
        let c = &self.streams[s].cr;
        c & 1 != 0 && (c >> 25) & 7 == chsel
    }

    /// Stream `s`'s programmed item count.
    pub fn reload(&self, s: usize) -> u32 {
        self.streams[s].reload
    }

    /// Remaining items of stream `s`.
    pub fn ndtr(&self, s: usize) -> u32 {
        self.streams[s].ndtr
    }

    fn advance(&mut self, s: usize) {
        let st = &mut self.streams[s];
        st.ndtr = st.ndtr.saturating_sub(1);
        st.pos += 1;
        let reload = st.reload;
        let mut f = 0;
        if st.ndtr == reload / 2 {
            f |= HTIF;
        }
        if st.ndtr == 0 {
            f |= TCIF;
            if st.cr & (1 << 8) != 0 {
                st.ndtr = reload;
                st.pos = 0;
            } else {
                st.cr &= !1;
            }
        }
        self.set_flags(s, f);
    }

    /// A peripheral-to-memory request on stream `s`: one item `value` written to memory.
    /// `false` if the stream is not enabled.
    pub fn to_memory(&mut self, s: usize, value: u32, out: &mut Vec<MemAction>) -> bool {
        let st = &self.streams[s];
        if st.cr & 1 == 0 || st.ndtr == 0 {
            return false;
        }
        if (st.cr >> 13) & 3 == 3 {
            // MSIZE 0b11 is reserved: a transfer error, the stream disabled.
            self.streams[s].cr &= !1;
            self.set_flags(s, 1 << 3);
            return false;
        }
        let msize = 1u32 << ((st.cr >> 13) & 3);
        let minc = st.cr & (1 << 10) != 0;
        let addr = st.m0ar + if minc { st.pos * msize } else { 0 };
        let bytes = value.to_le_bytes()[..msize as usize].to_vec();
        out.push(MemAction::Write(addr, bytes));
        self.advance(s);
        true
    }

    /// A memory-to-peripheral request on stream `s`: the next byte, if any.
    pub fn from_memory(&mut self, s: usize) -> Option<u8> {
        let st = &self.streams[s];
        if st.cr & 1 == 0 || st.ndtr == 0 {
            return None;
        }
        let msize = 1usize << ((st.cr >> 13) & 3).min(2);
        let b = st
            .tx_data
            .get(st.pos as usize * msize)
            .copied()
            .unwrap_or(0);
        self.advance(s);
        Some(b)
    }

    /// Stream `s`'s interrupt line level.
    pub fn irq_level(&self, s: usize) -> bool {
        let cr = self.streams[s].cr;
        let f = self.flags(s);
        (f & TCIF != 0 && cr & (1 << 4) != 0)
            || (f & HTIF != 0 && cr & (1 << 3) != 0)
            || (f & (1 << 3) != 0 && cr & (1 << 2) != 0)
            || (f & (1 << 2) != 0 && cr & (1 << 1) != 0)
            || (f & 1 != 0 && self.streams[s].fcr & (1 << 7) != 0)
    }

    /// A read.
    pub fn read(&self, off: u32) -> Option<u32> {
        match off {
            0x00 => Some(self.isr[0]),
            0x04 => Some(self.isr[1]),
            0x08 | 0x0C => Some(0),
            0x10..=0xCC => {
                let s = ((off - 0x10) / 0x18) as usize;
                let st = self.streams.get(s)?;
                Some(match (off - 0x10) % 0x18 {
                    0x00 => st.cr,
                    0x04 => st.ndtr,
                    0x08 => st.par,
                    0x0C => st.m0ar,
                    0x10 => st.m1ar,
                    _ => st.fcr | 0x20, // FIFO empty
                })
            }
            _ => None,
        }
    }

    /// A write (controller `ctrl`, for snapshots).
    pub fn write(&mut self, ctrl: usize, off: u32, v: u32, out: &mut Vec<MemAction>) -> Option<()> {
        match off {
            0x00 | 0x04 => {}
            0x08 => self.isr[0] &= !v,
            0x0C => self.isr[1] &= !v,
            0x10..=0xCC => {
                let s = ((off - 0x10) / 0x18) as usize;
                let st = self.streams.get_mut(s)?;
                let en = st.cr & 1 != 0;
                match (off - 0x10) % 0x18 {
                    0x00 => {
                        st.cr = v;
                        if !en && v & 1 != 0 {
                            st.pos = 0;
                            st.ndtr = st.reload;
                            if (v >> 6) & 3 == 1 {
                                // Bytes feed this board's USART: MSIZE 8-bit.
                                let msize = 1u32 << ((v >> 13) & 3).min(2);
                                out.push(MemAction::Snapshot {
                                    ctrl,
                                    stream: s,
                                    addr: st.m0ar,
                                    len: st.reload.saturating_mul(msize),
                                });
                            }
                        }
                    }
                    0x04 if !en => {
                        st.reload = v & 0xFFFF;
                        st.ndtr = st.reload;
                    }
                    0x08 if !en => st.par = v,
                    0x0C if !en => st.m0ar = v,
                    0x10 => st.m1ar = v,
                    0x14 => st.fcr = v,
                    _ => {}
                }
            }
            _ => return None,
        }
        Some(())
    }
}
