//! The Cortex-M4's system control space (0xE000_0000 …): NVIC, SCB, SysTick, DWT, DCB,
//! FPU control, and the STM32's DBGMCU. Register offsets and bits per the ARMv7-M
//! Architecture Reference Manual (B3) and PM0214.
//!
//! Exception numbers: 1 reset, 2 NMI, 3 HardFault, …, 11 SVCall, 14 PendSV, 15 SysTick,
//! 16 + n the n-th external interrupt (RM0090 table 61: TIM7 = 55, DMA2 stream 0 = 56, …).
//! Priorities are bytes with the STM32F4's four implemented bits (`0xF0`); with the
//! reset PRIGROUP every bit is group priority, so a lower byte preempts.

/// External interrupt lines of the STM32F407.
pub const IRQS: usize = 82;

/// Interrupt numbers (RM0090 table 61) the firmware's peripherals raise.
pub mod irq {
    /// TIM8 break / TIM12 global (the embassy time driver).
    pub const TIM8_BRK_TIM12: usize = 43;
    /// TIM7 global (the tick).
    pub const TIM7: usize = 55;
    /// DMA2 stream 0 (ADC1).
    pub const DMA2_STREAM0: usize = 56;
    /// DMA2 stream 1 (USART6 RX).
    pub const DMA2_STREAM1: usize = 57;
    /// DMA2 stream 6 (USART6 TX).
    pub const DMA2_STREAM6: usize = 69;
    /// USART6 global.
    pub const USART6: usize = 71;
}

/// The system control space's state.
#[derive(Debug, Clone)]
pub struct Scs {
    /// NVIC_ISER: enabled external interrupts.
    pub enabled: [bool; IRQS],
    /// Pending external interrupts.
    pub pending: [bool; IRQS],
    /// NVIC_IPR bytes.
    pub ipr: [u8; IRQS],
    /// Active exceptions, innermost last (exception numbers).
    pub active: Vec<u16>,
    /// PendSV / SysTick pending (ICSR).
    pub pendsv: bool,
    /// SysTick pending.
    pub systick_pending: bool,
    /// SCB_VTOR.
    pub vtor: u32,
    /// SCB_AIRCR's PRIGROUP.
    pub prigroup: u32,
    /// SCB_SCR.
    pub scr: u32,
    /// SCB_CCR.
    pub ccr: u32,
    /// SHPR1..3 bytes (exceptions 4..15).
    pub shpr: [u8; 12],
    /// SHCSR, CFSR, HFSR, MMFAR, BFAR.
    pub fault_regs: [u32; 5],
    /// CPACR.
    pub cpacr: u32,
    /// FPCCR, FPCAR, FPDSCR.
    pub fpccr: u32,
    /// FPCAR.
    pub fpcar: u32,
    /// FPDSCR.
    pub fpdscr: u32,
    /// SysTick CSR, RVR.
    pub syst_csr: u32,
    /// SysTick reload.
    pub syst_rvr: u32,
    /// Cycle at which SysTick's counter was last loaded.
    pub syst_base: u64,
    /// The cycle SysTick was last brought up to.
    pub syst_last: u64,
    /// DWT_CTRL.
    pub dwt_ctrl: u32,
    /// CYCCNT at `cyccnt_base_cycle` (it counts only while enabled).
    pub cyccnt_base: u32,
    /// The cycle at which CYCCNT was last written or enabled.
    pub cyccnt_base_cycle: u64,
    /// DCB_DEMCR.
    pub demcr: u32,
    /// DBGMCU_CR, APB1_FZ, APB2_FZ.
    pub dbgmcu: [u32; 3],
    /// AIRCR.SYSRESETREQ written (the board resets).
    pub reset_request: bool,
    /// An event for WFE (SEVONPEND).
    pub event: bool,
}

impl Default for Scs {
    fn default() -> Self {
        Self {
            enabled: [false; IRQS],
            pending: [false; IRQS],
            ipr: [0; IRQS],
            active: Vec::new(),
            pendsv: false,
            systick_pending: false,
            vtor: 0,
            prigroup: 0,
            scr: 0,
            ccr: 0x200, // STKALIGN
            shpr: [0; 12],
            fault_regs: [0; 5],
            cpacr: 0,
            fpccr: 0xC000_0000, // ASPEN | LSPEN
            fpcar: 0,
            fpdscr: 0,
            syst_csr: 0,
            syst_rvr: 0,
            syst_base: 0,
            syst_last: 0,
            dwt_ctrl: 0x4000_0000, // NUMCOMP = 4
            cyccnt_base: 0,
            cyccnt_base_cycle: 0,
            demcr: 0,
            dbgmcu: [0; 3],
            reset_request: false,
            event: false,
        }
    }
}

/// What an access to an unmodelled register reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unmodelled;

impl Scs {
    /// CYCCNT at `now` (it counts core cycles while DWT_CTRL.CYCCNTENA and DEMCR.TRCENA).
    pub fn cyccnt(&self, now: u64) -> u32 {
        if self.cyccnt_running() {
            self.cyccnt_base
                .wrapping_add(now.wrapping_sub(self.cyccnt_base_cycle) as u32)
        } else {
            self.cyccnt_base
        }
    }

    fn cyccnt_running(&self) -> bool {
        self.dwt_ctrl & 1 != 0 && self.demcr & (1 << 24) != 0
    }

    /// The priority byte of exception `exc` (fixed priorities negative).
    pub fn priority(&self, exc: u16) -> i32 {
        match exc {
            1 => -3,
            2 => -2,
            3 => -1,
            4..=15 => i32::from(self.shpr[usize::from(exc) - 4] & 0xF0),
            _ => self
                .ipr
                .get(usize::from(exc) - 16)
                .map_or(256, |p| i32::from(p & 0xF0)),
        }
    }

    /// The group priority (PRIGROUP splits the byte; the reset PRIGROUP keeps it whole
    /// with four implemented bits).
    fn group(&self, p: i32) -> i32 {
        if p < 0 {
            return p;
        }
        let shift = (self.prigroup + 1).min(8);
        if shift <= 4 {
            p
        } else {
            (p >> shift) << shift
        }
    }

    /// The execution priority given the active exceptions and the masks.
    pub fn execution_priority(&self, primask: bool, basepri: u32) -> i32 {
        let mut p = 256;
        for &e in &self.active {
            p = p.min(self.group(self.priority(e)));
        }
        if basepri & 0xF0 != 0 {
            p = p.min(self.group((basepri & 0xF0) as i32));
        }
        if primask {
            p = p.min(0);
        }
        p
    }

    /// The highest-priority pending exception that would preempt at `exec_prio`.
    pub fn takeable(&self, exec_prio: i32) -> Option<u16> {
        let mut best: Option<(i32, u16)> = None;
        let mut consider = |exc: u16, prio: i32| {
            if self.group(prio) < exec_prio && best.is_none_or(|(bp, _)| prio < bp) {
                best = Some((prio, exc));
            }
        };
        if self.pendsv {
            consider(14, self.priority(14));
        }
        if self.systick_pending {
            consider(15, self.priority(15));
        }
        for n in 0..IRQS {
            if self.pending[n] && self.enabled[n] {
                consider(16 + n as u16, self.priority(16 + n as u16));
            }
        }
        best.map(|b| b.1)
    }

    /// Whether any enabled interrupt is pending (WFI wakes on it whatever the masks).
    pub fn any_pending(&self) -> bool {
        self.pendsv || self.systick_pending || (0..IRQS).any(|n| self.pending[n] && self.enabled[n])
    }

    /// Marks `exc` active and no longer pending (exception entry).
    pub fn enter(&mut self, exc: u16) {
        match exc {
            14 => self.pendsv = false,
            15 => self.systick_pending = false,
            e if e >= 16 => {
                if let Some(p) = self.pending.get_mut(usize::from(e) - 16) {
                    *p = false;
                }
            }
            _ => {}
        }
        self.active.push(exc);
    }

    /// Raises external interrupt lines that are high (level-sensitive; a line high while
    /// its handler runs pends it again at the handler's return, see [`Self::leave`]).
    pub fn raise(&mut self, levels: &[bool; IRQS]) {
        for (n, &high) in levels.iter().enumerate() {
            if high && !self.active.contains(&(16 + n as u16)) {
                if !self.pending[n] && self.scr & 0x10 != 0 {
                    self.event = true; // SEVONPEND
                }
                self.pending[n] = true;
            }
        }
    }

    /// Exception return from `exc`: it is no longer active; a level still high pends it
    /// again.
    pub fn leave(&mut self, exc: u16, levels: &[bool; IRQS]) {
        if let Some(i) = self.active.iter().rposition(|&e| e == exc) {
            self.active.remove(i);
        }
        if exc >= 16 {
            let n = usize::from(exc) - 16;
            if levels.get(n).copied().unwrap_or(false) {
                if let Some(p) = self.pending.get_mut(n) {
                    *p = true;
                }
            }
        }
    }

    fn bits(flags: &[bool], word: usize) -> u32 {
        (0..32)
            .filter(|b| flags.get(word * 32 + b).copied().unwrap_or(false))
            .fold(0, |acc, b| acc | (1 << b))
    }

    fn set_bits(flags: &mut [bool], word: usize, v: u32, to: bool) {
        for b in 0..32 {
            if v & (1 << b) != 0 {
                if let Some(f) = flags.get_mut(word * 32 + b) {
                    *f = to;
                }
            }
        }
    }

    /// SysTick's clock: the core clock (CLKSOURCE = 1) or the core clock / 8.
    fn syst_div(&self) -> u64 {
        if self.syst_csr & 4 != 0 {
            1
        } else {
            8
        }
    }

    /// The core cycle at which SysTick next reaches zero (`None`: off or no reload).
    pub fn systick_next(&self, now: u64) -> Option<u64> {
        if self.syst_csr & 1 == 0 || self.syst_rvr == 0 {
            return None;
        }
        let period = (u64::from(self.syst_rvr) + 1) * self.syst_div();
        let el = now.saturating_sub(self.syst_base);
        Some(self.syst_base + (el / period + 1) * period)
    }

    /// SysTick up to `now`: COUNTFLAG, and the exception pended when TICKINT.
    pub fn systick_sync(&mut self, now: u64) {
        if let Some(t) = self.systick_next(self.syst_last.max(self.syst_base)) {
            if t <= now {
                self.syst_csr |= 1 << 16;
                if self.syst_csr & 2 != 0 {
                    self.systick_pending = true;
                }
            }
        }
        self.syst_last = now;
    }

    /// A 32-bit read at `addr` (0xE000_0000-based), at core cycle `now`.
    pub fn read(&mut self, addr: u32, now: u64) -> Result<u32, Unmodelled> {
        Ok(match addr {
            0xE000_1000 => self.dwt_ctrl,
            0xE000_1004 => self.cyccnt(now),
            0xE000_E004 => 0, // ICTR
            0xE000_E010 => {
                let v = self.syst_csr;
                self.syst_csr &= !(1 << 16);
                v
            }
            0xE000_E014 => self.syst_rvr,
            0xE000_E018 => {
                let reload = u64::from(self.syst_rvr) + 1;
                let el = (now.saturating_sub(self.syst_base) / self.syst_div()) % reload;
                (reload - 1 - el) as u32
            }
            0xE000_E01C => 0x4000_0000 | 20_999, // CALIB: no reference, 21 MHz·1 ms
            0xE000_E100..=0xE000_E108 => {
                Self::bits(&self.enabled, ((addr - 0xE000_E100) / 4) as usize)
            }
            0xE000_E180..=0xE000_E188 => {
                Self::bits(&self.enabled, ((addr - 0xE000_E180) / 4) as usize)
            }
            0xE000_E200..=0xE000_E208 => {
                Self::bits(&self.pending, ((addr - 0xE000_E200) / 4) as usize)
            }
            0xE000_E280..=0xE000_E288 => {
                Self::bits(&self.pending, ((addr - 0xE000_E280) / 4) as usize)
            }
            0xE000_E300..=0xE000_E308 => {
                let w = ((addr - 0xE000_E300) / 4) as usize;
                let mut act = [false; IRQS];
                for &e in &self.active {
                    if e >= 16 {
                        if let Some(a) = act.get_mut(usize::from(e) - 16) {
                            *a = true;
                        }
                    }
                }
                Self::bits(&act, w)
            }
            0xE000_E400..=0xE000_E450 => {
                let b = (addr - 0xE000_E400) as usize;
                (0..4).fold(0, |acc, k| {
                    acc | u32::from(self.ipr.get(b + k).copied().unwrap_or(0)) << (8 * k)
                })
            }
            0xE000_ED00 => 0x410F_C241, // CPUID: Cortex-M4 r0p1
            0xE000_ED04 => {
                let vectactive = u32::from(self.active.last().copied().unwrap_or(0));
                let pend = self.takeable(256).map_or(0, u32::from);
                vectactive
                    | (pend << 12)
                    | if self.any_pending() { 1 << 22 } else { 0 }
                    | if self.systick_pending { 1 << 26 } else { 0 }
                    | if self.pendsv { 1 << 28 } else { 0 }
            }
            0xE000_ED08 => self.vtor,
            0xE000_ED0C => 0xFA05_0000 | (self.prigroup << 8),
            0xE000_ED10 => self.scr,
            0xE000_ED14 => self.ccr,
            0xE000_ED18..=0xE000_ED20 => {
                let b = (addr - 0xE000_ED18) as usize;
                (0..4).fold(0, |acc, k| acc | u32::from(self.shpr[b + k]) << (8 * k))
            }
            0xE000_ED24 => self.fault_regs[0],
            0xE000_ED28 => self.fault_regs[1],
            0xE000_ED2C => self.fault_regs[2],
            0xE000_ED34 => self.fault_regs[3],
            0xE000_ED38 => self.fault_regs[4],
            0xE000_ED88 => self.cpacr,
            0xE000_EDF0 => 0, // DHCSR: no debugger attached
            0xE000_EDFC => self.demcr,
            0xE000_EF34 => self.fpccr,
            0xE000_EF38 => self.fpcar,
            0xE000_EF3C => self.fpdscr,
            0xE004_2000 => 0x1000_6413, // DBGMCU_IDCODE: STM32F407, rev A
            0xE004_2004 => self.dbgmcu[0],
            0xE004_2008 => self.dbgmcu[1],
            0xE004_200C => self.dbgmcu[2],
            _ => return Err(Unmodelled),
        })
    }

    /// A 32-bit write (byte writes to the priority registers come as `mask`ed words).
    pub fn write(&mut self, addr: u32, v: u32, mask: u32, now: u64) -> Result<(), Unmodelled> {
        let merge = |old: u32| (old & !mask) | (v & mask);
        match addr {
            0xE000_1000 => {
                let was = self.cyccnt_running();
                let c = self.cyccnt(now);
                self.dwt_ctrl = merge(self.dwt_ctrl);
                if was != self.cyccnt_running() {
                    self.cyccnt_base = c;
                    self.cyccnt_base_cycle = now;
                }
            }
            0xE000_1004 => {
                self.cyccnt_base = merge(self.cyccnt(now));
                self.cyccnt_base_cycle = now;
            }
            0xE000_E010 => {
                let was_on = self.syst_csr & 1 != 0;
                self.syst_csr = (self.syst_csr & (1 << 16)) | (merge(self.syst_csr) & 0x7);
                if !was_on && self.syst_csr & 1 != 0 {
                    self.syst_base = now;
                    self.syst_last = now;
                }
            }
            0xE000_E014 => self.syst_rvr = merge(self.syst_rvr) & 0x00FF_FFFF,
            0xE000_E018 => {
                self.syst_base = now;
                self.syst_last = now;
                self.syst_csr &= !(1 << 16);
            }
            0xE000_E100..=0xE000_E108 => Self::set_bits(
                &mut self.enabled,
                ((addr - 0xE000_E100) / 4) as usize,
                v & mask,
                true,
            ),
            0xE000_E180..=0xE000_E188 => Self::set_bits(
                &mut self.enabled,
                ((addr - 0xE000_E180) / 4) as usize,
                v & mask,
                false,
            ),
            0xE000_E200..=0xE000_E208 => Self::set_bits(
                &mut self.pending,
                ((addr - 0xE000_E200) / 4) as usize,
                v & mask,
                true,
            ),
            0xE000_E280..=0xE000_E288 => Self::set_bits(
                &mut self.pending,
                ((addr - 0xE000_E280) / 4) as usize,
                v & mask,
                false,
            ),
            0xE000_E400..=0xE000_E450 => {
                let b = (addr - 0xE000_E400) as usize;
                for k in 0..4 {
                    if mask & (0xFF << (8 * k)) != 0 {
                        if let Some(p) = self.ipr.get_mut(b + k) {
                            *p = (v >> (8 * k)) as u8 & 0xF0;
                        }
                    }
                }
            }
            0xE000_EF00 => {
                if let Some(p) = self.pending.get_mut((v & 0x1FF) as usize) {
                    *p = true;
                }
            }
            0xE000_ED04 => {
                if v & (1 << 28) != 0 {
                    self.pendsv = true;
                }
                if v & (1 << 27) != 0 {
                    self.pendsv = false;
                }
                if v & (1 << 26) != 0 {
                    self.systick_pending = true;
                }
                if v & (1 << 25) != 0 {
                    self.systick_pending = false;
                }
            }
            0xE000_ED08 => self.vtor = merge(self.vtor) & 0xFFFF_FF80,
            0xE000_ED0C => {
                if v >> 16 == 0x05FA {
                    self.prigroup = (v >> 8) & 7;
                    if v & 4 != 0 {
                        self.reset_request = true;
                    }
                }
            }
            0xE000_ED10 => self.scr = merge(self.scr),
            0xE000_ED14 => self.ccr = merge(self.ccr),
            0xE000_ED18..=0xE000_ED20 => {
                let b = (addr - 0xE000_ED18) as usize;
                for k in 0..4 {
                    if mask & (0xFF << (8 * k)) != 0 {
                        self.shpr[b + k] = (v >> (8 * k)) as u8 & 0xF0;
                    }
                }
            }
            0xE000_ED24 => self.fault_regs[0] = merge(self.fault_regs[0]),
            0xE000_ED28 => self.fault_regs[1] &= !(v & mask),
            0xE000_ED2C => self.fault_regs[2] &= !(v & mask),
            0xE000_ED88 => self.cpacr = merge(self.cpacr),
            0xE000_EDFC => {
                let c = self.cyccnt(now);
                let was = self.cyccnt_running();
                self.demcr = merge(self.demcr);
                if was != self.cyccnt_running() {
                    self.cyccnt_base = c;
                    self.cyccnt_base_cycle = now;
                }
            }
            0xE000_EF34 => self.fpccr = merge(self.fpccr),
            0xE000_EF38 => self.fpcar = merge(self.fpcar),
            0xE000_EF3C => self.fpdscr = merge(self.fpdscr),
            0xE004_2004 => self.dbgmcu[0] = merge(self.dbgmcu[0]),
            0xE004_2008 => self.dbgmcu[1] = merge(self.dbgmcu[1]),
            0xE004_200C => self.dbgmcu[2] = merge(self.dbgmcu[2]),
            _ => return Err(Unmodelled),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn priorities_masks_and_pending_while_masked() {
        let mut s = Scs::default();
        s.write(0xE000_E100 + 4, 1 << (irq::TIM7 - 32), u32::MAX, 0)
            .unwrap(); // ISER1
                       // TIM7 at priority 0, USART6 at 0x30 (IPR byte 71, written as a byte lane).
        s.write(0xE000_E400 + 68, 0x30 << 24, 0xFF << 24, 0)
            .unwrap();
        assert_eq!(s.ipr[irq::USART6], 0x30);
        s.enabled[irq::USART6] = true;
        let mut lv = [false; IRQS];
        lv[irq::USART6] = true;
        lv[irq::TIM7] = true;
        s.raise(&lv);
        assert_eq!(
            s.takeable(s.execution_priority(true, 0)),
            None,
            "PRIMASK masks both"
        );
        assert!(s.any_pending(), "still pending while masked");
        assert_eq!(
            s.takeable(s.execution_priority(false, 0x20)),
            Some(16 + irq::TIM7 as u16),
            "BASEPRI 0x20 lets 0 through"
        );
        s.enter(16 + irq::TIM7 as u16);
        assert_eq!(
            s.takeable(s.execution_priority(false, 0)),
            None,
            "0x30 does not preempt 0"
        );
        s.leave(16 + irq::TIM7 as u16, &[false; IRQS]);
        assert_eq!(
            s.takeable(s.execution_priority(false, 0)),
            Some(16 + irq::USART6 as u16),
            "tail-chained next"
        );
        s.enter(16 + irq::USART6 as u16);
        s.leave(16 + irq::USART6 as u16, &lv);
        assert!(s.pending[irq::USART6], "a line still high pends again");
    }

    #[test]
    fn unmodelled_system_registers_are_refused() {
        let mut s = Scs::default();
        assert_eq!(s.read(0xE000_ED40, 0), Err(Unmodelled));
        assert_eq!(s.write(0xE000_0000, 0, u32::MAX, 0), Err(Unmodelled));
    }
}
