//! The hard-period tick: TIM7's update interrupt at the highest priority.
//!
//! Deadline: the whole tick (encoder latch → runtime → valve write → watchdog feed) must
//! finish within one period (1 ms by default, down to 100 µs). Nothing else runs at
//! priority 0, so the only delay between the timer's update event and the first encoder
//! read is the interrupt entry (12 cycles) plus the longest critical section of the
//! lower-priority code (the single-core `critical-section` masks interrupts; embassy's
//! own sections are a few dozen cycles).
//!
//! Per tick:
//! 1. `t0` ← DWT cycle counter; TIM7's update flag cleared; at most one command taken
//!    from its queue; then the encoders are latched (the first thing `Runtime::tick_io`
//!    does, about 30 cycles after the handler's entry);
//! 2. the runtime's step with at most one queued command and the overrun flag of the
//!    previous tick; valves and enable written;
//! 3. the independent watchdog fed (only here: a tick that stops running resets the
//!    board within the watchdog timeout);
//! 4. every 10 ms a status snapshot is queued for the host link;
//! 5. a [`TickSample`] (tick, master, per-axis target/actual/DAC code) is queued for the
//!    host link's telemetry (a full queue drops it);
//! 6. the tick's cycles are recorded (max, window mean); if TIM7's update flag is set
//!    again the next period began before the tick finished, and if two tick starts are
//!    more than 1.5 periods apart a period was skipped: either is an overrun, reported to
//!    the runtime (which latches `Fault::Overrun`) at the next tick.

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
use hydra_core::runtime::{Command, CommandError, Runtime, Status};
use static_cell::StaticCell;

use crate::board::{BoardIo, PRESSURES, SLAVES, SYSCLK_HZ};
use crate::laws::LawRef;
use crate::watchdog::{self, Timeout};

/// The runtime as this board runs it: the law in one of the two static law buffers
/// (`crate::laws`), so installing one swaps a reference.
pub type BoardRuntime = Runtime<LawRef, SLAVES, PRESSURES>;
/// The status snapshot of this board.
pub type BoardStatus = Status<SLAVES, PRESSURES>;

/// A command for the tick, with the token its answer carries and when it was queued.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct TickCommand {
    /// The command.
    pub cmd: Command,
    /// Chosen by the sender; the reply carries it back.
    pub token: u16,
    /// DWT cycle count when it was queued: a command older than [`COMMAND_MAX_AGE_US`]
    /// when the tick takes it is dropped, never applied (its sender has given up waiting
    /// and answered the host already).
    pub queued_at: u32,
}

/// Age beyond which a queued command is dropped unapplied, µs: the link's wait for an
/// answer (`crate::link::COMMAND_WAIT_MS`) less one period, so a command whose wait
/// timed out can never take effect later (e.g. a Start after a flash erase).
pub const COMMAND_MAX_AGE_US: u32 = crate::link::COMMAND_WAIT_MS * 1000 - crate::program::PERIOD_US;

/// A command's answer, sent back to the host link.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct Reply {
    /// The command.
    pub cmd: Command,
    /// The sender's token ([`TickCommand::token`]).
    pub token: u16,
    /// Applied and accepted (`Ok`), refused by the runtime (`Err(Some(e))`), or dropped
    /// unapplied because it was older than [`COMMAND_MAX_AGE_US`] (`Err(None)`).
    pub result: Result<(), Option<CommandError>>,
}

/// One tick's telemetry sample (raw fixed-point bits, as on the wire).
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "console", allow(dead_code))]
pub struct TickSample {
    /// Tick number since boot.
    pub tick: u32,
    /// Filtered master, I48F16 master counts (raw bits).
    pub master: i64,
    /// Per slave: target, I24F8 µm (raw bits).
    pub target_um: [i32; SLAVES],
    /// Per slave: measured position, I24F8 µm (raw bits).
    pub actual_um: [i32; SLAVES],
    /// Per slave: valve command, DAC LSB.
    pub dac: [i16; SLAVES],
}

/// Status snapshots are queued every this many µs.
pub const STATUS_PERIOD_US: u32 = 10_000;

/// Everything the tick owns.
pub struct Tick {
    rt: BoardRuntime,
    io: BoardIo,
    timer: Timer<'static, TIM7>,
    cmd_rx: Consumer<'static, TickCommand>,
    reply_tx: Producer<'static, Reply>,
    status_tx: Producer<'static, BoardStatus>,
    sample_tx: Producer<'static, TickSample>,
    period_cycles: u32,
    last_start: Option<u32>,
    overrun_pending: bool,
    status_every: u32,
    status_countdown: u32,
}

/// The channels between the tick and the host link.
pub struct TickLinks {
    /// Commands in.
    pub cmd_rx: Consumer<'static, TickCommand>,
    /// Replies out.
    pub reply_tx: Producer<'static, Reply>,
    /// Status snapshots out.
    pub status_tx: Producer<'static, BoardStatus>,
    /// Per-tick telemetry samples out.
    pub sample_tx: Producer<'static, TickSample>,
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
        let period_cycles = (SYSCLK_HZ / 1_000_000).saturating_mul(period_us);
        let status_every = (STATUS_PERIOD_US / period_us).max(1);
        Self {
            rt,
            io,
            timer,
            cmd_rx: links.cmd_rx,
            reply_tx: links.reply_tx,
            status_tx: links.status_tx,
            sample_tx: links.sample_tx,
            period_cycles,
            last_start: None,
            overrun_pending: false,
            status_every,
            status_countdown: status_every,
        }
    }

    #[inline(always)]
    fn run(&mut self) {
        let t0 = cortex_m::peripheral::DWT::cycle_count();
        // The update flag is cleared first, so the check at the end sees only the *next*
        // period's update event.
        self.timer.clear_update_interrupt();
        let queued = self.cmd_rx.dequeue();
        // A command older than its sender's wait is dropped, never applied.
        let max_age = (SYSCLK_HZ / 1_000_000).saturating_mul(COMMAND_MAX_AGE_US);
        let fresh = queued.filter(|c| t0.wrapping_sub(c.queued_at) <= max_age);
        let overrun = self.overrun_pending || self.skipped(t0);
        // 1.–2. latch, step, write (encoders are the first thing tick_io touches).
        let reply = self.rt.tick_io(&mut self.io, fresh.map(|c| c.cmd), overrun);
        self.overrun_pending = false;
        // 3. the watchdog is fed here and nowhere else.
        watchdog::pet();
        if let Some(c) = queued {
            let result = match (fresh, reply) {
                (Some(_), Some(r)) => r.map_err(Some),
                // Applied with no answer cannot happen (`tick_io` answers every command).
                (Some(_), None) => Ok(()),
                (None, _) => Err(None),
            };
            let reply = Reply {
                cmd: c.cmd,
                token: c.token,
                result,
            };
            crate::link::REPLY.signal(reply);
            // A full reply queue drops the reply; the command was applied regardless.
            let _ = self.reply_tx.enqueue(reply);
        }
        // 4. status for the host link.
        self.status_countdown = self.status_countdown.saturating_sub(1);
        if self.status_countdown == 0 {
            self.status_countdown = self.status_every;
            // A full queue means the link is behind: skip this snapshot.
            let _ = self.status_tx.enqueue(*self.rt.status());
        }
        // 5. telemetry sample (a full queue means the link is behind: dropped).
        let st = self.rt.status();
        let _ = self.sample_tx.enqueue(TickSample {
            tick: st.tick,
            master: st.master.to_bits(),
            target_um: st.target_um.map(|v| v.to_bits()),
            actual_um: st.pos_um.map(|v| v.to_bits()),
            dac: st.dac.map(|d| d.get()),
        });
        // 6. timing and overrun.
        let t1 = cortex_m::peripheral::DWT::cycle_count();
        self.rt.record_tick_cycles(t1.wrapping_sub(t0));
        if self.timer.regs_core().sr().read().uif() {
            self.overrun_pending = true;
        }
    }

    /// Whether more than 1.5 periods passed since the previous tick started.
    #[inline(always)]
    fn skipped(&mut self, t0: u32) -> bool {
        let late = self.last_start.is_some_and(|prev| {
            t0.wrapping_sub(prev) > self.period_cycles.saturating_add(self.period_cycles / 2)
        });
        self.last_start = Some(t0);
        late
    }
}

#[cfg(not(feature = "console"))]
/// Runs `f` on the tick's runtime inside a critical section (the tick cannot run
/// meanwhile): keep `f` short, it delays the next tick by its duration. `None` before
/// [`start`].
pub fn with_runtime<R>(f: impl FnOnce(&mut BoardRuntime) -> R) -> Option<R> {
    critical_section::with(|cs| TICK.borrow_ref_mut(cs).as_mut().map(|t| f(&mut t.rt)))
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
            if !matches!(t.rt.state(), State::Idle | State::Fault) {
                return Err(StallError::NotIdle);
            }
            while t.cmd_rx.dequeue().is_some() {}
        }
        let before = watchdog::current();
        watchdog::set(Timeout::STALL);
        let r = f();
        if let Some(t) = cell.as_mut() {
            let c = *t.rt.coeffs();
            // Idle/Fault was checked above and nothing ran since: cannot be refused.
            let _ = t.rt.set_coeffs(c);
            t.last_start = None;
            t.overrun_pending = false;
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
    t.timer.start();
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
