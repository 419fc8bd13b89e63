//! The board of a simulated run: core's board traits ([`EncoderInput`],
//! [`PressureInput`], [`SafetyInput`], [`ValveOutput`]) over what the run's sensors read
//! this period, and the tick's glue ([`TickHost`]) on simulated time — so every period
//! of a run is one [`TickLoop::run`], the firmware's TIM7 handler: reference edges,
//! E-stop, pressure health, command ageing and the overrun check all live.
//!
//! Units: the clock counts ns of simulated time (`TickLoop::new` with 1000 cycles per
//! µs), wrapping `u32`.

use hydra_core::runtime::{
    Command, CommandError, Controller, EncoderInput, EncoderSample, PressureInput, Reply, Runtime,
    SafetyInput, Status, TickCommand, TickHost, TickLoop, TickSample, ValveOutput,
};
use hydra_core::units::{DacCode, PressureBar};

/// Cycles of the simulated clock per µs (it counts ns).
pub const CYCLES_PER_US: u32 = 1000;
/// A queued command older than this when the tick takes it is dropped, µs (a simulated
/// tick takes its command at once: the firmware's rule, kept).
pub const MAX_COMMAND_AGE_US: u32 = 50_000;

/// The firmware's tick around `rt` on the simulated clock ([`SimHost`]).
pub fn tick_loop<C: Controller<S>, const S: usize, const P: usize>(
    rt: Runtime<C, S, P>,
) -> TickLoop<C, S, P> {
    TickLoop::new(rt, CYCLES_PER_US, MAX_COMMAND_AGE_US)
}

/// The inputs the run's sensors read at the period's sample instant, and the outputs the
/// tick wrote.
#[derive(Clone, Copy, Debug)]
pub struct SampledBoard<const S: usize, const P: usize> {
    /// The encoder counts (and the master's edge timer).
    pub enc: EncoderSample<S>,
    /// The chamber pressures, bar.
    pub pressure_bar: [PressureBar; P],
    /// The pressure inputs are updating (`false`: a lost transmitter or converter).
    pub pressure_live: bool,
    /// The E-stop chain is open.
    pub estop: bool,
    /// The valve codes the tick wrote.
    pub codes: [DacCode; S],
    /// The valve power the tick switched.
    pub enable: bool,
}

impl<const S: usize, const P: usize> SampledBoard<S, P> {
    /// A board at rest: zero counts and pressures, E-stop closed, valves at null, off.
    pub fn new(enc: EncoderSample<S>) -> Self {
        Self {
            enc,
            pressure_bar: [PressureBar::ZERO; P],
            pressure_live: true,
            estop: false,
            codes: [DacCode::NULL; S],
            enable: false,
        }
    }
}

impl<const S: usize, const P: usize> EncoderInput<S> for SampledBoard<S, P> {
    fn latch(&mut self) -> EncoderSample<S> {
        self.enc
    }
}

impl<const S: usize, const P: usize> PressureInput<P> for SampledBoard<S, P> {
    fn read(&mut self) -> [PressureBar; P] {
        self.pressure_bar
    }
    fn healthy(&mut self) -> bool {
        self.pressure_live
    }
}

impl<const S: usize, const P: usize> SafetyInput for SampledBoard<S, P> {
    fn estop_active(&mut self) -> bool {
        self.estop
    }
}

impl<const S: usize, const P: usize> ValveOutput<S> for SampledBoard<S, P> {
    fn write(&mut self, codes: &[DacCode; S]) {
        self.codes = *codes;
    }
    fn set_enable(&mut self, on: bool) {
        self.enable = on;
    }
}

/// The tick's glue on simulated time: one command slot, its reply, no watchdog to feed
/// and a period that is never late (the simulated clock stops while the tick runs).
#[derive(Clone, Copy, Debug, Default)]
pub struct SimHost {
    /// Simulated time at the current tick's start, ns (wrapping).
    pub now_ns: u32,
    cmd: Option<TickCommand>,
    reply: Option<Reply>,
}

impl SimHost {
    /// Queues `cmd` for the next tick (at the current time).
    pub fn queue(&mut self, cmd: Command) {
        self.cmd = Some(TickCommand {
            cmd,
            token: 0,
            queued_at: self.now_ns,
        });
    }

    /// The reply of the last tick that took a command: `Err` if the runtime refused it
    /// (or it was dropped as too old, which a simulated tick never does).
    pub fn take_refusal(&mut self) -> Option<Option<CommandError>> {
        self.reply.take().and_then(|r| r.result.err())
    }
}

impl<const S: usize, const P: usize> TickHost<S, P> for SimHost {
    fn now_cycles(&mut self) -> u32 {
        self.now_ns
    }
    fn clear_period_flag(&mut self) {}
    fn period_flag(&mut self) -> bool {
        false
    }
    fn take_command(&mut self) -> Option<TickCommand> {
        self.cmd.take()
    }
    fn feed_watchdog(&mut self) {}
    fn reply(&mut self, r: Reply) {
        self.reply = Some(r);
    }
    fn status(&mut self, _st: &Status<S, P>) {}
    fn sample(&mut self, _s: &TickSample<S>) {}
}
