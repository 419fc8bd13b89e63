//! General-purpose and basic timers (RM0090 §18–20): up-counting with prescaler and
//! auto-reload, update and compare flags and their interrupts (TIM7, TIM12), and
//! encoder mode (TIM2/3/5), whose counter is the plant's position in counts.
//!
//! The kernel clock is 84 MHz (APB1 at 42 MHz with its ×2 timer multiplier): one timer
//! clock per [`CORE_PER_TIMCLK`] core cycles; TIM8 on APB2 counts at 168 MHz
//! ([`Tim::new_apb2`]).
//!
//! **Input capture** (RM0090 §18.3.5): a channel whose CCxS selects an input and whose
//! CCxE is set copies a value into CCRx at an edge, sets CCxIF (CCxOF if it was still
//! set), and reading CCRx clears CCxIF. Two sources are modelled, the ones the firmware
//! wires: TIM5's channel 1 in encoder mode at a rising edge of channel A
//! ([`Tim::capture_count`]: the count), and TIM8's channel 1 on TRC from TIM5's trigger
//! output in compare-pulse mode ([`Tim::capture_trigger`]: TIM8's own counter at the
//! edge's cycle) — the master encoder's edge timer (`firmware/src/encoders.rs`). State is computed lazily from the core cycle
//! at which counting (re)started, so a timer costs nothing between accesses; its next
//! interrupt is reported to the scheduler ([`Tim::next_event`]).

/// Core cycles (168 MHz) per timer kernel clock (84 MHz).
pub const CORE_PER_TIMCLK: u64 = 2;

const CR1: usize = 0;
/// CR2 (byte offset 0x04).
const CR2: usize = 1;
const SMCR: usize = 0x08 / 4;
const DIER: usize = 0x0C / 4;
const SR: usize = 0x10 / 4;
const EGR: usize = 0x14 / 4;
const CCMR1: usize = 0x18 / 4;
const CCER: usize = 0x20 / 4;
const CNT: usize = 0x24 / 4;
const PSC: usize = 0x28 / 4;
const ARR: usize = 0x2C / 4;
const CCR1: usize = 0x34 / 4;
const CCR4: usize = 0x40 / 4;

/// One timer.
#[derive(Debug, Clone)]
pub struct Tim {
    /// Interrupt line (an index into the NVIC's external interrupts).
    pub irq: usize,
    /// A 32-bit counter (TIM2, TIM5) or a 16-bit one.
    pub wide: bool,
    regs: [u32; 21],
    /// Prescaler in effect (PSC is loaded at an update event).
    psc_active: u32,
    /// Core cycle at which `cnt_base` was the counter's value.
    base_cycle: u64,
    cnt_base: u32,
    last_sync: u64,
    /// Encoder mode: the counter is `position + offset` (mod ARR + 1).
    enc_offset: i64,
    /// The external position in counts (encoder mode).
    pub position: i64,
    /// Core cycles per kernel clock (2 on APB1, 1 on APB2).
    core_per_clk: u64,
}

impl Tim {
    /// A timer at its reset state.
    pub fn new(irq: usize, wide: bool) -> Self {
        let mut regs = [0; 21];
        regs[ARR] = if wide { u32::MAX } else { 0xFFFF };
        Self {
            irq,
            wide,
            regs,
            psc_active: 0,
            base_cycle: 0,
            cnt_base: 0,
            last_sync: 0,
            enc_offset: 0,
            position: 0,
            core_per_clk: CORE_PER_TIMCLK,
        }
    }

    /// A 16-bit timer on APB2 (TIM1, TIM8: kernel clock 168 MHz).
    pub fn new_apb2(irq: usize) -> Self {
        Self {
            core_per_clk: 1,
            ..Self::new(irq, false)
        }
    }

    /// Channel `ch`'s CCxS (0: output; 1…3: an input).
    fn ccs(&self, ch: usize) -> u32 {
        (self.regs[CCMR1 + ch / 2] >> (8 * (ch % 2))) & 3
    }

    /// Whether channel `ch` captures: an input selected and CCxE set.
    fn capturing(&self, ch: usize) -> bool {
        self.ccs(ch) != 0 && self.regs[CCER] & (1 << (4 * ch)) != 0
    }

    /// A capture on channel `ch` of `value` (nothing unless it is capturing).
    fn capture(&mut self, ch: usize, value: u32) -> bool {
        if !self.capturing(ch) {
            return false;
        }
        if self.regs[SR] & (2 << ch) != 0 {
            self.regs[SR] |= 1 << (9 + ch); // CCxOF
        }
        self.regs[CCR1 + ch] = value;
        self.regs[SR] |= 2 << ch;
        true
    }

    /// Encoder mode, a rising edge of channel A after which the position is `count`:
    /// channel 1 (on TI1, CC1S = 01) captures the counter. Returns whether the trigger
    /// output pulses (CR2.MMS = 011, compare pulse: on every capture of channel 1).
    pub fn capture_count(&mut self, count: i64) -> bool {
        let mask = if self.wide { u32::MAX as u64 } else { 0xFFFF };
        let p = self.period() as i64;
        let v = ((count + self.enc_offset).rem_euclid(p) as u64 & mask) as u32;
        self.ccs(0) == 1 && self.capture(0, v) && (self.regs[CR2] >> 4) & 7 == 3
    }

    /// A trigger pulse from internal trigger `itr` at core cycle `at` (≤ now): channel 1
    /// on TRC (CC1S = 11) captures the counter at that cycle if SMCR.TS selects `itr`.
    pub fn capture_trigger(&mut self, itr: u32, at: u64) {
        if (self.regs[SMCR] >> 4) & 7 == itr && self.ccs(0) == 3 {
            let v = self.counter(at.max(self.base_cycle));
            self.capture(0, v);
        }
    }

    fn enabled(&self) -> bool {
        self.regs[CR1] & 1 != 0
    }

    fn encoder(&self) -> bool {
        matches!(self.regs[SMCR] & 7, 1..=3)
    }

    fn period(&self) -> u64 {
        u64::from(self.regs[ARR]) + 1
    }

    fn core_per_tick(&self) -> u64 {
        self.core_per_clk * (u64::from(self.psc_active) + 1)
    }

    /// Timer ticks since `base_cycle` at core cycle `now`.
    fn ticks(&self, now: u64) -> u64 {
        if !self.enabled() || self.encoder() {
            return 0;
        }
        now.saturating_sub(self.base_cycle) / self.core_per_tick()
    }

    /// The counter at `now`.
    pub fn counter(&self, now: u64) -> u32 {
        let mask = if self.wide { u32::MAX as u64 } else { 0xFFFF };
        if self.encoder() {
            let p = self.period() as i64;
            return ((self.position + self.enc_offset).rem_euclid(p) as u64 & mask) as u32;
        }
        ((u64::from(self.cnt_base) + self.ticks(now)) % self.period()) as u32
    }

    /// Brings the flags up to `now`.
    pub fn sync(&mut self, now: u64) {
        if now <= self.last_sync || !self.enabled() || self.encoder() {
            self.last_sync = self.last_sync.max(now);
            return;
        }
        let t0 = self.ticks(self.last_sync);
        let n = self.ticks(now) - t0;
        self.last_sync = now;
        if n == 0 {
            return;
        }
        let period = self.period();
        let c0 = (u64::from(self.cnt_base) + t0) % period;
        if n >= period - c0 && self.regs[CR1] & 2 == 0 {
            self.regs[SR] |= 1; // UIF
        }
        for ch in 0..4 {
            let ccr = u64::from(self.regs[CCR1 + ch]);
            // A compare (output) channel only: an input channel's flag is its capture's.
            if self.ccs(ch) == 0 && ccr < period && (ccr + period - c0 - 1) % period < n {
                self.regs[SR] |= 2 << ch; // CCxIF
            }
        }
    }

    /// The core cycle of the next event whose interrupt is enabled.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        if !self.enabled() || self.encoder() {
            return None;
        }
        let dier = self.regs[DIER];
        let period = self.period();
        let t = self.ticks(now);
        let c = (u64::from(self.cnt_base) + t) % period;
        let mut k: Option<u64> = None;
        let mut take = |d: u64| k = Some(k.map_or(d, |x: u64| x.min(d)));
        if dier & 1 != 0 {
            take(period - c);
        }
        for ch in 0..4 {
            let ccr = u64::from(self.regs[CCR1 + ch]);
            if dier & (2 << ch) != 0 && ccr < period {
                take((ccr + period - c - 1) % period + 1);
            }
        }
        k.map(|k| self.base_cycle + (t + k) * self.core_per_tick())
    }

    /// Whether the interrupt line is high (a flag set whose interrupt is enabled).
    pub fn irq_level(&self) -> bool {
        self.regs[SR] & self.regs[DIER] & 0x1F != 0
    }

    /// Re-bases the counter at `now` with value `cnt`.
    fn rebase(&mut self, now: u64, cnt: u32) {
        self.cnt_base = cnt;
        self.base_cycle = now;
        self.last_sync = now;
    }

    /// A 32-bit read of the register at byte offset `off`.
    pub fn read(&mut self, off: u32, now: u64) -> Option<u32> {
        self.sync(now);
        let i = (off / 4) as usize;
        if off > 0x50 {
            return None;
        }
        Some(match i {
            CNT => self.counter(now),
            // Reading a capture register clears its flag.
            CCR1..=CCR4 if self.ccs(i - CCR1) != 0 => {
                self.regs[SR] &= !(2 << (i - CCR1));
                self.regs[i]
            }
            _ => *self.regs.get(i)?,
        })
    }

    /// A 32-bit write.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Option<()> {
        self.sync(now);
        if off > 0x50 {
            return None;
        }
        let i = (off / 4) as usize;
        match i {
            CR1 => {
                let cnt = self.counter(now);
                let was = self.enabled();
                self.regs[CR1] = v & 0x3FF;
                if was != self.enabled() {
                    self.rebase(now, cnt);
                }
            }
            SR => self.regs[SR] &= v, // rc_w0
            EGR => {
                if v & 1 != 0 {
                    // UG: counter and prescaler reloaded; UIF unless URS.
                    self.psc_active = self.regs[PSC];
                    self.rebase(now, 0);
                    if self.regs[CR1] & 4 == 0 {
                        self.regs[SR] |= 1;
                    }
                }
                self.regs[SR] |= v & 0x1E; // CCxG
            }
            CNT => {
                if self.encoder() {
                    self.enc_offset = i64::from(v) - self.position;
                } else {
                    self.rebase(now, v);
                }
            }
            PSC => {
                self.regs[PSC] = v & 0xFFFF;
                if !self.enabled() {
                    self.psc_active = self.regs[PSC];
                }
            }
            ARR => {
                let cnt = self.counter(now);
                self.regs[ARR] = if self.wide { v } else { v & 0xFFFF };
                self.rebase(
                    now,
                    (u64::from(cnt) % (u64::from(self.regs[ARR]) + 1)) as u32,
                );
            }
            SMCR => {
                let cnt = self.counter(now);
                self.regs[SMCR] = v;
                if self.encoder() {
                    self.enc_offset = i64::from(cnt) - self.position;
                }
            }
            _ => *self.regs.get_mut(i)? = v,
        }
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tim3_in_encoder_mode_wraps_at_16_bits() {
        let mut t = Tim::new(29, false);
        t.position = 1000;
        t.write(0x08, 3, 0).unwrap(); // SMS = encoder mode 3: counts from here
        t.write(0x00, 1, 0).unwrap();
        t.position = 1000 + 70_000;
        assert_eq!(t.read(0x24, 0), Some(70_000 - 65_536));
        t.position = 1000 - 5;
        assert_eq!(t.read(0x24, 0), Some(65_531));
    }

    #[test]
    fn update_and_compare_flags_and_the_next_event() {
        // TIM12-like: PSC 83 (1 MHz), ARR 999 (1 kHz), CCR1 500, UIE + CC1IE.
        let mut t = Tim::new(43, false);
        t.write(0x28, 83, 0).unwrap();
        t.write(0x2C, 999, 0).unwrap();
        t.write(0x00, 4, 0).unwrap(); // URS: UG sets no flag
        t.write(0x14, 1, 0).unwrap(); // UG: PSC loaded
        t.write(0x34, 500, 0).unwrap();
        t.write(0x0C, 3, 0).unwrap();
        t.write(0x00, 5, 0).unwrap(); // CEN
        assert_eq!(t.read(0x10, 0), Some(0));
        // 168 core cycles per µs: CC1 at 500 µs, update at 1000 µs.
        assert_eq!(t.next_event(0), Some(500 * 168));
        t.sync(500 * 168);
        assert_eq!(t.read(0x10, 500 * 168), Some(2));
        assert!(t.irq_level());
        t.write(0x10, !2, 500 * 168).unwrap(); // rc_w0
        assert!(!t.irq_level());
        assert_eq!(t.next_event(500 * 168), Some(1000 * 168));
        t.sync(1000 * 168);
        assert_eq!(t.read(0x10, 1000 * 168).map(|v| v & 1), Some(1));
        assert_eq!(t.read(0x24, 1000 * 168 + 168 * 7), Some(7));
        assert_eq!(t.read(0x60, 0), None, "beyond the register block");
    }

    #[test]
    fn the_master_edge_capture_pair() {
        // TIM5 in encoder mode 3 (SMCR.SMS = 011), CC1S = 01, CC1E, MMS = compare pulse.
        let mut t5 = Tim::new(50, true);
        t5.write(0x08, 3, 0).unwrap();
        t5.write(0x18, 0x0101, 0).unwrap();
        t5.write(0x04, 3 << 4, 0).unwrap();
        t5.position = 100;
        // Without CC1E nothing is captured and no trigger leaves.
        assert!(!t5.capture_count(101));
        t5.write(0x20, 1, 0).unwrap();
        // TIM8 on APB2: PSC 167 (1 MHz), TS = ITR3, CC1S = 11 (TRC), CC1E, CEN.
        let mut t8 = Tim::new_apb2(46);
        t8.write(0x28, 167, 0).unwrap();
        t8.write(0x08, 3 << 4, 0).unwrap();
        t8.write(0x18, 3, 0).unwrap();
        t8.write(0x20, 1, 0).unwrap();
        t8.write(0x14, 1, 0).unwrap();
        t8.write(0x00, 1, 0).unwrap();
        // An edge at 2.5 ms (420 000 core cycles = 2 500 µs), count 101 after it.
        assert!(t5.capture_count(101));
        t8.capture_trigger(3, 420_000);
        assert_eq!(t5.read(0x10, 500_000).map(|v| v & 2), Some(2), "CC1IF");
        assert_eq!(t8.read(0x34, 500_000), Some(2_500));
        assert_eq!(t5.read(0x34, 500_000), Some(101));
        assert_eq!(
            t5.read(0x10, 500_000).map(|v| v & 2),
            Some(0),
            "read clears CC1IF"
        );
        // Another trigger source (ITR0) is not TIM8's: nothing captured.
        t8.capture_trigger(0, 450_000);
        assert_eq!(t8.read(0x34, 500_000), Some(2_500));
        // Two captures unread: overcapture.
        assert!(t5.capture_count(105));
        assert!(t5.capture_count(109));
        assert_eq!(
            t5.read(0x10, 500_000).map(|v| v & (1 << 9)),
            Some(1 << 9),
            "CC1OF"
        );
        // A capture channel never sets its flag by comparing: TIM8's counter passes
        // CCR1 without a flag.
        t8.sync(1_000_000);
        assert_eq!(t8.read(0x10, 1_000_000).map(|v| v & 2), Some(0));
    }
}
