//! The board's tick, in one place: what the hard-period interrupt does each period, for
//! every board that runs the runtime — the firmware's TIM7 handler and the host's
//! virtual board call [`TickLoop::run`], and supply only drivers ([`Board`]) and glue
//! ([`TickHost`]: clock, queues, watchdog).
//!
//! Per tick, in this order:
//! 1. `t0` ← [`TickHost::now_cycles`]; the period timer's flag cleared
//!    ([`TickHost::clear_period_flag`]); at most one command taken
//!    ([`TickHost::take_command`]); a command older than the loop's `max_age` is dropped
//!    unapplied (its sender has given up waiting and answered the host already);
//! 2. [`Runtime::tick_io`]: the encoders latched first, the runtime's step with the
//!    command and the overrun flag of the previous tick, valves then enable written;
//! 3. the watchdog fed ([`TickHost::feed_watchdog`]; only here, so a tick that stops
//!    running resets the board);
//! 4. the command's [`Reply`] ([`TickHost::reply`]);
//! 5. every [`STATUS_PERIOD_US`] a status snapshot ([`TickHost::status`]);
//! 6. a [`TickSample`] for the telemetry and the capture ring ([`TickHost::sample`]);
//! 7. the tick's cycles recorded; if the period flag is set again
//!    ([`TickHost::period_flag`]) the next period began before this tick finished, and if
//!    two tick starts are more than 1.5 periods apart a period was skipped: either is an
//!    overrun, reported to the runtime (which latches `Fault::Overrun`) at the next tick.
//!
//! Units: cycles of the host's clock, [`TickLoop::new`]'s `cycles_per_us` per µs (168 on
//! the board's DWT counter at 168 MHz; 1000 on the virtual board, whose clock counts
//! nanoseconds); wrapping `u32`, so differences are valid for up to 2³² cycles.

use super::controller::Controller;
use super::io::Board;
use super::machine::{Command, CommandError, Runtime, Status};

/// Status snapshots are handed to the host every this many µs.
pub const STATUS_PERIOD_US: u32 = 10_000;

/// A command for the tick, with the token its answer carries and when it was queued.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickCommand {
    /// The command.
    pub cmd: Command,
    /// Chosen by the sender; the reply carries it back.
    pub token: u16,
    /// [`TickHost::now_cycles`] when it was queued.
    pub queued_at: u32,
}

/// A command's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reply {
    /// The command.
    pub cmd: Command,
    /// The sender's token ([`TickCommand::token`]).
    pub token: u16,
    /// Applied and accepted (`Ok`), refused by the runtime (`Err(Some(e))`), or dropped
    /// unapplied because it was older than the loop's maximum age (`Err(None)`).
    pub result: Result<(), Option<CommandError>>,
}

/// [`TickSample::flags`]: the state bits, one 3-bit value — 0 Idle, 1 Following,
/// 2 Holding, 3 Fault, 4 Manual ([`super::State::code`]), 6 = 2 | [`FLAG_END_OF_TABLE`]
/// holding at the end of the table. Decode the value, not the bits one by one: bit 2
/// alone is Manual.
pub const STATE_MASK: u8 = 0b111;
/// [`TickSample::flags`]: with Holding (2), holding because the table ended (the value 6).
pub const FLAG_END_OF_TABLE: u8 = 1 << 2;
/// [`TickSample::flags`]: valve power (the enable output) on.
pub const FLAG_VALVE_POWER: u8 = 1 << 3;
/// [`TickSample::flags`]: the E-stop input is active.
pub const FLAG_ESTOP: u8 = 1 << 4;
/// [`TickSample::flags`]: this tick applied a host command (the runtime accepted it).
pub const FLAG_COMMAND: u8 = 1 << 5;

/// One tick's sample for telemetry and the capture ring (raw fixed-point bits, as on
/// the wire).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickSample<const S: usize> {
    /// Tick number since boot.
    pub tick: u32,
    /// Filtered master, I48F16 master counts (raw bits).
    pub master: i64,
    /// Per slave: target, I24F8 µm (raw bits).
    pub target_um: [i32; S],
    /// Per slave: measured position, I24F8 µm (raw bits).
    pub actual_um: [i32; S],
    /// Per slave: valve command, DAC LSB (0 = null).
    pub dac: [i16; S],
    /// Per slave: chamber A and B pressure (the board's pressure inputs 2k and 2k + 1;
    /// 0 where the board has none), centibar (0.01 bar, 0 … 655.35 bar, saturating: a
    /// negative reading is 0).
    pub pressure_cbar: [[u16; 2]; S],
    /// State bits ([`STATE_MASK`]), [`FLAG_VALVE_POWER`], [`FLAG_ESTOP`],
    /// [`FLAG_COMMAND`].
    pub flags: u8,
}

impl<const S: usize> TickSample<S> {
    /// The sample of a status snapshot (without [`FLAG_COMMAND`]: the tick adds it).
    pub fn of<const P: usize>(st: &Status<S, P>) -> Self {
        // I16F16 bar × 100 → centibar: (raw · 100) >> 16, saturated to u16.
        let pressure_cbar = super::io::chamber_pressures::<S, P>(&st.pressure_bar).map(|pair| {
            pair.map(|bar| {
                let cbar = i64::from(bar.to_bits()).saturating_mul(100) >> 16;
                u16::try_from(cbar.max(0)).unwrap_or(u16::MAX)
            })
        });
        let end = st.state == super::State::Holding(super::HoldReason::EndOfTable);
        let state = st.state.code() | if end { FLAG_END_OF_TABLE } else { 0 };
        let flags = state
            | if st.enable { FLAG_VALVE_POWER } else { 0 }
            | if st.estop { FLAG_ESTOP } else { 0 };
        Self {
            tick: st.tick,
            master: st.master.to_bits(),
            target_um: st.target_um.map(|v| v.to_bits()),
            actual_um: st.pos_um.map(|v| v.to_bits()),
            dac: st.dac.map(|d| d.get()),
            pressure_cbar,
            flags,
        }
    }
}

/// The glue around the tick: the board's clock, its period timer, the queues to and from
/// the host link and the watchdog.
pub trait TickHost<const S: usize, const P: usize> {
    /// A free-running cycle counter (wrapping).
    fn now_cycles(&mut self) -> u32;
    /// Clears the period timer's update flag.
    fn clear_period_flag(&mut self);
    /// Whether the period timer's update flag is set (the next period has begun).
    fn period_flag(&mut self) -> bool;
    /// The next queued command, if any.
    fn take_command(&mut self) -> Option<TickCommand>;
    /// Feeds the watchdog.
    fn feed_watchdog(&mut self);
    /// A command's answer (a full queue may drop it: the command was applied regardless).
    fn reply(&mut self, r: Reply);
    /// A status snapshot, every [`STATUS_PERIOD_US`] (a full queue may drop it).
    fn status(&mut self, st: &Status<S, P>);
    /// Every tick's telemetry sample (a full queue may drop it).
    fn sample(&mut self, s: &TickSample<S>);
}

/// The runtime and the per-tick bookkeeping around it.
pub struct TickLoop<C, const S: usize, const P: usize> {
    rt: Runtime<C, S, P>,
    period_cycles: u32,
    max_age_cycles: u32,
    last_start: Option<u32>,
    overrun_pending: bool,
    status_every: u32,
    status_countdown: u32,
}

impl<C: Controller<S>, const S: usize, const P: usize> TickLoop<C, S, P> {
    /// The loop around `rt` at its period; `cycles_per_us` of the host's clock;
    /// commands older than `max_age_us` when taken are dropped unapplied.
    pub fn new(rt: Runtime<C, S, P>, cycles_per_us: u32, max_age_us: u32) -> Self {
        let period_us = rt.coeffs().period_us;
        let status_every = STATUS_PERIOD_US.checked_div(period_us).unwrap_or(1).max(1);
        Self {
            rt,
            period_cycles: cycles_per_us.saturating_mul(period_us),
            max_age_cycles: cycles_per_us.saturating_mul(max_age_us),
            last_start: None,
            overrun_pending: false,
            status_every,
            status_countdown: status_every,
        }
    }

    /// The runtime.
    pub fn runtime(&self) -> &Runtime<C, S, P> {
        &self.rt
    }

    /// The runtime, mutable (law installs, references, coefficients).
    pub fn runtime_mut(&mut self) -> &mut Runtime<C, S, P> {
        &mut self.rt
    }

    /// One period of cycles.
    pub fn period_cycles(&self) -> u32 {
        self.period_cycles
    }

    /// After a pause of the tick longer than a period (a flash erase, with the axes
    /// idle): the runtime's encoder history is dropped (`Runtime::set_coeffs` with the
    /// same coefficients: the next sample is not compared with the one before the
    /// pause) and the start-to-start overrun check restarts. `Err(Busy)` unless Idle or
    /// in Fault.
    pub fn resync(&mut self) -> Result<(), CommandError> {
        let c = *self.rt.coeffs();
        self.rt.set_coeffs(c)?;
        self.last_start = None;
        self.overrun_pending = false;
        Ok(())
    }

    /// One tick (the module's steps 1–7).
    #[inline(always)]
    pub fn run<B: Board<S, P>, H: TickHost<S, P>>(&mut self, io: &mut B, host: &mut H) {
        let t0 = host.now_cycles();
        // The flag is cleared first, so the check at the end sees only the *next*
        // period's update event.
        host.clear_period_flag();
        let queued = host.take_command();
        let fresh = queued.filter(|c| t0.wrapping_sub(c.queued_at) <= self.max_age_cycles);
        let overrun = self.overrun_pending || self.skipped(t0);
        let reply = self.rt.tick_io(io, fresh.map(|c| c.cmd), overrun);
        // A command the runtime accepted (the capture's `command` trigger).
        let applied = matches!(reply, Some(Ok(())));
        self.overrun_pending = false;
        host.feed_watchdog();
        if let Some(c) = queued {
            let result = match (fresh, reply) {
                (Some(_), Some(r)) => r.map_err(Some),
                // Applied with no answer cannot happen (`tick_io` answers every command).
                (Some(_), None) => Ok(()),
                (None, _) => Err(None),
            };
            host.reply(Reply {
                cmd: c.cmd,
                token: c.token,
                result,
            });
        }
        self.status_countdown = self.status_countdown.saturating_sub(1);
        if self.status_countdown == 0 {
            self.status_countdown = self.status_every;
            host.status(self.rt.status());
        }
        let mut sample = TickSample::of(self.rt.status());
        if applied {
            sample.flags |= FLAG_COMMAND;
        }
        host.sample(&sample);
        let t1 = host.now_cycles();
        self.rt.record_tick_cycles(t1.wrapping_sub(t0));
        if host.period_flag() {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::controller::mock::MockLaw;
    use crate::runtime::io::{
        EncoderInput, EncoderSample, PressureInput, SafetyInput, ValveOutput,
    };
    use crate::runtime::{BootCause, Fault, RuntimeConfig, State};
    use crate::units::{Counts, DacCode, PressureBar};
    use heapless::Vec;

    /// A board that holds still: every count 0.
    #[derive(Default)]
    struct Still {
        enable: bool,
        writes: u32,
    }

    impl EncoderInput<1> for Still {
        fn latch(&mut self) -> EncoderSample<1> {
            EncoderSample {
                master: Counts(0),
                slaves: [Counts(0)],
                master_edges: None,
            }
        }
    }
    impl PressureInput<0> for Still {
        fn read(&mut self) -> [PressureBar; 0] {
            []
        }
    }
    impl SafetyInput for Still {
        fn estop_active(&mut self) -> bool {
            false
        }
    }
    impl ValveOutput<1> for Still {
        fn write(&mut self, _codes: &[DacCode; 1]) {
            self.writes += 1;
        }
        fn set_enable(&mut self, on: bool) {
            self.enable = on;
        }
    }

    /// A host whose clock the test sets; it records what the tick hands it.
    #[derive(Default)]
    struct Rec {
        now: u32,
        late: bool,
        cmd: Option<TickCommand>,
        feeds: u32,
        replies: Vec<Reply, 8>,
        statuses: u32,
        samples: u32,
    }

    impl TickHost<1, 0> for Rec {
        fn now_cycles(&mut self) -> u32 {
            self.now
        }
        fn clear_period_flag(&mut self) {}
        fn period_flag(&mut self) -> bool {
            core::mem::take(&mut self.late)
        }
        fn take_command(&mut self) -> Option<TickCommand> {
            self.cmd.take()
        }
        fn feed_watchdog(&mut self) {
            self.feeds += 1;
        }
        fn reply(&mut self, r: Reply) {
            let _ = self.replies.push(r);
        }
        fn status(&mut self, _st: &Status<1, 0>) {
            self.statuses += 1;
        }
        fn sample(&mut self, _s: &TickSample<1>) {
            self.samples += 1;
        }
    }

    const PERIOD: u32 = 1000; // cycles: 1 cycle per µs at 1 ms

    fn tl() -> TickLoop<MockLaw<1>, 1, 0> {
        let cfg = RuntimeConfig::<1>::default().build().unwrap();
        TickLoop::new(
            Runtime::new(cfg, Some(MockLaw::new()), BootCause::Normal),
            1,
            5000,
        )
    }

    fn run_ticks(t: &mut TickLoop<MockLaw<1>, 1, 0>, b: &mut Still, h: &mut Rec, n: u32) {
        for _ in 0..n {
            t.run(b, h);
            h.now = h.now.wrapping_add(PERIOD);
        }
    }

    #[test]
    fn one_feed_and_sample_per_tick_a_status_every_10_ms() {
        let (mut t, mut b, mut h) = (tl(), Still::default(), Rec::default());
        run_ticks(&mut t, &mut b, &mut h, 25);
        assert_eq!((h.feeds, h.samples, b.writes), (25, 25, 25));
        assert_eq!(h.statuses, 2);
        assert_eq!(t.runtime().status().tick, 25);
        assert_eq!(t.period_cycles(), PERIOD);
    }

    #[test]
    fn a_command_is_answered_and_a_stale_one_dropped_unapplied() {
        let (mut t, mut b, mut h) = (tl(), Still::default(), Rec::default());
        run_ticks(&mut t, &mut b, &mut h, 3);
        h.cmd = Some(TickCommand {
            cmd: Command::Start,
            token: 7,
            queued_at: h.now.wrapping_sub(100),
        });
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(h.replies[0].token, 7);
        assert_eq!(h.replies[0].result, Ok(()));
        assert_eq!(t.runtime().state(), State::Following);
        assert!(b.enable);
        // Queued 5 001 µs ago, the maximum age 5 000 µs: never applied.
        h.cmd = Some(TickCommand {
            cmd: Command::Stop,
            token: 8,
            queued_at: h.now.wrapping_sub(5001),
        });
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(h.replies[1].token, 8);
        assert_eq!(h.replies[1].result, Err(None));
        assert_eq!(t.runtime().state(), State::Following);
        // A refusal carries the runtime's reason.
        h.cmd = Some(TickCommand {
            cmd: Command::Home { axis: 5 },
            token: 9,
            queued_at: h.now,
        });
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(
            h.replies[2].result,
            Err(Some(CommandError::Busy)),
            "homing while following"
        );
    }

    #[test]
    fn a_tick_still_running_at_the_next_period_is_an_overrun() {
        let (mut t, mut b, mut h) = (tl(), Still::default(), Rec::default());
        run_ticks(&mut t, &mut b, &mut h, 2);
        h.late = true;
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(
            t.runtime().state(),
            State::Idle,
            "reported at the next tick"
        );
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(t.runtime().fault().map(|f| f.fault), Some(Fault::Overrun));
        assert!(!b.enable);
    }

    #[test]
    fn a_skipped_period_is_an_overrun_unless_resynchronised() {
        let (mut t, mut b, mut h) = (tl(), Still::default(), Rec::default());
        run_ticks(&mut t, &mut b, &mut h, 2);
        // A pause of 2 periods with a resync (a flash erase): no fault.
        h.now = h.now.wrapping_add(2 * PERIOD);
        t.resync().unwrap();
        run_ticks(&mut t, &mut b, &mut h, 2);
        assert_eq!(t.runtime().fault(), None);
        // 1.6 periods between two starts without one: an overrun.
        h.now = h.now.wrapping_add(PERIOD * 6 / 10);
        run_ticks(&mut t, &mut b, &mut h, 1);
        assert_eq!(t.runtime().fault().map(|f| f.fault), Some(Fault::Overrun));
    }
}
