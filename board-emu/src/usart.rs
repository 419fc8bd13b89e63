//! USART6 (RM0090 §30), 8N1 at the rate BRR sets: a byte occupies the line for ten bit
//! times (BRR APB2 clocks each, two core cycles per APB2 clock). RX: bytes from the host
//! arrive back to back, into DR (RXNE) or, with CR3.DMAR, through the DMA; one idle frame
//! after the last byte sets IDLE. TX: DR → shift register, TXE/TC, fed by the DMA with
//! CR3.DMAT. Status flags clear as on the part (RXNE by reading DR; IDLE/ORE/NE/FE by
//! reading SR then DR; TC by writing 0).

use std::collections::VecDeque;

const SR_PE_FE_NE_ORE: u32 = 0xF;
const IDLE: u32 = 1 << 4;
const RXNE: u32 = 1 << 5;
const TC: u32 = 1 << 6;
const TXE: u32 = 1 << 7;
const ORE: u32 = 1 << 3;

/// The USART.
#[derive(Debug, Clone, Default)]
pub struct Usart {
    sr: u32,
    rx_dr: u8,
    brr: u32,
    cr: [u32; 3],
    gtpr: u32,
    sr_seen: u32,
    /// Bytes from the host not yet on the line.
    pub rx_queue: VecDeque<u8>,
    rx_next: Option<u64>,
    idle_at: Option<u64>,
    tx_dr: Option<u8>,
    tx_dr_at: u64,
    tx_free_at: u64,
    dr_empty_since: u64,
    synced: u64,
    /// Bytes on the line towards the host: (completion cycle, byte).
    tx_inflight: VecDeque<(u64, u8)>,
    /// Bytes received by the host (completed).
    pub to_host: Vec<u8>,
    /// Bytes lost to an overrun.
    pub overruns: u64,
    /// Bytes from the host dropped because the USART was off (UE, RE or a rate unset).
    pub dropped: u64,
    /// A frame is on the line (TC is set when the last one completes).
    tx_busy: bool,
}

impl Usart {
    /// At reset.
    pub fn new() -> Self {
        Self {
            sr: TXE | TC,
            ..Default::default()
        }
    }

    /// Core cycles per byte on the line (`None` while the USART is off or has no rate).
    pub fn byte_cycles(&self) -> Option<u64> {
        (self.cr[0] & (1 << 13) != 0 && self.brr != 0).then(|| 20 * u64::from(self.brr))
    }

    /// Host → board: bytes start arriving at `now`.
    pub fn host_send(&mut self, bytes: &[u8], now: u64) {
        if self.byte_cycles().is_none() || self.cr[0] & (1 << 2) == 0 {
            // Nothing samples the line: the bytes are lost, as on the part.
            self.dropped += bytes.len() as u64;
            return;
        }
        self.rx_queue.extend(bytes.iter().copied());
        if self.rx_next.is_none() {
            if let Some(bt) = self.byte_cycles() {
                self.rx_next = Some(now + bt);
                self.idle_at = None;
            }
        }
    }

    fn dmar(&self) -> bool {
        self.cr[2] & (1 << 6) != 0
    }

    fn dmat(&self) -> bool {
        self.cr[2] & (1 << 7) != 0
    }

    /// Brings the line up to `now`; `dma_rx` takes a received byte (false: no DMA
    /// stream took it), `dma_tx` provides the next byte to send.
    pub fn sync(
        &mut self,
        now: u64,
        dma_rx: &mut dyn FnMut(u8) -> bool,
        dma_tx: &mut dyn FnMut() -> Option<u8>,
    ) {
        let from = self.synced;
        self.synced = now;
        let Some(bt) = self.byte_cycles() else {
            return;
        };
        // RX.
        while let Some(t) = self.rx_next.filter(|&t| t <= now) {
            if let Some(b) = self.rx_queue.pop_front() {
                let receiving = self.cr[0] & (1 << 2) != 0;
                if receiving && !(self.dmar() && dma_rx(b)) {
                    if self.sr & RXNE != 0 {
                        self.sr |= ORE;
                        self.overruns += 1;
                    } else {
                        self.rx_dr = b;
                        self.sr |= RXNE;
                    }
                }
            }
            if self.rx_queue.is_empty() {
                self.rx_next = None;
                self.idle_at = Some(t + bt);
            } else {
                self.rx_next = Some(t + bt);
            }
        }
        if let Some(t) = self.idle_at.filter(|&t| t <= now) {
            let _ = t;
            self.idle_at = None;
            if self.cr[0] & (1 << 2) != 0 {
                self.sr |= IDLE;
            }
        }
        // TX.
        loop {
            if let Some(b) = self.tx_dr {
                let start = self.tx_free_at.max(self.tx_dr_at);
                if start > now {
                    break;
                }
                self.tx_dr = None;
                self.tx_free_at = start + bt;
                self.dr_empty_since = start;
                self.tx_inflight.push_back((self.tx_free_at, b));
                self.tx_busy = true;
                self.sr |= TXE;
                continue;
            }
            if self.dmat() {
                if let Some(b) = dma_tx() {
                    self.tx_dr = Some(b);
                    self.tx_dr_at = self.dr_empty_since.max(from);
                    self.sr &= !(TXE | TC);
                    continue;
                }
            }
            break;
        }
        while let Some(&(t, b)) = self.tx_inflight.front() {
            if t > now {
                break;
            }
            self.tx_inflight.pop_front();
            self.to_host.push(b);
        }
        // TC when the last frame completes with nothing left to send (once: software may
        // clear it by writing 0).
        if self.tx_busy && self.tx_dr.is_none() && self.tx_inflight.is_empty() {
            self.tx_busy = false;
            self.sr |= TC;
        }
    }

    /// The next cycle at which something on the line happens.
    pub fn next_event(&self) -> Option<u64> {
        let tx = if self.tx_dr.is_some() || !self.tx_inflight.is_empty() {
            Some(self.tx_free_at.max(self.tx_dr_at))
        } else {
            None
        };
        [self.rx_next, self.idle_at, tx].into_iter().flatten().min()
    }

    /// The interrupt line.
    pub fn irq_level(&self) -> bool {
        let (cr1, cr3) = (self.cr[0], self.cr[2]);
        (self.sr & TXE != 0 && cr1 & (1 << 7) != 0)
            || (self.sr & TC != 0 && cr1 & (1 << 6) != 0)
            || (self.sr & (RXNE | ORE) != 0 && cr1 & (1 << 5) != 0)
            || (self.sr & IDLE != 0 && cr1 & (1 << 4) != 0)
            || (self.sr & SR_PE_FE_NE_ORE & !1 != 0 && cr3 & 1 != 0 && self.dmar())
    }

    /// A read.
    pub fn read(&mut self, off: u32) -> Option<u32> {
        match off {
            0x00 => {
                self.sr_seen = self.sr;
                Some(self.sr)
            }
            0x04 => {
                self.sr &= !RXNE;
                self.sr &= !(self.sr_seen & (IDLE | SR_PE_FE_NE_ORE));
                self.sr_seen = 0;
                Some(u32::from(self.rx_dr))
            }
            0x08 => Some(self.brr),
            0x0C => Some(self.cr[0]),
            0x10 => Some(self.cr[1]),
            0x14 => Some(self.cr[2]),
            0x18 => Some(self.gtpr),
            _ => None,
        }
    }

    /// A write.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Option<()> {
        match off {
            0x00 => self.sr &= v | !(RXNE | TC | (1 << 8) | (1 << 9)),
            0x04 => {
                self.tx_dr = Some(v as u8);
                self.tx_dr_at = now;
                self.sr &= !(TXE | TC);
            }
            0x08 => self.brr = v & 0xFFFF,
            0x0C => self.cr[0] = v,
            0x10 => self.cr[1] = v,
            0x14 => self.cr[2] = v,
            0x18 => self.gtpr = v,
            _ => return None,
        }
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on(u: &mut Usart) {
        u.write(0x08, 0x5B, 0).unwrap(); // BRR 5.6875 → 91 APB2 clocks per bit
        u.write(0x0C, (1 << 13) | (1 << 3) | (1 << 2) | (1 << 4), 0)
            .unwrap(); // UE TE RE IDLEIE
    }

    #[test]
    fn bytes_arrive_paced_and_idle_follows_one_frame_later() {
        let mut u = Usart::new();
        on(&mut u);
        let bt = u.byte_cycles().unwrap();
        assert_eq!(bt, 20 * 0x5B);
        u.write(0x14, 1 << 6, 0).unwrap(); // DMAR
        u.host_send(&[1, 2], 0);
        let mut got = Vec::new();
        u.sync(
            bt - 1,
            &mut |b| {
                got.push(b);
                true
            },
            &mut || None,
        );
        assert!(got.is_empty(), "not before one byte time");
        u.sync(
            2 * bt,
            &mut |b| {
                got.push(b);
                true
            },
            &mut || None,
        );
        assert_eq!(got, [1, 2]);
        assert_eq!(u.read(0x00).unwrap() & IDLE, 0);
        u.sync(3 * bt, &mut |_| true, &mut || None);
        assert_ne!(
            u.read(0x00).unwrap() & IDLE,
            0,
            "IDLE one frame after the last byte"
        );
        assert!(u.irq_level());
        let _ = u.read(0x04); // SR then DR clears it
        assert_eq!(u.read(0x00).unwrap() & IDLE, 0);
    }

    #[test]
    fn a_byte_not_read_in_time_is_an_overrun() {
        let mut u = Usart::new();
        on(&mut u);
        let bt = u.byte_cycles().unwrap();
        u.host_send(&[7, 8], 0);
        u.sync(2 * bt, &mut |_| false, &mut || None);
        assert_eq!(u.overruns, 1);
        assert_ne!(u.read(0x00).unwrap() & ORE, 0);
        assert_eq!(u.read(0x04), Some(7));
    }

    #[test]
    fn dma_transmission_takes_ten_bit_times_per_byte() {
        let mut u = Usart::new();
        on(&mut u);
        u.write(0x14, 1 << 7, 0).unwrap(); // DMAT
        let bt = u.byte_cycles().unwrap();
        let mut data = vec![b'a', b'b', b'c'].into_iter();
        u.sync(0, &mut |_| false, &mut || data.next());
        u.sync(3 * bt - 1, &mut |_| false, &mut || data.next());
        assert_eq!(u.to_host, b"ab");
        u.sync(3 * bt, &mut |_| false, &mut || data.next());
        assert_eq!(u.to_host, b"abc");
        assert_ne!(u.read(0x00).unwrap() & TC, 0);
    }
}
