//! The emulated STM32F407: unicorn's Cortex-M4 core, the memory map, the exception model
//! unicorn leaves out (entry with the basic or the FPU's extended frame, EXC_RETURN,
//! tail-chaining, priorities and masks), sleep, the cycle model, resets and power cuts.
//!
//! **Cycle model.** Every executed instruction costs one core cycle; with the flash
//! accelerator off (FLASH_ACR without both ICEN and PRFTEN) each 16-byte flash line a
//! translation block spans costs FLASH_ACR.LATENCY more (the wait states of an
//! uncached fetch). Load/store and branch penalties are not modelled: the cycle count
//! is a lower bound, compared with bench-m4's per-class estimate in docs/results.md,
//! "Firmware in the loop". Time is
//! that count at 168 MHz; WFI/WFE (and polling a busy flash) skip to the next event.
//! Nothing depends on the host's clock: the same ELF and inputs give the same run.
//!
//! **Interrupts.** A pending, enabled interrupt is taken at the next translation-block
//! boundary at which its priority beats the execution priority (active exceptions,
//! BASEPRI, PRIMASK). Tail-chaining is modelled as return-then-entry (same order, no
//! saved cycles).

use crate::bus::{Bus, Environment, SYSCLK_HZ};
use crate::dma::MemAction;
use crate::elf::Image;
use crate::flash::{Flash, BASE as FLASH_BASE};
use anyhow::{anyhow, bail, Result};
use std::collections::HashMap;
use std::rc::Rc;
use unicorn_engine::{Arch, Mode, Prot, RegisterARM, Unicorn};

/// SRAM1+2.
pub const RAM: (u32, u32) = (0x2000_0000, 128 * 1024);
/// CCM data RAM.
pub const CCM: (u32, u32) = (0x1000_0000, 64 * 1024);
/// The word painted over RAM at power-on (the stack high-water mark is the lowest
/// overwritten word).
pub const PAINT: u32 = 0xC0DE_5AFE;
/// Exception number of TIM7 (the tick).
pub const TIM7_EXC: u16 = 16 + crate::scs::irq::TIM7 as u16;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sleep {
    Wfi,
    Wfe,
}

/// Counters of a run.
#[derive(Debug, Clone, Default)]
pub struct Stats {
    /// Exceptions taken, by number.
    pub taken: HashMap<u16, u64>,
    /// TIM7 handler durations, core cycles: count, sum, max.
    pub tick_cycles: (u64, u64, u64),
    /// TIM7 handler instructions: sum, max.
    pub tick_instructions: (u64, u64),
    /// Core cycle of the first TIM7 entry since the last reset (the boot time).
    pub first_tick: Option<u64>,
    /// Resets by the watchdog.
    pub watchdog_resets: u32,
    /// Resets by SYSRESETREQ.
    pub software_resets: u32,
    /// Instructions executed.
    pub instructions: u64,
    /// Exception entries that stacked the FPU's extended frame (CONTROL.FPCA set).
    pub extended_frames: u64,
}

/// The emulator's state, shared with unicorn's callbacks.
pub struct State {
    /// The peripherals.
    pub bus: Bus,
    /// Core cycles since power-on.
    pub cycles: u64,
    stop_at: u64,
    irq_watch: bool,
    /// Why the run stopped with an error.
    pub error: Option<String>,
    sleeping: Option<Sleep>,
    event: bool,
    block_cost: HashMap<(u32, u32), (u32, u32)>,
    image: Rc<Image>,
    last_block: u32,
    tick_entry: Option<(u64, u64)>,
    /// Counters.
    pub stats: Stats,
    /// Raw defmt bytes read from the RTT up-buffer.
    pub rtt: Vec<u8>,
    /// Fault injection: the next TIM7 handler hangs (cleared by a reset).
    pub stall_tick: bool,
}

/// A `b .` (branch to itself) in system memory, the target of [`State::stall_tick`].
const STALL_LOOP: u32 = 0x1FFF_0000;

/// The board.
pub struct Machine {
    /// unicorn.
    pub uc: Unicorn<'static, State>,
    image: Rc<Image>,
}

fn reg(uc: &Unicorn<'_, State>, r: RegisterARM) -> u32 {
    uc.reg_read(r).unwrap_or(0) as u32
}

fn set(uc: &mut Unicorn<'_, State>, r: RegisterARM, v: u32) {
    let _ = uc.reg_write(r, u64::from(v));
}

fn rd32(uc: &Unicorn<'_, State>, a: u32) -> Result<u32> {
    let mut b = [0u8; 4];
    uc.mem_read(u64::from(a), &mut b)
        .map_err(|e| anyhow!("read {a:#010x}: {e:?}"))?;
    Ok(u32::from_le_bytes(b))
}

fn wr32(uc: &mut Unicorn<'_, State>, a: u32, v: u32) -> Result<()> {
    uc.mem_write(u64::from(a), &v.to_le_bytes())
        .map_err(|e| anyhow!("write {a:#010x}: {e:?}"))
}

/// Thumb instructions in `code` (a 32-bit instruction starts with 0b11101/11110/11111).
fn count_instructions(code: &[u8]) -> u32 {
    let mut i = 0;
    let mut n = 0;
    while i + 1 < code.len() {
        let hw = u16::from_le_bytes([code[i], code[i + 1]]);
        i += if hw >> 11 >= 0x1D { 4 } else { 2 };
        n += 1;
    }
    n
}

const FRAME_REGS: [RegisterARM; 6] = [
    RegisterARM::R0,
    RegisterARM::R1,
    RegisterARM::R2,
    RegisterARM::R3,
    RegisterARM::R12,
    RegisterARM::LR,
];

fn fp_reg(k: usize) -> RegisterARM {
    use RegisterARM::*;
    [
        S0, S1, S2, S3, S4, S5, S6, S7, S8, S9, S10, S11, S12, S13, S14, S15,
    ][k]
}

impl State {
    fn apply_actions(uc: &mut Unicorn<'_, State>) {
        let acts = std::mem::take(&mut uc.get_data_mut().bus.actions);
        for a in acts {
            match a {
                MemAction::Write(addr, bytes) => {
                    if uc.mem_write(u64::from(addr), &bytes).is_err() {
                        let st = uc.get_data_mut();
                        st.error = Some(format!("DMA write to unmapped {addr:#010x}"));
                    }
                }
                MemAction::Snapshot {
                    ctrl,
                    stream,
                    addr,
                    len,
                } => {
                    let data = uc
                        .mem_read_as_vec(u64::from(addr), len as usize)
                        .unwrap_or_default();
                    uc.get_data_mut().bus.dma[ctrl].streams[stream].tx_data = data;
                }
            }
        }
        let st = uc.get_data_mut();
        st.cycles += std::mem::take(&mut st.bus.stall);
        st.irq_watch = st.bus.scs.any_pending();
    }

    fn unmodelled(&mut self, what: &str, addr: u32) {
        if self.error.is_none() {
            self.error = Some(format!(
                "{what} of unmodelled register {addr:#010x} in {}",
                self.image.symbolize(self.last_block)
            ));
        }
    }
}

impl Machine {
    /// A board with `flash` (its code sectors get the image), cold (RAM painted), with the
    /// reset flags `csr_flags` (power-on: POR + PIN + BOR).
    pub fn new(image: Rc<Image>, mut flash: Flash, env: Box<dyn Environment>) -> Result<Self> {
        flash.reset_registers();
        for (addr, data) in &image.segments {
            let off = addr.wrapping_sub(FLASH_BASE) as usize;
            if off + data.len() > 0xC_0000 {
                bail!("segment at {addr:#010x} is not in the code sectors 0-9");
            }
            flash.mem[off..off + data.len()].copy_from_slice(data);
        }
        let csr =
            crate::clocks::csr::PORRSTF | crate::clocks::csr::PINRSTF | crate::clocks::csr::BORRSTF;
        let state = State {
            bus: Bus::new(flash, csr, env),
            cycles: 0,
            stop_at: 0,
            irq_watch: false,
            error: None,
            sleeping: None,
            event: false,
            block_cost: HashMap::new(),
            image: image.clone(),
            last_block: 0,
            tick_entry: None,
            stats: Stats::default(),
            rtt: Vec::new(),
            stall_tick: false,
        };
        let mut uc = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, state)
            .map_err(|e| anyhow!("unicorn: {e:?}"))?;
        uc.ctl_set_cpu_model(unicorn_engine::ArmCpuModel::CORTEX_M4 as i32)
            .map_err(|e| anyhow!("cpu model: {e:?}"))?;
        let map = |uc: &mut Unicorn<'static, State>, a: u32, n: u32| {
            uc.mem_map(u64::from(a), u64::from(n), Prot::ALL)
                .map_err(|e| anyhow!("map {a:#x}: {e:?}"))
        };
        // Code sectors 0-9 as memory (the CPU fetches there); sectors 10/11 through the
        // flash model.
        map(&mut uc, FLASH_BASE, 0xC_0000)?;
        let code = uc.get_data().bus.flash.mem[..0xC_0000].to_vec();
        uc.mem_write(u64::from(FLASH_BASE), &code)
            .map_err(|e| anyhow!("load: {e:?}"))?;
        map(&mut uc, RAM.0, RAM.1)?;
        map(&mut uc, CCM.0, CCM.1)?;
        // System memory: the unique ID and the flash size (1024 KiB) registers.
        map(&mut uc, 0x1FFF_0000, 0x8000)?;
        uc.mem_write(0x1FFF_7A22, &1024u16.to_le_bytes())
            .map_err(|e| anyhow!("{e:?}"))?;
        uc.mem_write(u64::from(STALL_LOOP), &[0xFE, 0xE7])
            .map_err(|e| anyhow!("{e:?}"))?;
        let paint: Vec<u8> = std::iter::repeat_n(PAINT.to_le_bytes(), (RAM.1 / 4) as usize)
            .flatten()
            .collect();
        uc.mem_write(u64::from(RAM.0), &paint)
            .map_err(|e| anyhow!("{e:?}"))?;
        let mut m = Self { uc, image };
        m.map_peripherals()?;
        m.hooks()?;
        m.reset_cpu()?;
        Ok(m)
    }

    fn map_peripherals(&mut self) -> Result<()> {
        for (base, size) in [
            (0x080C_0000u32, 0x4_0000u32),
            (0x4000_0000, 0x8_0000),
            (0x5000_0000, 0x6_1000),
            (0xE000_0000, 0x10_0000),
        ] {
            self.uc
                .mmio_map(
                    u64::from(base),
                    u64::from(size),
                    Some(
                        move |uc: &mut Unicorn<'_, State>, off: u64, sz: usize| -> u64 {
                            let addr = base + off as u32;
                            let st = uc.get_data_mut();
                            let now = st.cycles;
                            let r = st.bus.read(addr, sz, now);
                            match r {
                                Ok(v) => {
                                    State::apply_actions(uc);
                                    u64::from(v)
                                }
                                Err(_) => {
                                    st.unmodelled("read", addr);
                                    let _ = uc.emu_stop();
                                    0
                                }
                            }
                        },
                    ),
                    Some(
                        move |uc: &mut Unicorn<'_, State>, off: u64, sz: usize, v: u64| {
                            let addr = base + off as u32;
                            let st = uc.get_data_mut();
                            let now = st.cycles;
                            match st.bus.write(addr, sz, v as u32, now) {
                                Ok(()) => State::apply_actions(uc),
                                Err(_) => {
                                    st.unmodelled("write", addr);
                                    let _ = uc.emu_stop();
                                }
                            }
                        },
                    ),
                )
                .map_err(|e| anyhow!("mmio {base:#x}: {e:?}"))?;
        }
        Ok(())
    }

    fn hooks(&mut self) -> Result<()> {
        let code = self.uc.get_data().bus.flash.mem[..0xC_0000].to_vec();
        self.uc
            .add_block_hook(1, 0, move |uc, addr, size| {
                let a = addr as u32;
                let st = uc.get_data_mut();
                let acr = st.bus.flash.acr();
                let key = (a, size);
                let (n, lines) = *st.block_cost.entry(key).or_insert_with(|| {
                    let off = a.wrapping_sub(FLASH_BASE) as usize;
                    let n = code
                        .get(off..off + size as usize)
                        .map_or(size / 2, count_instructions);
                    let in_flash = off < code.len();
                    let lines = if in_flash {
                        (a + size).div_ceil(16) - a / 16
                    } else {
                        0
                    };
                    (n, lines)
                });
                let art = acr & (1 << 9) != 0 && acr & (1 << 8) != 0;
                let ws = if art {
                    0
                } else {
                    u64::from(lines) * u64::from(acr & 0xF)
                };
                st.cycles += u64::from(n) + ws;
                st.stats.instructions += u64::from(n);
                st.last_block = a;
                if st.cycles >= st.stop_at {
                    let _ = uc.emu_stop();
                    return;
                }
                if st.irq_watch {
                    let pm = reg(uc, RegisterARM::PRIMASK) & 1 != 0;
                    let bp = reg(uc, RegisterARM::BASEPRI);
                    let st = uc.get_data();
                    let prio = st.bus.scs.execution_priority(pm, bp);
                    if st.bus.scs.takeable(prio).is_some() {
                        let _ = uc.emu_stop();
                    }
                }
            })
            .map_err(|e| anyhow!("block hook: {e:?}"))?;
        // WFI / WFE / SEV: every halfword 0xBF30 / 0xBF20 / 0xBF40 in the code gets a hook
        // (one that is not an instruction start never fires).
        let code = self.uc.get_data().bus.flash.mem[..0xC_0000].to_vec();
        let mut n_hooks = 0;
        for i in (0..code.len() - 1).step_by(2) {
            let hw = u16::from_le_bytes([code[i], code[i + 1]]);
            let addr = u64::from(FLASH_BASE) + i as u64;
            let kind = match hw {
                0xBF30 => Sleep::Wfi,
                0xBF20 => Sleep::Wfe,
                0xBF40 => {
                    self.uc
                        .add_code_hook(addr, addr, |uc, _, _| uc.get_data_mut().event = true)
                        .map_err(|e| anyhow!("{e:?}"))?;
                    continue;
                }
                _ => continue,
            };
            n_hooks += 1;
            self.uc
                .add_code_hook(addr, addr, move |uc, a, _| {
                    let st = uc.get_data_mut();
                    let sleep = match kind {
                        Sleep::Wfe if st.event => {
                            st.event = false;
                            false
                        }
                        Sleep::Wfi => !st.bus.scs.any_pending(),
                        Sleep::Wfe => true,
                    };
                    let _ = uc.reg_write(RegisterARM::PC, (a + 2) | 1);
                    if sleep {
                        uc.get_data_mut().sleeping = Some(kind);
                        let _ = uc.emu_stop();
                    }
                })
                .map_err(|e| anyhow!("{e:?}"))?;
        }
        let _ = n_hooks;
        // Exception return (EXCP_EXCEPTION_EXIT) and the CPU's own faults.
        self.uc
            .add_intr_hook(|uc, intno| {
                let r = match intno {
                    8 => exception_return(uc),
                    // BKPT without a debugger, prefetch/data aborts: HardFault (the
                    // configurable faults are disabled at reset and escalate).
                    3 | 4 | 7 => {
                        let pc = reg(uc, RegisterARM::PC);
                        // HFSR: DEBUGEVT for BKPT, FORCED otherwise.
                        uc.get_data_mut().bus.scs.fault_regs[2] |=
                            if intno == 7 { 1 << 31 } else { 1 << 30 };
                        if uc.get_data().bus.scs.active.contains(&3) {
                            Err(anyhow!(
                                "lockup: fault {intno} inside HardFault at {pc:#010x}"
                            ))
                        } else {
                            exception_entry(uc, 3, pc)
                        }
                    }
                    n => Err(anyhow!("CPU exception {n}")),
                };
                if let Err(e) = r {
                    let st = uc.get_data_mut();
                    if st.error.is_none() {
                        st.error = Some(format!("{e} (in {})", st.image.symbolize(st.last_block)));
                    }
                    let _ = uc.emu_stop();
                }
            })
            .map_err(|e| anyhow!("intr hook: {e:?}"))?;
        // UDF and invalid instructions (unicorn routes them here, not to the interrupt
        // hook): UsageFault, disabled at reset, escalates to HardFault.
        self.uc
            .add_insn_invalid_hook(|uc| {
                let pc = reg(uc, RegisterARM::PC);
                uc.get_data_mut().bus.scs.fault_regs[2] |= 1 << 30; // HFSR.FORCED
                let r = if uc.get_data().bus.scs.active.contains(&3) {
                    Err(anyhow!(
                        "lockup: invalid instruction inside HardFault at {pc:#010x}"
                    ))
                } else {
                    exception_entry(uc, 3, pc)
                };
                match r {
                    Ok(()) => true,
                    Err(e) => {
                        let st = uc.get_data_mut();
                        if st.error.is_none() {
                            st.error =
                                Some(format!("{e} (in {})", st.image.symbolize(st.last_block)));
                        }
                        let _ = uc.emu_stop();
                        false
                    }
                }
            })
            .map_err(|e| anyhow!("invalid-instruction hook: {e:?}"))?;
        // Writes to the code sectors are a firmware bug (it stores tables in 10/11 only).
        self.uc
            .add_mem_hook(
                unicorn_engine::HookType::MEM_WRITE,
                u64::from(FLASH_BASE),
                u64::from(FLASH_BASE + 0xC_0000 - 1),
                |uc, _, addr, _, _| {
                    let st = uc.get_data_mut();
                    st.error = Some(format!(
                        "write to code flash {addr:#010x} in {}",
                        st.image.symbolize(st.last_block)
                    ));
                    let _ = uc.emu_stop();
                    true
                },
            )
            .map_err(|e| anyhow!("{e:?}"))?;
        Ok(())
    }

    /// CPU reset: MSP and PC from the vector table, registers and SCS at reset values.
    fn reset_cpu(&mut self) -> Result<()> {
        let sp = rd32(&self.uc, FLASH_BASE)?;
        let pc = rd32(&self.uc, FLASH_BASE + 4)?;
        for r in [
            RegisterARM::R0,
            RegisterARM::R1,
            RegisterARM::R2,
            RegisterARM::R3,
            RegisterARM::R4,
            RegisterARM::R5,
            RegisterARM::R6,
            RegisterARM::R7,
            RegisterARM::R8,
            RegisterARM::R9,
            RegisterARM::R10,
            RegisterARM::R11,
            RegisterARM::R12,
        ] {
            set(&mut self.uc, r, 0);
        }
        set(&mut self.uc, RegisterARM::CONTROL, 0);
        set(&mut self.uc, RegisterARM::PRIMASK, 0);
        set(&mut self.uc, RegisterARM::BASEPRI, 0);
        set(&mut self.uc, RegisterARM::IPSR, 0);
        set(&mut self.uc, RegisterARM::SP, sp);
        set(&mut self.uc, RegisterARM::LR, 0xFFFF_FFFF);
        set(&mut self.uc, RegisterARM::PC, pc | 1);
        let st = self.uc.get_data_mut();
        st.sleeping = None;
        st.event = false;
        st.tick_entry = None;
        Ok(())
    }

    /// A system reset (watchdog or SYSRESETREQ): peripherals at reset, RAM kept, the
    /// reset flags set.
    pub fn reset(&mut self, flags: u32) -> Result<()> {
        let st = self.uc.get_data_mut();
        let now = st.cycles;
        st.bus.flash.power_cut(now); // an operation in progress is cut
        let mut flash = std::mem::take(&mut st.bus.flash);
        flash.reset_registers();
        let env = std::mem::replace(
            &mut st.bus.env,
            Box::new(crate::bus::Still(Default::default())),
        );
        let keep = st.bus.clocks.reset_flags();
        let tick_io = st.bus.tick_io.take();
        st.bus = Bus::new(flash, keep | flags | crate::clocks::csr::PINRSTF, env);
        st.bus.tick_io = tick_io;
        st.stall_tick = false;
        st.stats.first_tick = None;
        st.bus.sync(now);
        self.reset_cpu()
    }

    /// The image.
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// The state.
    pub fn state(&self) -> &State {
        self.uc.get_data()
    }

    /// The state, mutably.
    pub fn state_mut(&mut self) -> &mut State {
        self.uc.get_data_mut()
    }

    /// Core cycles since power-on.
    pub fn cycles(&self) -> u64 {
        self.state().cycles
    }

    /// Emulated seconds since power-on.
    pub fn seconds(&self) -> f64 {
        self.cycles() as f64 / SYSCLK_HZ as f64
    }

    /// Runs until core cycle `until` (or an error).
    pub fn run_until(&mut self, until: u64) -> Result<()> {
        loop {
            if let Some(e) = self.state().error.clone() {
                bail!("{e}");
            }
            self.poll_rtt();
            let now = self.cycles();
            if now >= until {
                return Ok(());
            }
            {
                let st = self.state_mut();
                st.bus.sync(now);
                State::apply_actions(&mut self.uc);
            }
            // Watchdog and reset requests.
            let st = self.state_mut();
            if st.bus.iwdg.deadline.is_some_and(|d| d <= now) {
                st.stats.watchdog_resets += 1;
                self.reset(crate::clocks::csr::IWDGRSTF)?;
                continue;
            }
            if st.bus.scs.reset_request {
                st.stats.software_resets += 1;
                self.reset(crate::clocks::csr::SFTRSTF)?;
                continue;
            }
            // Interrupts.
            let pm = reg(&self.uc, RegisterARM::PRIMASK) & 1 != 0;
            let bp = reg(&self.uc, RegisterARM::BASEPRI);
            let st = self.state();
            let prio = st.bus.scs.execution_priority(pm, bp);
            let take = st.bus.scs.takeable(prio);
            let woken = match st.sleeping {
                None => true,
                Some(Sleep::Wfi) => st.bus.scs.any_pending() || take.is_some(),
                Some(Sleep::Wfe) => st.event || take.is_some() || st.bus.scs.event,
            };
            if let Some(exc) = take {
                let pc = reg(&self.uc, RegisterARM::PC);
                self.state_mut().sleeping = None;
                exception_entry(&mut self.uc, exc, pc)?;
                continue;
            }
            let next = self
                .state()
                .bus
                .next_event(now)
                .unwrap_or(u64::MAX)
                .min(until);
            if !woken {
                // Asleep: time passes to the next event.
                self.state_mut().cycles = next.max(now + 1);
                continue;
            }
            {
                let st = self.state_mut();
                if st.sleeping == Some(Sleep::Wfe) {
                    st.event = false;
                    st.bus.scs.event = false;
                }
                st.sleeping = None;
                st.stop_at = next.max(now + 1);
                st.irq_watch = st.bus.scs.any_pending();
            }
            let pc = reg(&self.uc, RegisterARM::PC);
            if let Err(e) = self.uc.emu_start(u64::from(pc | 1), 0, 0, 0) {
                let st = self.state();
                let msg = st.error.clone().unwrap_or_else(|| {
                    format!(
                        "{e:?} at {} (pc {:#010x})",
                        st.image.symbolize(st.last_block),
                        pc
                    )
                });
                self.state_mut().error = Some(msg);
            }
        }
    }

    /// Runs for `seconds` of emulated time.
    pub fn run_for(&mut self, seconds: f64) -> Result<()> {
        let until = self.cycles() + (seconds * SYSCLK_HZ as f64) as u64;
        self.run_until(until)
    }

    /// Reads new bytes from the defmt RTT up-buffer 0.
    pub fn poll_rtt(&mut self) {
        let Some(cb) = self.image.rtt else { return };
        let Ok(buf) = rd32(&self.uc, cb + 28) else {
            return;
        };
        let (Ok(size), Ok(w), Ok(r)) = (
            rd32(&self.uc, cb + 32),
            rd32(&self.uc, cb + 36),
            rd32(&self.uc, cb + 40),
        ) else {
            return;
        };
        if w == r || size == 0 || w >= size || r >= size {
            return;
        }
        let mut out = Vec::new();
        let mut pos = r;
        while pos != w {
            let end = if w > pos { w } else { size };
            if let Ok(v) = self
                .uc
                .mem_read_as_vec(u64::from(buf + pos), (end - pos) as usize)
            {
                out.extend_from_slice(&v);
            }
            pos = if end == size { 0 } else { end };
        }
        let _ = wr32(&mut self.uc, cb + 40, w);
        self.state_mut().rtt.extend_from_slice(&out);
    }

    /// The lowest stack address written since power-on (the painted RAM's first
    /// overwritten word above the stack's bottom), and the free bytes below it.
    pub fn stack_min_free(&self) -> u32 {
        let (bottom, top) = self.image.stack;
        let mut a = bottom.max(RAM.0);
        while a < top {
            match rd32(&self.uc, a) {
                Ok(PAINT) => a += 4,
                _ => break,
            }
        }
        a - bottom.max(RAM.0)
    }

    /// Cuts the power now: a flash operation in progress is left half done. Returns the
    /// flash for the next power-on.
    pub fn power_cut(mut self) -> Flash {
        let now = self.cycles();
        let st = self.state_mut();
        st.bus.flash.power_cut(now);
        std::mem::take(&mut st.bus.flash)
    }
}

/// unicorn's IPSR write does not refresh QEMU's cached translation flags (handler mode
/// decides whether `bx lr` with EXC_RETURN is an exception return); writing APSR.NZCV
/// does (`arm_rebuild_hflags`). Called after every IPSR change.
fn refresh_mode(uc: &mut Unicorn<'_, State>) {
    let nzcv = reg(uc, RegisterARM::APSR) & 0xF000_0000;
    set(uc, RegisterARM::APSR_NZCV, nzcv);
}

/// Exception entry (ARMv7-M B1.5.6): the frame pushed on MSP (the FPU's extended frame
/// when CONTROL.FPCA), LR = EXC_RETURN, IPSR = `exc`, PC = its vector.
fn exception_entry(uc: &mut Unicorn<'_, State>, exc: u16, ret_pc: u32) -> Result<()> {
    let control = reg(uc, RegisterARM::CONTROL);
    if control & 2 != 0 {
        bail!("CONTROL.SPSEL (process stack) is not modelled");
    }
    let fpca = control & 4 != 0;
    let sp = reg(uc, RegisterARM::SP);
    let size = if fpca { 0x68 } else { 0x20 };
    let mut frame = sp.wrapping_sub(size);
    let pad = frame & 4 != 0;
    frame &= !7;
    let apsr = reg(uc, RegisterARM::APSR) & 0xF80F_0000;
    let ipsr = reg(uc, RegisterARM::IPSR) & 0x1FF;
    let epsr = reg(uc, RegisterARM::EPSR) & 0x0600_FC00;
    let xpsr = apsr | ipsr | epsr | (1 << 24) | if pad { 1 << 9 } else { 0 };
    for (k, r) in FRAME_REGS.iter().enumerate() {
        let v = reg(uc, *r);
        wr32(uc, frame + 4 * k as u32, v)?;
    }
    wr32(uc, frame + 24, ret_pc & !1)?;
    wr32(uc, frame + 28, xpsr)?;
    if fpca {
        for k in 0..16 {
            let v = reg(uc, fp_reg(k));
            wr32(uc, frame + 32 + 4 * k as u32, v)?;
        }
        let fpscr = reg(uc, RegisterARM::FPSCR);
        wr32(uc, frame + 96, fpscr)?;
    }
    let to_thread = ipsr == 0;
    let exc_return = 0xFFFF_FFE1 | if fpca { 0 } else { 0x10 } | if to_thread { 0x8 } else { 0 };
    let vtor = uc.get_data().bus.scs.vtor;
    let table = if vtor == 0 { FLASH_BASE } else { vtor };
    let vector = rd32(uc, table + 4 * u32::from(exc))?;
    set(uc, RegisterARM::SP, frame);
    set(uc, RegisterARM::LR, exc_return);
    set(uc, RegisterARM::IPSR, u32::from(exc));
    set(uc, RegisterARM::EPSR, 1 << 24);
    set(uc, RegisterARM::CONTROL, control & !4);
    refresh_mode(uc);
    set(uc, RegisterARM::PC, vector | 1);
    let st = uc.get_data_mut();
    st.bus.scs.enter(exc);
    st.event = true;
    *st.stats.taken.entry(exc).or_default() += 1;
    if fpca {
        st.stats.extended_frames += 1;
    }
    if exc == TIM7_EXC {
        st.tick_entry = Some((st.cycles, st.stats.instructions));
        st.stats.first_tick.get_or_insert(st.cycles);
        let at = st.cycles;
        if let Some(t) = st.bus.tick_io.as_mut() {
            t.push(crate::bus::TickIo {
                at,
                ..Default::default()
            });
        }
        if st.stall_tick {
            // Fault injection: the tick hangs (a branch-to-self in system memory, inside
            // the handler at priority 0): nothing feeds the watchdog any more.
            set(uc, RegisterARM::PC, STALL_LOOP | 1);
        }
    }
    Ok(())
}

/// Exception return (B1.5.8): EXC_RETURN in PC; the frame popped; a pending exception
/// that now preempts is taken at the next block.
fn exception_return(uc: &mut Unicorn<'_, State>) -> Result<()> {
    let excret = reg(uc, RegisterARM::PC) | 1;
    let exc = (reg(uc, RegisterARM::IPSR) & 0x1FF) as u16;
    if excret & 4 != 0 {
        bail!("EXC_RETURN {excret:#x} to the process stack is not modelled");
    }
    let frame = reg(uc, RegisterARM::SP);
    for (k, r) in FRAME_REGS.iter().enumerate() {
        let v = rd32(uc, frame + 4 * k as u32)?;
        set(uc, *r, v);
    }
    let pc = rd32(uc, frame + 24)?;
    let xpsr = rd32(uc, frame + 28)?;
    let extended = excret & 0x10 == 0;
    let mut size = 0x20;
    if extended {
        for k in 0..16 {
            let v = rd32(uc, frame + 32 + 4 * k as u32)?;
            set(uc, fp_reg(k), v);
        }
        let fpscr = rd32(uc, frame + 96)?;
        set(uc, RegisterARM::FPSCR, fpscr);
        size = 0x68;
    }
    if xpsr & (1 << 9) != 0 {
        size += 4;
    }
    set(uc, RegisterARM::SP, frame + size);
    set(uc, RegisterARM::APSR_NZCVQG, xpsr & 0xF80F_0000);
    set(uc, RegisterARM::IPSR, xpsr & 0x1FF);
    set(uc, RegisterARM::EPSR, xpsr & 0x0700_FC00);
    let control = reg(uc, RegisterARM::CONTROL);
    set(
        uc,
        RegisterARM::CONTROL,
        if extended { control | 4 } else { control & !4 },
    );
    set(uc, RegisterARM::PC, pc | 1);
    let st = uc.get_data_mut();
    let levels = st.bus.levels;
    st.bus.scs.leave(exc, &levels);
    st.irq_watch = st.bus.scs.any_pending();
    st.event = true;
    if exc == TIM7_EXC {
        if let Some((t0, i0)) = st.tick_entry.take() {
            let d = st.cycles - t0;
            let tc = &mut st.stats.tick_cycles;
            tc.0 += 1;
            tc.1 += d;
            tc.2 = tc.2.max(d);
            let di = st.stats.instructions - i0;
            let ti = &mut st.stats.tick_instructions;
            ti.0 += di;
            ti.1 = ti.1.max(di);
        }
    }
    Ok(())
}
