//! The peripheral bus: every register the firmware touches, by address (RM0090 §2.3
//! memory map), and the board's wiring to the outside ([`Environment`]). An address that
//! belongs to no modelled peripheral is [`Unmodelled`]: the emulator stops with the
//! address and the PC's function, never reads a silent zero.

use crate::adc::Adc;
use crate::clocks::Clocks;
use crate::dac::Dac;
use crate::dma::{Dma, MemAction};
use crate::flash::Flash;
use crate::gpio::Port;
use crate::iwdg::Iwdg;
use crate::scs::{irq, Scs, Unmodelled, IRQS};
use crate::timers::Tim;
use crate::usart::Usart;

/// Core clock, Hz.
pub const SYSCLK_HZ: u64 = 168_000_000;

/// What the board drives (sampled by the environment).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Outputs {
    /// DAC1 channel 1 / 2 codes (`None`: channel off).
    pub dac: [Option<u16>; 2],
    /// PE7, the valve-power enable.
    pub enable: bool,
    /// PD12, the status LED.
    pub led: bool,
}

/// What the board reads from the machine.
#[derive(Debug, Clone, Copy)]
pub struct Inputs {
    /// Master encoder (TIM5), counts.
    pub master: i64,
    /// Slave encoders (TIM2, TIM3), counts.
    pub slaves: [i64; 2],
    /// ADC codes of PC1, PC2, PB0, PB1 (IN11, IN12, IN8, IN9): pressures A/B of slave 0,
    /// A/B of slave 1.
    pub pressures: [u16; 4],
    /// PE8: the E-stop chain closed (run permitted).
    pub estop_closed: bool,
    /// The master encoder's newest rising edge of channel A so far: its core cycle and
    /// the count after it (TIM5 captures the count, TIM8 the time: [`crate::timers`]).
    pub master_edge: Option<(u64, i64)>,
}

impl Default for Inputs {
    fn default() -> Self {
        Self {
            master: 0,
            slaves: [0; 2],
            pressures: [0; 4],
            estop_closed: true,
            master_edge: None,
        }
    }
}

/// What one tick (one TIM7 handler) read from the encoders and wrote to the valves: the
/// first CNT read of TIM5, TIM2, TIM3, the master edge timer's reads (TIM8 CNT, TIM8
/// CCR1 twice, TIM5 CCR1) and the last DAC1 ch1/ch2 holding-register and PE7 writes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TickIo {
    /// Core cycle of the handler's entry.
    pub at: u64,
    /// TIM5, TIM2, TIM3 counts as read.
    pub enc: [Option<u32>; 3],
    /// TIM8's counter as first read (the edge timer's time now).
    pub edge_now: Option<u32>,
    /// TIM8's CCR1 as read first and last (the edge's time, and its re-read).
    pub edge_time: [Option<u32>; 2],
    /// TIM5's CCR1 as read (the count at the edge).
    pub edge_count: Option<u32>,
    /// DAC codes written (12-bit unipolar).
    pub dac: [Option<u16>; 2],
    /// The valve-power enable as written.
    pub enable: Option<bool>,
}

/// The machine around the board.
pub trait Environment {
    /// Advances the machine to core cycle `now` with `out` applied since the previous
    /// call, and returns the inputs at `now`.
    fn advance(&mut self, now: u64, out: &Outputs) -> Inputs;
}

/// A machine that never moves (inputs fixed).
pub struct Still(pub Inputs);

impl Environment for Still {
    fn advance(&mut self, _now: u64, _out: &Outputs) -> Inputs {
        self.0
    }
}

/// The peripherals.
pub struct Bus {
    /// RCC, PWR.
    pub clocks: Clocks,
    /// Flash and its interface.
    pub flash: Flash,
    /// GPIO A–I.
    pub gpio: Vec<Port>,
    /// TIM2 (slave 0 encoder).
    pub tim2: Tim,
    /// TIM3 (slave 1 encoder, 16 bit).
    pub tim3: Tim,
    /// TIM5 (master encoder).
    pub tim5: Tim,
    /// TIM7 (the tick).
    pub tim7: Tim,
    /// TIM8 (the master encoder's edge timer: captures TIM5's trigger output).
    pub tim8: Tim,
    /// TIM12 (embassy's time driver).
    pub tim12: Tim,
    /// DAC1.
    pub dac: Dac,
    /// ADC1.
    pub adc: Adc,
    /// DMA1, DMA2.
    pub dma: [Dma; 2],
    /// USART6 (host link).
    pub usart6: Usart,
    /// IWDG.
    pub iwdg: Iwdg,
    /// NVIC, SCB, SysTick, DWT, FPU, DBGMCU.
    pub scs: Scs,
    syscfg: [u32; 9],
    exti: [u32; 6],
    /// Memory work for the emulator after an access.
    pub actions: Vec<MemAction>,
    /// Cycles an access stalled the CPU (a flash operation it waited for).
    pub stall: u64,
    /// The machine.
    pub env: Box<dyn Environment>,
    /// The latest outputs and inputs.
    pub outputs: Outputs,
    /// The latest inputs.
    pub inputs: Inputs,
    /// Interrupt lines.
    pub levels: [bool; IRQS],
    /// Per-tick I/O, recorded while `Some` (the emulator pushes one entry per TIM7
    /// entry).
    pub tick_io: Option<Vec<TickIo>>,
    /// The master edge last handed to TIM5/TIM8.
    inputs_edge_applied: Option<(u64, i64)>,
}

/// TIM8's capture/compare interrupt line (never enabled by the firmware).
const TIM8_CC: usize = 46;

/// DMA2 request channel of ADC1 (stream 0) and USART6 (streams 1 and 6).
const ADC_CH: u32 = 0;
const USART6_CH: u32 = 5;

impl Bus {
    /// At reset (`flash` and the reset flags carried over).
    pub fn new(flash: Flash, csr_flags: u32, env: Box<dyn Environment>) -> Self {
        Self {
            clocks: Clocks::new(csr_flags),
            flash,
            gpio: (0..9).map(Port::new).collect(),
            tim2: Tim::new(28, true),
            tim3: Tim::new(29, false),
            tim5: Tim::new(50, true),
            tim7: Tim::new(irq::TIM7, false),
            tim8: Tim::new_apb2(TIM8_CC),
            tim12: Tim::new(irq::TIM8_BRK_TIM12, false),
            dac: Dac::default(),
            adc: Adc::new(),
            dma: [
                Dma::new([11, 12, 13, 14, 15, 16, 17, 47]),
                Dma::new([56, 57, 58, 59, 60, 68, 69, 70]),
            ],
            usart6: Usart::new(),
            iwdg: Iwdg::new(),
            scs: Scs::default(),
            syscfg: [0; 9],
            exti: [0; 6],
            actions: Vec::new(),
            stall: 0,
            env,
            outputs: Outputs::default(),
            inputs: Inputs::default(),
            levels: [false; IRQS],
            tick_io: None,
            inputs_edge_applied: None,
        }
    }

    fn in_tick(&self) -> bool {
        self.scs.active.last() == Some(&(16 + irq::TIM7 as u16))
    }

    fn current_outputs(&self) -> Outputs {
        let pe = &self.gpio[4];
        let pd = &self.gpio[3];
        Outputs {
            dac: [self.dac.output(0), self.dac.output(1)],
            enable: pe.is_output(7) && pe.odr() & (1 << 7) != 0,
            led: pd.odr() & (1 << 12) != 0,
        }
    }

    /// Brings the machine and every peripheral to `now`.
    pub fn sync(&mut self, now: u64) {
        let out = self.outputs;
        let inp = self.env.advance(now, &out);
        self.inputs = inp;
        self.tim5.position = inp.master;
        self.tim2.position = inp.slaves[0];
        self.tim3.position = inp.slaves[1];
        if inp.master_edge != self.inputs_edge_applied {
            self.inputs_edge_applied = inp.master_edge;
            if let Some((at, count)) = inp.master_edge {
                // TIM5 ch 1 captures the count; its trigger output (compare pulse) is TIM8's
                // ITR3 (RM0090 Table 86), whose ch 1 on TRC captures TIM8's time.
                self.tim8.sync(at.min(now));
                if self.tim5.capture_count(count) {
                    self.tim8.capture_trigger(3, at.min(now));
                }
            }
        }
        for (ch, code) in [11usize, 12, 8, 9].into_iter().zip(inp.pressures) {
            self.adc.input[ch] = code;
        }
        self.gpio[4].external[8] = Some(inp.estop_closed);
        for t in [
            &mut self.tim2,
            &mut self.tim3,
            &mut self.tim5,
            &mut self.tim7,
            &mut self.tim8,
            &mut self.tim12,
        ] {
            t.sync(now);
        }
        self.flash.sync(now);
        self.scs.systick_sync(now);
        let (dma, actions) = (&mut self.dma[1], &mut self.actions);
        self.adc.sync(now, &mut |c| {
            dma.active(0, ADC_CH) && dma.to_memory(0, u32::from(c.code), actions)
        });
        let dma2 = std::cell::RefCell::new(&mut self.dma[1]);
        let actions = std::cell::RefCell::new(&mut self.actions);
        self.usart6.sync(
            now,
            &mut |b| {
                let mut d = dma2.borrow_mut();
                d.active(1, USART6_CH) && d.to_memory(1, u32::from(b), &mut actions.borrow_mut())
            },
            &mut || {
                let mut d = dma2.borrow_mut();
                if d.active(6, USART6_CH) {
                    d.from_memory(6)
                } else {
                    None
                }
            },
        );
        self.update_levels();
    }

    /// Recomputes the interrupt lines and pends those that are high.
    pub fn update_levels(&mut self) {
        let mut l = [false; IRQS];
        for t in [&self.tim2, &self.tim3, &self.tim5, &self.tim7, &self.tim12] {
            if t.irq_level() {
                l[t.irq] = true;
            }
        }
        for d in &self.dma {
            for s in 0..8 {
                if d.irq_level(s) {
                    l[d.irqs[s]] = true;
                }
            }
        }
        if self.usart6.irq_level() {
            l[irq::USART6] = true;
        }
        self.levels = l;
        self.scs.raise(&l);
    }

    /// The next core cycle at which a peripheral raises an interrupt or changes what the
    /// CPU can observe without asking.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        let mut ev: Vec<u64> = [&self.tim7, &self.tim12]
            .iter()
            .filter_map(|t| t.next_event(now))
            .collect();
        if let Some(t) = self.usart6.next_event() {
            ev.push(t);
        }
        if let Some(t) = self.iwdg.deadline {
            ev.push(t);
        }
        if let Some(t) = self.scs.systick_next(now) {
            ev.push(t);
        }
        // The ADC's DMA stream raises its half/full-transfer interrupt: conversions until
        // the next flag, at the current conversion time.
        let d = &self.dma[1];
        let s = &d.streams[0];
        if let Some(t) = self.adc.next_event() {
            if s.cr & 1 != 0 && s.cr & (3 << 3) != 0 {
                let nd = u64::from(d.ndtr(0));
                let half = u64::from(d.reload(0)) / 2;
                let to_flag = if nd > half { nd - half } else { nd };
                ev.push(t + to_flag.saturating_sub(1) * self.adc.conversion_cycles());
            }
        }
        ev.into_iter().min()
    }

    /// A read of `size` bytes at `addr`.
    pub fn read(&mut self, addr: u32, size: usize, now: u64) -> Result<u32, Unmodelled> {
        self.sync(now);
        if (0x080C_0000..0x0810_0000).contains(&addr) {
            if self.flash.busy_until().is_some() {
                // A read of the array waits for the operation (RM0090 §3.5.4).
                let end = self.flash.busy_until().unwrap_or(now);
                self.stall += end.saturating_sub(now);
                self.flash.sync(end);
            }
            return Ok(self.flash.read_mem((addr - 0x0800_0000) as usize, size));
        }
        let word = addr & !3;
        let shift = 8 * (addr & 3);
        let v = self.read_word(word, now)?;
        if self.in_tick() {
            let ch = match word {
                0x4000_0C24 => Some(0),
                0x4000_0024 => Some(1),
                0x4000_0424 => Some(2),
                _ => None,
            };
            if let Some(rec) = self.tick_io.as_mut().and_then(|t| t.last_mut()) {
                if let Some(ch) = ch {
                    rec.enc[ch].get_or_insert(v);
                }
                match word {
                    0x4001_0424 => {
                        rec.edge_now.get_or_insert(v);
                    }
                    0x4001_0434 => {
                        rec.edge_time[0].get_or_insert(v);
                        rec.edge_time[1] = Some(v);
                    }
                    0x4000_0C34 => rec.edge_count = Some(v),
                    _ => {}
                }
            }
        }
        let v = v >> shift;
        let r = match size {
            1 => v & 0xFF,
            2 => v & 0xFFFF,
            _ => v,
        };
        self.update_levels();
        Ok(r)
    }

    fn read_word(&mut self, a: u32, now: u64) -> Result<u32, Unmodelled> {
        let base = a & !0x3FF;
        let off = a & 0x3FF;
        let r = match base {
            0x4000_0000 => self.tim2.read(off, now),
            0x4000_0400 => self.tim3.read(off, now),
            0x4000_0C00 => self.tim5.read(off, now),
            0x4000_1400 => self.tim7.read(off, now),
            0x4000_1800 => self.tim12.read(off, now),
            0x4001_0400 => self.tim8.read(off, now),
            0x4000_3000 => self.iwdg.read(off, now),
            0x4000_7000 => self.clocks.pwr_read(off),
            0x4000_7400 => self.dac.read(off),
            0x4001_1400 => self.usart6.read(off),
            0x4001_2000 => self.adc.read(off),
            0x4001_3800 => match off {
                0x20 => Some(self.syscfg[8] | (u32::from(self.syscfg[8] & 1 != 0) << 8)),
                0..=0x1C => Some(self.syscfg[(off / 4) as usize]),
                _ => None,
            },
            0x4001_3C00 => self.exti.get((off / 4) as usize).copied(),
            0x4002_0000..=0x4002_2000 => {
                self.gpio[((base - 0x4002_0000) / 0x400) as usize].read(off)
            }
            0x4002_3800 => self.clocks.rcc_read(off),
            0x4002_3C00 => {
                let v = self.flash.read(off, now);
                if off == 0x0C {
                    if let Some(end) = self.flash.busy_until() {
                        // Polling BSY: the CPU would spin until the end; skip there.
                        self.stall += end.saturating_sub(now);
                    }
                }
                v
            }
            0x4002_6000 => self.dma[0].read(off),
            0x4002_6400 => self.dma[1].read(off),
            0xE000_0000..=0xE00F_FC00 => self.scs.read(a, now).ok(),
            _ => None,
        };
        r.ok_or(Unmodelled)
    }

    /// A write of `size` bytes at `addr`.
    pub fn write(&mut self, addr: u32, size: usize, v: u32, now: u64) -> Result<(), Unmodelled> {
        self.sync(now);
        if (0x080C_0000..0x0810_0000).contains(&addr) {
            self.flash
                .write_mem((addr - 0x0800_0000) as usize, size, v, now);
            return Ok(());
        }
        let word = addr & !3;
        let shift = 8 * (addr & 3);
        let mask = match size {
            1 => 0xFFu32 << shift,
            2 => 0xFFFFu32 << shift,
            _ => u32::MAX,
        };
        let val = v << shift;
        if (0xE000_0000..0xE010_0000).contains(&word) {
            self.scs.write(word, val, mask, now)?;
        } else {
            let full = if mask == u32::MAX || matches!(word & !0x3FF, 0x4001_1400 | 0x4001_2000) {
                val
            } else {
                (self.read_word(word, now)? & !mask) | (val & mask)
            };
            self.write_word(word, full, now)?;
            if self.in_tick() {
                if let Some(rec) = self.tick_io.as_mut().and_then(|t| t.last_mut()) {
                    match word {
                        0x4000_7408 => rec.dac[0] = Some(full as u16 & 0xFFF),
                        0x4000_7414 => rec.dac[1] = Some(full as u16 & 0xFFF),
                        0x4002_1018 if full & (1 << 7) != 0 => rec.enable = Some(true),
                        0x4002_1018 if full & (1 << 23) != 0 => rec.enable = Some(false),
                        _ => {}
                    }
                }
            }
        }
        self.outputs = self.current_outputs();
        self.update_levels();
        Ok(())
    }

    fn write_word(&mut self, a: u32, v: u32, now: u64) -> Result<(), Unmodelled> {
        let base = a & !0x3FF;
        let off = a & 0x3FF;
        let r = match base {
            0x4000_0000 => self.tim2.write(off, v, now),
            0x4000_0400 => self.tim3.write(off, v, now),
            0x4000_0C00 => self.tim5.write(off, v, now),
            0x4000_1400 => self.tim7.write(off, v, now),
            0x4000_1800 => self.tim12.write(off, v, now),
            0x4001_0400 => self.tim8.write(off, v, now),
            0x4000_3000 => self.iwdg.write(off, v, now, SYSCLK_HZ),
            0x4000_7000 => self.clocks.pwr_write(off, v),
            0x4000_7400 => self.dac.write(off, v),
            0x4001_1400 => self.usart6.write(off, v, now),
            0x4001_2000 => self.adc.write(off, v, now),
            0x4001_3800 => match off {
                0..=0x20 => {
                    self.syscfg[(off / 4) as usize] = v;
                    Some(())
                }
                _ => None,
            },
            0x4001_3C00 => match off {
                0x14 => {
                    self.exti[5] &= !v;
                    Some(())
                }
                0..=0x10 => {
                    self.exti[(off / 4) as usize] = v;
                    Some(())
                }
                _ => None,
            },
            0x4002_0000..=0x4002_2000 => {
                self.gpio[((base - 0x4002_0000) / 0x400) as usize].write(off, v)
            }
            0x4002_3800 => self.clocks.rcc_write(off, v),
            0x4002_3C00 => self.flash.write(off, v, now),
            0x4002_6000 => self.dma[0].write(0, off, v, &mut self.actions),
            0x4002_6400 => self.dma[1].write(1, off, v, &mut self.actions),
            _ => None,
        };
        r.ok_or(Unmodelled)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unmodelled_peripheral_is_an_error_not_a_zero() {
        let mut b = Bus::new(Flash::new(), 0, Box::new(Still(Inputs::default())));
        assert_eq!(
            b.read(0x4000_4400, 4, 0),
            Err(Unmodelled),
            "USART2 is not on this board"
        );
        assert_eq!(b.write(0x4000_0800, 4, 0, 0), Err(Unmodelled), "TIM4");
        assert_eq!(
            b.read(0x4002_3874, 4, 0).map(|v| v & 0x0E00_0000),
            Ok(0),
            "RCC_CSR reads"
        );
    }

    #[test]
    fn adc_scans_into_the_dma_ring() {
        let mut b = Bus::new(
            Flash::new(),
            0,
            Box::new(Still(Inputs {
                pressures: [100, 200, 300, 400],
                ..Inputs::default()
            })),
        );
        // DMA2 stream 0: channel 0, p2m, circular, MINC, 16-bit, 8 items at 0x2000_0000.
        b.write(0x4002_6400 + 0x10 + 4, 4, 8, 0).unwrap();
        b.write(0x4002_6400 + 0x10 + 0xC, 4, 0x2000_0000, 0)
            .unwrap();
        b.write(
            0x4002_6400 + 0x10,
            4,
            (1 << 13) | (1 << 11) | (1 << 10) | (1 << 8) | 1,
            0,
        )
        .unwrap();
        // ADC1: IN11, IN12, IN8, IN9; 144-cycle sampling; continuous, DMA + DDS, start.
        b.write(0x4001_2000 + 0x2C, 4, 3 << 20, 0).unwrap();
        b.write(
            0x4001_2000 + 0x34,
            4,
            11 | (12 << 5) | (8 << 10) | (9 << 15),
            0,
        )
        .unwrap();
        b.write(0x4001_2000 + 0x0C, 4, 0o660, 0).unwrap();
        b.write(0x4001_2000 + 0x304, 4, 1 << 16, 0).unwrap(); // ADCPRE /4: 21 MHz
        b.write(0x4001_2000 + 0x10, 4, 0o6600000000, 0).unwrap();
        b.write(
            0x4001_2000 + 0x08,
            4,
            1 | 2 | (1 << 8) | (1 << 9) | (1 << 30),
            0,
        )
        .unwrap();
        // (144 + 12) ADC clocks at 21 MHz = 1248 core cycles per conversion.
        b.sync(4 * 1248);
        let writes: Vec<u16> = b
            .actions
            .iter()
            .filter_map(|a| match a {
                MemAction::Write(_, v) => Some(u16::from_le_bytes([v[0], v[1]])),
                _ => None,
            })
            .collect();
        assert_eq!(writes, [100, 200, 300, 400]);
        assert_eq!(b.dma[1].ndtr(0), 4, "half the ring left");
    }
}
