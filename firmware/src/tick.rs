//! The hard-period tick: TIM7's update interrupt at the highest priority, running
//! core's board tick ([`hydra_core::runtime::TickLoop::run`], the same entry point the
//! host's virtual board calls). This file is the glue: the DWT cycle counter as the
//! clock, TIM7's update flag as the period flag, the SPSC queues to the host link and
//! the independent watchdog ([`FwHost`]); the per-tick order of operations is core's.
//!
//! Deadline: the whole tick (encoder latch → runtime → valve write → watchdog feed) must
//! finish within one period (1 ms by default, down to 100 µs). Nothing else runs at
//! priority 0, so the only delay between the timer's update event and the first encoder
//! read is the interrupt entry (12 cycles) plus the longest critical section of the
//! lower-priority code (the single-core `critical-section` masks interrupts; embassy's
//! own sections are a few dozen cycles).

use core::cell::RefCell;
use critical_section::Mutex;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::TIM7;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::Peri;
use heapless::spsc::{Consumer, Producer};
#[cfg(not(feature = "console"))]
use hydra_core::runtime::State;
use hydra_core::runtime::{Runtime, TickHost, TickLoop};
use static_cell::StaticCell;

use crate::board::BoardIo;
use crate::consts::{PRESSURES, SLAVES, SYSCLK_HZ};
use crate::law_buffers::LawRef;
use crate::watchdog::{self, Timeout};

use crate::channels::{
    BoardCapture, BoardStatus, Reply, TickCommand, TickLinks, TickSample, COMMAND_MAX_AGE_US, REPLY,
};

/// The runtime as this board runs it: the law in one of the two static law buffers
/// (`crate::law_buffers`), so installing one swaps a reference.
pub type BoardRuntime = Runtime<LawRef, SLAVES, PRESSURES>;

/// The tick's glue: clock, period timer, queues, watchdog.
pub struct FwHost {
    timer: Timer<'static, TIM7>,
    cmd_rx: Consumer<'static, TickCommand>,
    reply_tx: Producer<'static, Reply>,
    status_tx: Producer<'static, BoardStatus>,
    sample_tx: Producer<'static, TickSample>,
    /// The loop-rate capture ring (`crate::capture`), recorded every tick.
    capture: BoardCapture,
}

impl TickHost<SLAVES, PRESSURES> for FwHost {
    #[inline(always)]
    fn now_cycles(&mut self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
    #[inline(always)]
    fn clear_period_flag(&mut self) {
        self.timer.clear_update_interrupt();
    }
    #[inline(always)]
    fn period_flag(&mut self) -> bool {
        self.timer.regs_core().sr().read().uif()
    }
    #[inline(always)]
    fn take_command(&mut self) -> Option<TickCommand> {
        self.cmd_rx.dequeue()
    }
    #[inline(always)]
    fn feed_watchdog(&mut self) {
        // The watchdog is fed here and nowhere else.
        watchdog::pet();
    }
    #[inline(always)]
    fn reply(&mut self, r: Reply) {
        REPLY.signal(r);
        // A full reply queue drops the reply; the command was applied regardless.
        let _ = self.reply_tx.enqueue(r);
    }
    #[inline(always)]
    fn status(&mut self, st: &BoardStatus) {
        // A full queue means the link is behind: skip this snapshot.
        let _ = self.status_tx.enqueue(*st);
    }
    #[inline(always)]
    fn sample(&mut self, s: &TickSample) {
        self.capture.push(s);
        // A full queue means the link is behind: dropped.
        let _ = self.sample_tx.enqueue(*s);
    }
}

/// Everything the tick owns.
pub struct Tick {
    tl: TickLoop<LawRef, SLAVES, PRESSURES>,
    io: BoardIo,
    host: FwHost,
}

/// The tick's state (≈ 9 KiB with the cam table) lives in `.bss`.
static TICK_CELL: StaticCell<Tick> = StaticCell::new();
/// The interrupt's handle on it (`None` until [`start`]; a null pointer, so also `.bss`).
static TICK: Mutex<RefCell<Option<&'static mut Tick>>> = Mutex::new(RefCell::new(None));

impl Tick {
    /// Assembles the tick; the period is the runtime's.
    pub fn new(rt: BoardRuntime, io: BoardIo, tim7: Peri<'static, TIM7>, links: TickLinks) -> Self {
        let period_us = rt.coeffs().period_us;
        let timer = Timer::new(tim7);
        timer.set_period_us(period_us, RoundTo::Slower);
        timer.enable_update_interrupt(true);
        Self {
            tl: TickLoop::new(rt, SYSCLK_HZ / 1_000_000, COMMAND_MAX_AGE_US),
            io,
            host: FwHost {
                timer,
                cmd_rx: links.cmd_rx,
                reply_tx: links.reply_tx,
                status_tx: links.status_tx,
                sample_tx: links.sample_tx,
                capture: links.capture,
            },
        }
    }

    #[inline(always)]
    fn run(&mut self) {
        self.tl.run(&mut self.io, &mut self.host);
    }
}

#[cfg(not(feature = "console"))]
/// Runs `f` on the tick's runtime inside a critical section (the tick cannot run
/// meanwhile): keep `f` short, it delays the next tick by its duration. `None` before
/// [`start`].
pub fn with_runtime<R>(f: impl FnOnce(&mut BoardRuntime) -> R) -> Option<R> {
    critical_section::with(|cs| {
        TICK.borrow_ref_mut(cs)
            .as_mut()
            .map(|t| f(t.tl.runtime_mut()))
    })
}

#[cfg(not(feature = "console"))]
/// Runs `f` on the tick's capture ring inside a critical section (as [`with_runtime`]:
/// keep it short). `None` before [`start`].
pub fn with_capture<R>(f: impl FnOnce(&mut BoardCapture) -> R) -> Option<R> {
    critical_section::with(|cs| {
        TICK.borrow_ref_mut(cs)
            .as_mut()
            .map(|t| f(&mut t.host.capture))
    })
}

#[cfg(not(feature = "console"))]
/// Why [`stalled`] refused to run its function.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum StallError {
    /// An axis is following or holding (checked inside the critical section, so it
    /// cannot start between the check and the stall).
    NotIdle,
}

#[cfg(not(feature = "console"))]
/// Runs `f` — something that stalls the CPU for longer than a period, i.e. a flash
/// sector erase — with the tick held off, then resynchronises it so the pause is not
/// an overrun. Refused ([`StallError::NotIdle`]) unless the runtime is Idle or in Fault,
/// checked inside the same critical section as `f`.
///
/// Inside one critical section: the state is checked; every command still queued is
/// dropped unapplied (its sender gave up waiting, or it would run after a pause of
/// seconds); the watchdog is lengthened to [`Timeout::STALL`] (≥ 8.2 s at the fastest
/// LSI); `f` runs; the runtime's encoder history is dropped (`Runtime::set_coeffs` with
/// the same coefficients: the next sample is not compared with the one before the pause,
/// so a drift while the valves were unpowered is not an encoder jump — the 16-bit TIM3
/// extension itself stays exact unless that slave drifts 32 767 counts, 32.8 mm, during
/// the pause); the start-to-start overrun check restarts; the watchdog gets its previous
/// timeout back. The tick pending during the pause runs as soon as the section ends.
pub fn stalled<R>(f: impl FnOnce() -> R) -> Result<R, StallError> {
    critical_section::with(|cs| {
        let mut cell = TICK.borrow_ref_mut(cs);
        if let Some(t) = cell.as_mut() {
            if !matches!(t.tl.runtime().state(), State::Idle | State::Fault) {
                return Err(StallError::NotIdle);
            }
            while t.host.cmd_rx.dequeue().is_some() {}
        }
        let before = watchdog::current();
        watchdog::set(Timeout::STALL);
        let r = f();
        if let Some(t) = cell.as_mut() {
            // Idle/Fault was checked above and nothing ran since: cannot be refused.
            let _ = t.tl.resync();
        }
        watchdog::set(before);
        Ok(r)
    })
}

/// Hands the tick to its interrupt and starts the period timer.
pub fn start(tick: Tick) {
    let t = TICK_CELL.init(tick);
    // From the boot timeout to the running one (fed by every tick from now on).
    watchdog::set(Timeout::TICK);
    t.host.timer.start();
    critical_section::with(|cs| {
        TICK.borrow_ref_mut(cs).replace(t);
    });
    interrupt::TIM7.set_priority(Priority::P0);
    // Note(unsafe): the handler only touches `TICK`, initialised just above.
    #[allow(unsafe_code)]
    unsafe {
        interrupt::TIM7.enable();
    }
}

#[allow(unsafe_code)]
#[interrupt]
fn TIM7() {
    // The tick runs inside a critical section: it is the highest priority anyway, so
    // this only costs the PRIMASK save/restore and lets the state live in a safe static.
    critical_section::with(|cs| {
        if let Some(t) = TICK.borrow_ref_mut(cs).as_mut() {
            t.run();
        }
    });
}
