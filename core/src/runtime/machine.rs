//! The runtime state machine: Idle, Following, Holding, Manual, Fault.
//!
//! ```text
//!            Start                         Hold
//!   Idle ───────────────▶ Following ◀──────────────▶ Holding
//!    ▲  ◀─────── Stop ───────┘   Start (resume)    │   (commanded, or
//!    │  ◀─────────────────── Stop ─────────────────┘    end of table)
//!    │ ClearFault (cause gone)
//!   Fault ◀──────── any fault, from every state (latched)
//!
//!   Idle ── Jog / MoveTo / Approach / Test ──▶ Manual ── Stop ──▶ Idle
//!   Manual ── Start (every slave at rest), or the approach's end ──▶ Following
//! ```
//!
//! In `Manual` every slave follows its own reference (`super::manual`: hold, jog, S-curve
//! move) under the law's position control ([`Controller::tick_manual`]); Hold brakes every
//! moving slave to rest and stays in `Manual`. Approach moves every slave to the table's
//! value at the present master and starts following in the tick the last one arrives, if
//! the master is still within `resume_window_counts` of where it was (else the slaves
//! hold in `Manual`).
//!
//! One [`Runtime::step`] per control period, in this order:
//! 1. encoder counts → master (counts) and slave positions (µm);
//! 2. instantaneous causes: E-stop, tick overrun, implausible encoder steps; each one
//!    latches a fault at once;
//! 3. at most one command (so a command never races the tick);
//! 4. Following / Holding: the control law runs; a following error beyond the axis limit,
//!    a fault flagged by the law, or (following, encoder master) a stalled master latches
//!    a fault; the law's end of table moves Following → Holding;
//! 5. outputs: Following / Holding write the law's codes with the enable on; Idle and
//!    Fault write every valve's null code with the enable off — in the very tick a fault
//!    is detected, whatever the law computed.
//!
//! A commanded hold feeds the law the master frozen at the moment of the hold, so every
//! slave holds the table position of that master; Start resumes only if the live master
//! is still within `resume_window_counts` of it (otherwise the target would jump). At
//! the end of the table the law keeps getting the live master: holding the final
//! position is the law's own end-of-table behaviour (SPEC §A step 8). A fault
//! leaves `Fault` only through `ClearFault`, and only in a tick where none of its
//! instantaneous causes (E-stop, overrun, encoder step) is present; the latched record
//! keeps the first cause and a set of every kind seen since.

#[path = "machine_manual.rs"]
mod manual_cmd;

use super::config::{MasterSource, RuntimeCoeffs};
use super::controller::{ControlInputs, Controller, LawFault};
use super::encoder::{plausible, step};
use super::fault::{Fault, FaultEvent, FaultHistory, FaultRecord, FaultSet};
use super::io::{Board, EncoderSample};
use super::manual::{Manual, ManualKind, MotionError, MotionLimits, JOG_DEADMAN_US};
use super::reference::{RefState, References};
use super::stall::StallMonitor;
use super::timing::TickTiming;
use crate::fixed_point::sat_i32;
use crate::master::EdgeEstimator;
use crate::units::{Counts, DacCode, Master, PosUm, PressureBar, VelUmPerS};

/// Why the runtime is holding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HoldReason {
    /// A Hold command.
    Commanded,
    /// The master passed the end of the table.
    EndOfTable,
}

/// Runtime state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum State {
    /// Not controlling: valves at null, enable off.
    Idle,
    /// Slaves follow the master through the law.
    Following,
    /// Slaves hold the table position of a frozen master.
    Holding(HoldReason),
    /// Latched fault: valves at null, enable off.
    Fault,
    /// Slaves moved by hand (jog, move, approach) under position control.
    Manual,
}

impl State {
    /// The state's code in Status and in a tick sample's state bits: 0 Idle,
    /// 1 Following, 2 Holding, 3 Fault, 4 Manual.
    pub const fn code(self) -> u8 {
        match self {
            State::Idle => 0,
            State::Following => 1,
            State::Holding(_) => 2,
            State::Fault => 3,
            State::Manual => 4,
        }
    }
}

/// A command to the runtime (from the host link; applied at the next tick).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Idle → Following; Holding (commanded) → Following.
    Start,
    /// Idle or Following → Holding.
    Hold,
    /// Following or Holding → Idle (valves to null, enable off).
    Stop,
    /// Fault → Idle, if the cause is gone.
    ClearFault,
    /// Idle or Fault: slave `axis` is at `pos_um` (set-position, `super::reference`).
    SetPosition {
        /// Slave axis (0-based).
        axis: u8,
        /// Where it is, µm.
        pos_um: PosUm,
    },
    /// Idle or Fault: arm homing of slave `axis` (referenced at its next reference
    /// edge, `super::reference`).
    Home {
        /// Slave axis (0-based).
        axis: u8,
    },
    /// Idle or Manual: jog slave `axis` at `speed` (0: brake to rest); renews its deadman
    /// (`super::manual::JOG_DEADMAN_US`). Within `range` once the slave is referenced.
    Jog {
        /// Slave axis (0-based).
        axis: u8,
        /// Target speed, µm/s (signed).
        speed: VelUmPerS,
        /// Acceleration and jerk (the velocity limit is not used: `speed` is the jog's).
        limits: MotionLimits,
        /// The slave's position limits (min, max), µm.
        range: (PosUm, PosUm),
    },
    /// Idle or Manual, slave at rest and referenced: move slave `axis` to `to` by the
    /// S-curve of `limits`; refused outside `range`.
    MoveTo {
        /// Slave axis (0-based).
        axis: u8,
        /// Target, µm.
        to: PosUm,
        /// Velocity, acceleration and jerk limits.
        limits: MotionLimits,
        /// The slave's position limits (min, max), µm.
        range: (PosUm, PosUm),
    },
    /// Idle or Manual at rest, every slave referenced: move every slave to the table's
    /// value at the present master, then follow (module docs).
    Approach {
        /// Velocity, acceleration and jerk limits of every slave's move.
        limits: MotionLimits,
    },
    /// Idle or Manual, slave at rest and referenced: the identification test move
    /// `spec` about where it holds (`super::test_move`), within `range` and
    /// `max_speed_um_per_s`.
    Test {
        /// Slave axis (0-based).
        axis: u8,
        /// The test.
        spec: super::test_move::TestSpec,
        /// The slave's position limits (min, max), µm.
        range: (PosUm, PosUm),
        /// The slave's top speed, µm/s.
        max_speed_um_per_s: u32,
    },
}

/// Why a command was refused (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// No control law is installed.
    NoController,
    /// The runtime is in Fault: clear it first.
    Faulted,
    /// ClearFault while a cause is still present.
    CauseActive(Fault),
    /// Resume refused: the master moved more than the resume window while holding.
    MasterMoved,
    /// Resume refused: holding at the end of the table.
    EndOfTable,
    /// A new law can only be installed in Idle, Fault or at the end of the table; a
    /// reference can only be set in Idle or Fault.
    Busy,
    /// Start (or Hold from Idle) while a slave is not referenced (`super::reference`).
    NotReferenced {
        /// The first unreferenced slave.
        axis: u8,
    },
    /// A reference command for a slave the runtime does not have.
    NoAxis {
        /// The axis asked for.
        axis: u8,
    },
    /// A manual motion of slave `axis` refused for `error`.
    Motion {
        /// The slave.
        axis: u8,
        /// Why.
        error: MotionError,
    },
}

/// Whether the board came out of a watchdog reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BootCause {
    /// Power-on, pin or software reset: start in Idle.
    Normal,
    /// Independent-watchdog reset: start latched in `Fault::Watchdog`.
    Watchdog,
}

/// Everything sampled at the start of a period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample<const S: usize, const P: usize> {
    /// Encoder counts.
    pub enc: EncoderSample<S>,
    /// Chamber pressures, bar.
    pub pressure_bar: [PressureBar; P],
    /// E-stop input active.
    pub estop: bool,
    /// The scheduler saw the previous tick overrun (or a skipped period).
    pub overrun: bool,
}

/// What one tick writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickOutputs<const S: usize> {
    /// Valve codes.
    pub dac: [DacCode; S],
    /// Valve-power enable.
    pub enable: bool,
    /// The answer to this tick's command, if there was one.
    pub reply: Option<Result<(), CommandError>>,
}

/// A snapshot of the runtime for status and telemetry (updated every tick).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status<const S: usize, const P: usize> {
    /// Tick counter (wraps).
    pub tick: u32,
    /// State.
    pub state: State,
    /// Latched first fault.
    pub fault: Option<FaultRecord>,
    /// Every fault kind seen since the latch.
    pub fault_set: FaultSet,
    /// Master as fed to the law (frozen while holding), master counts.
    pub master: Master,
    /// Measured slave positions, µm.
    pub pos_um: [PosUm; S],
    /// Targets (position + error), µm.
    pub target_um: [PosUm; S],
    /// Following errors, µm: the law's on every tick it ran (also the tick on which a
    /// fault stopped the control: the error that tripped it), 0 otherwise.
    pub error_um: [PosUm; S],
    /// Valve codes written.
    pub dac: [DacCode; S],
    /// Valve-power enable written.
    pub enable: bool,
    /// E-stop input.
    pub estop: bool,
    /// Chamber pressures, bar.
    pub pressure_bar: [PressureBar; P],
    /// Tick execution time.
    pub timing: TickTiming,
    /// Each slave's reference state.
    pub reference: [RefState; S],
    /// The pressure inputs were live this tick ([`super::io::PressureInput::healthy`]).
    pub pressure_ok: bool,
    /// What each slave does in manual control (`Hold` outside `Manual`).
    pub manual: [ManualKind; S],
}

/// The runtime: states, fault rules and outputs around a control law `C`.
#[derive(Clone, Debug)]
pub struct Runtime<C, const S: usize, const P: usize> {
    cfg: RuntimeCoeffs<S>,
    law: Option<C>,
    state: State,
    fault: Option<FaultRecord>,
    fault_set: FaultSet,
    history: FaultHistory,
    /// The previous sample's master and slave counts (the plausibility check).
    prev_enc: Option<(Counts, [Counts; S])>,
    /// The master below one count from its encoder's timestamped edges
    /// ([`crate::master::EdgeEstimator`]; the count where the board has no edge timer).
    edges: EdgeEstimator,
    time_master: i64,
    held_master: Master,
    stall: StallMonitor,
    status: Status<S, P>,
    refs: References<S>,
    /// Per slave, the configured offset plus the reference offset, µm: worked out when
    /// either changes ([`Runtime::refresh_offsets`]), so a tick adds one offset.
    pos_offset_um: [PosUm; S],
    /// The board's pressure inputs were live at the last `tick_io`.
    pressure_ok: bool,
    /// The chamber pressures per slave the law gets: this tick's while the pressure
    /// inputs are live, else the last live ones.
    chambers: [[PressureBar; 2]; S],
    /// The slaves' references in `Manual`.
    manual: Manual<S>,
    /// A pending approach: the master of its command and its limits (following begins
    /// when the slaves have arrived at the table's value at the live master).
    approach: Option<(Master, MotionLimits)>,
    /// Ticks left in which a Jog may not re-enter `Manual` from Idle: a host still
    /// renewing a jog must not undo a Stop (or a fault) by its next renewal. (MoveTo,
    /// Approach and Test are not renewals: not locked.)
    jog_lockout_ticks: u32,
}

/// Slave position from a count: `count · scale + offset` (scale in Q.32, result I24F8).
#[inline]
fn pos_from_counts(c: Counts, scale_q32: i64, offset: PosUm) -> PosUm {
    // Saturating: a product beyond i64 is a position far outside the I24F8 range anyway.
    let q8 = i64::from(c.0).saturating_mul(scale_q32).wrapping_shr(24);
    PosUm::from_bits(sat_i32(q8)).saturating_add(offset)
}

impl<C: Controller<S>, const S: usize, const P: usize> Runtime<C, S, P> {
    /// A runtime in Idle (or latched in `Fault::Watchdog` after a watchdog reset).
    pub fn new(cfg: RuntimeCoeffs<S>, law: Option<C>, boot: BootCause) -> Self {
        let mut rt = Self {
            cfg,
            law,
            state: State::Idle,
            fault: None,
            fault_set: FaultSet::EMPTY,
            history: FaultHistory::new(),
            prev_enc: None,
            edges: EdgeEstimator::START,
            time_master: 0,
            held_master: Master::ZERO,
            stall: StallMonitor::default(),
            status: Status {
                tick: 0,
                state: State::Idle,
                fault: None,
                fault_set: FaultSet::EMPTY,
                master: Master::ZERO,
                pos_um: [PosUm::ZERO; S],
                target_um: [PosUm::ZERO; S],
                error_um: [PosUm::ZERO; S],
                dac: [DacCode::NULL; S],
                enable: false,
                estop: false,
                pressure_bar: [PressureBar::ZERO; P],
                timing: TickTiming::default(),
                reference: [RefState::Unreferenced; S],
                pressure_ok: true,
                manual: [ManualKind::Hold; S],
            },
            refs: References::new(cfg.slave_reference, cfg.home_position_um),
            pos_offset_um: cfg.slave_offset_um,
            pressure_ok: true,
            chambers: [[PressureBar::ZERO; 2]; S],
            manual: Manual::holding(&[PosUm::ZERO; S], cfg.period_us),
            approach: None,
            jog_lockout_ticks: 0,
        };
        rt.status.reference = *rt.refs.states();
        rt.status.dac = rt.null_codes();
        if boot == BootCause::Watchdog {
            rt.raise(Fault::Watchdog, 0, 0);
            rt.status.state = rt.state;
            rt.status.fault = rt.fault;
            rt.status.fault_set = rt.fault_set;
        }
        rt
    }

    /// Current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<FaultRecord> {
        self.fault
    }

    /// The last fault events ([`FaultHistory`]; `oldest_ordered()` reads them in order).
    pub fn fault_history(&self) -> &FaultHistory {
        &self.history
    }

    /// The latest status snapshot.
    pub fn status(&self) -> &Status<S, P> {
        &self.status
    }

    /// The configuration in use.
    pub fn coeffs(&self) -> &RuntimeCoeffs<S> {
        &self.cfg
    }

    /// The installed law.
    pub fn law(&self) -> Option<&C> {
        self.law.as_ref()
    }

    /// The installed law, mutable (e.g. to change gains between runs).
    pub fn law_mut(&mut self) -> Option<&mut C> {
        self.law.as_mut()
    }

    /// Records the execution time of the tick that just ran (cycles).
    pub fn record_tick_cycles(&mut self, cycles: u32) {
        self.status.timing.record(cycles);
    }

    /// Clears the timing statistics.
    pub fn reset_timing(&mut self) {
        self.status.timing.reset();
    }

    /// Whether a new law may be installed now: Idle, Fault, or holding at table end.
    pub fn at_safe_point(&self) -> bool {
        matches!(
            self.state,
            State::Idle | State::Fault | State::Holding(HoldReason::EndOfTable)
        )
    }

    /// Installs a new law at a safe point and returns the old one. Holding at the end
    /// of the table goes to Idle (valves to null at the next tick).
    pub fn install(&mut self, law: C) -> Result<Option<C>, CommandError> {
        if !self.at_safe_point() {
            return Err(CommandError::Busy);
        }
        if matches!(self.state, State::Holding(_)) {
            self.state = State::Idle;
        }
        Ok(self.law.replace(law))
    }

    /// Each slave's reference ([`super::reference`]).
    pub fn references(&self) -> &References<S> {
        &self.refs
    }

    /// The reference offset of slave `axis` if it is an absolute axis (the value to
    /// persist), µm.
    pub fn absolute_offset_um(&self, axis: u8) -> Option<PosUm> {
        if self.refs.is_absolute(axis) {
            self.refs.offsets().get(usize::from(axis)).copied()
        } else {
            None
        }
    }

    /// Sets where homing references slave `axis`, µm (any state: it acts at the next
    /// reference edge of an armed homing; `NoAxis` for a missing slave).
    pub fn set_home_um(&mut self, axis: u8, home_um: PosUm) -> Result<(), CommandError> {
        self.refs
            .set_home(axis, home_um)
            .ok_or(CommandError::NoAxis { axis })
    }

    /// Slave `axis`' encoder scale, µm per count.
    pub fn um_per_count(&self, axis: u8) -> Option<f32> {
        self.cfg.um_per_count(axis)
    }

    /// Changes slave `axis`' encoder scale, µm per count (Idle or Fault only: `Busy`
    /// otherwise; `NoAxis` for a missing slave or a scale outside 0.001 … 1000 in
    /// magnitude, [`RuntimeCoeffs::set_um_per_count`]). An incremental slave whose scale
    /// changes loses its reference (its offset was in the old scale): Start is refused
    /// until it is referenced again. The scale in force set again changes nothing.
    pub fn set_um_per_count(&mut self, axis: u8, um_per_count: f32) -> Result<(), CommandError> {
        if !matches!(self.state, State::Idle | State::Fault) {
            return Err(CommandError::Busy);
        }
        // The scale in force again (a settings file sent back whole): nothing changes,
        // and the reference stays.
        if self.cfg.um_per_count(axis) == Some(um_per_count) {
            return Ok(());
        }
        self.cfg
            .set_um_per_count(axis, um_per_count)
            .ok_or(CommandError::NoAxis { axis })?;
        self.refs
            .drop_incremental(axis)
            .ok_or(CommandError::NoAxis { axis })?;
        self.refresh_offsets();
        self.status.reference = *self.refs.states();
        Ok(())
    }

    /// Restores a persisted reference offset of absolute slave `axis` (boot; Idle or
    /// Fault only; `NoAxis` for an incremental or missing slave).
    pub fn restore_reference_offset(
        &mut self,
        axis: u8,
        offset_um: PosUm,
    ) -> Result<(), CommandError> {
        if !matches!(self.state, State::Idle | State::Fault) {
            return Err(CommandError::Busy);
        }
        // Only an absolute axis has a persisted offset: an incremental one counts from
        // power-up, and a stale offset would make it look referenced.
        if !self.refs.is_absolute(axis) {
            return Err(CommandError::NoAxis { axis });
        }
        self.refs
            .restore_offset(axis, offset_um)
            .ok_or(CommandError::NoAxis { axis })?;
        self.refresh_offsets();
        self.status.reference = *self.refs.states();
        Ok(())
    }

    /// Recomputes [`Runtime::pos_offset_um`] after the configuration or a reference
    /// changed.
    fn refresh_offsets(&mut self) {
        let sums = self
            .pos_offset_um
            .iter_mut()
            .zip(self.cfg.slave_offset_um.iter())
            .zip(self.refs.offsets().iter());
        for ((o, &c), &r) in sums {
            *o = c.saturating_add(r);
        }
    }

    /// Replaces the configuration (allowed in Idle and Fault only).
    pub fn set_coeffs(&mut self, cfg: RuntimeCoeffs<S>) -> Result<(), CommandError> {
        if !matches!(self.state, State::Idle | State::Fault) {
            return Err(CommandError::Busy);
        }
        self.cfg = cfg;
        self.prev_enc = None;
        self.refresh_offsets();
        Ok(())
    }

    /// Every valve's null code (the law's calibration, or mid-scale without a law).
    pub fn null_codes(&self) -> [DacCode; S] {
        self.law
            .as_ref()
            .map_or([DacCode::NULL; S], Controller::null_codes)
    }

    /// Latches `f` (if not latched already) and records it in the history if its kind is
    /// new since the latch; `value` and `limit` as [`FaultEvent`] documents.
    fn raise(&mut self, f: Fault, value: i32, limit: i32) {
        let latched = self.state == State::Fault;
        if !latched || !self.fault_set.contains(f.kind()) {
            self.history.write(FaultEvent {
                fault: f,
                tick: self.status.tick,
                value,
                limit,
            });
        }
        self.fault_set.insert(f);
        if self.state != State::Fault {
            self.state = State::Fault;
            self.fault = Some(FaultRecord {
                fault: f,
                tick: self.status.tick,
            });
        }
    }

    /// The master the law is fed: the encoder's (`enc`: the count, or below one count from
    /// its edges; negated with `master_invert`) or time's.
    fn master_from(&self, enc: Master) -> Master {
        let c = enc.to_bits();
        let c = if self.cfg.master_invert {
            c.wrapping_neg()
        } else {
            c
        };
        match self.cfg.master_source {
            // |c| ≤ 2^47 (a count of ±2^31 ± ½): its negation cannot wrap.
            MasterSource::Encoder => Master::from_bits(c),
            MasterSource::Time => Master::from_bits(self.time_master.saturating_mul(1 << 16)),
        }
    }

    /// Latches every instantaneous cause of this sample and returns the first one.
    fn latch_causes(&mut self, s: &Sample<S, P>) -> Option<Fault> {
        let mut first = None;
        let mut cause = |rt: &mut Self, f: Fault, value: i32, limit: u32| {
            rt.raise(f, value, i32::try_from(limit).unwrap_or(i32::MAX));
            first.get_or_insert(f);
        };
        if s.estop {
            cause(self, Fault::EStop, 0, 0);
        }
        if s.overrun {
            cause(self, Fault::Overrun, 0, 0);
        }
        if self.cfg.pressure_required && !self.pressure_ok {
            cause(self, Fault::PressureInput, 0, 0);
        }
        if let Some((prev_master, prev_slaves)) = self.prev_enc {
            let master_used = self.cfg.master_source == MasterSource::Encoder;
            let m_step = step(prev_master, s.enc.master);
            if master_used && !plausible(m_step, self.cfg.master_step_limit) {
                let limit = self.cfg.master_step_limit;
                cause(self, Fault::EncoderJump { channel: 0 }, m_step, limit);
            }
            let limits = self.cfg.slave_step_limit;
            let slaves = prev_slaves
                .iter()
                .zip(s.enc.slaves.iter())
                .zip(limits.iter());
            for (i, ((&a, &b), &lim)) in slaves.enumerate() {
                let d = step(a, b);
                if !plausible(d, lim) {
                    let channel = u8::try_from(i.saturating_add(1)).unwrap_or(u8::MAX);
                    cause(self, Fault::EncoderJump { channel }, d, lim);
                }
            }
        }
        self.prev_enc = Some((s.enc.master, s.enc.slaves));
        first
    }

    /// Whether `m` is within the end window of the law's master span.
    fn near_table_end(&self, m: Master) -> bool {
        let w = self.cfg.stall_end_window_counts;
        let span = self.law.as_ref().and_then(Controller::master_span);
        span.is_some_and(|(first, last)| {
            m.saturating_sub(first).unsigned_abs() <= w
                || m.saturating_sub(last).unsigned_abs() <= w
                || m < first
                || m > last
        })
    }

    /// The law's inputs: `master`, `pos_um` and this tick's chamber pressures.
    #[inline(always)]
    pub(super) fn inputs(&self, master: Master, pos_um: &[PosUm; S]) -> ControlInputs<S> {
        ControlInputs {
            master,
            pos_um: *pos_um,
            pressure_bar: self.chambers,
        }
    }

    pub(super) fn begin_control(&mut self, inputs: &ControlInputs<S>) {
        if let Some(law) = self.law.as_mut() {
            law.restart(inputs);
        }
        self.stall.reset(inputs.master);
    }

    fn command(
        &mut self,
        cmd: Command,
        master: Master,
        pos_um: &[PosUm; S],
        first_cause: Option<Fault>,
    ) -> Result<(), CommandError> {
        let has_law = self.law.is_some();
        let unreferenced = self.refs.first_unreferenced();
        let manual_at_rest = self.state == State::Manual && self.manual.at_rest();
        match (cmd, self.state) {
            (
                Command::Jog { .. }
                | Command::MoveTo { .. }
                | Command::Approach { .. }
                | Command::Test { .. },
                _,
            ) => self.manual_command(cmd, master, pos_um),
            (Command::Hold, State::Manual) => {
                self.manual.stop_all();
                self.approach = None;
                Ok(())
            }
            (Command::Start, State::Manual) if !manual_at_rest => Err(CommandError::Busy),
            (Command::SetPosition { axis, pos_um: at }, State::Idle | State::Fault) => {
                let measured = *pos_um
                    .get(usize::from(axis))
                    .ok_or(CommandError::NoAxis { axis })?;
                self.refs
                    .set_position(axis, measured, at)
                    .ok_or(CommandError::NoAxis { axis })?;
                self.refresh_offsets();
                Ok(())
            }
            (Command::Home { axis }, State::Idle | State::Fault) => self
                .refs
                .arm_home(axis)
                .ok_or(CommandError::NoAxis { axis }),
            (Command::SetPosition { .. } | Command::Home { .. }, _) => Err(CommandError::Busy),
            (Command::ClearFault, State::Fault) => match first_cause {
                Some(f) => Err(CommandError::CauseActive(f)),
                None => {
                    self.state = State::Idle;
                    self.fault = None;
                    self.fault_set = FaultSet::EMPTY;
                    Ok(())
                }
            },
            (Command::ClearFault | Command::Stop, _) => {
                if matches!(
                    self.state,
                    State::Following | State::Holding(_) | State::Manual
                ) {
                    self.state = State::Idle;
                    self.approach = None;
                }
                Ok(())
            }
            (Command::Start | Command::Hold, State::Fault) => Err(CommandError::Faulted),
            (Command::Start | Command::Hold, _) if !has_law => Err(CommandError::NoController),
            (Command::Start, State::Following) | (Command::Hold, State::Holding(_)) => Ok(()),
            (Command::Start | Command::Hold, State::Idle | State::Manual)
                if unreferenced.is_some() =>
            {
                Err(CommandError::NotReferenced {
                    axis: unreferenced.unwrap_or(0),
                })
            }
            (Command::Start | Command::Hold, State::Idle | State::Manual) => {
                self.time_master = 0;
                let m = self.run_master(master);
                self.begin_control(&self.inputs(m, pos_um));
                if cmd == Command::Start {
                    self.state = State::Following;
                } else {
                    self.held_master = m;
                    self.state = State::Holding(HoldReason::Commanded);
                }
                Ok(())
            }
            (Command::Start, State::Holding(HoldReason::EndOfTable)) => {
                Err(CommandError::EndOfTable)
            }
            (Command::Start, State::Holding(HoldReason::Commanded)) => {
                if master.saturating_sub(self.held_master).unsigned_abs()
                    > self.cfg.resume_window_counts
                {
                    return Err(CommandError::MasterMoved);
                }
                self.stall.reset(master);
                self.state = State::Following;
                Ok(())
            }
            (Command::Hold, State::Following) => {
                self.held_master = master;
                self.state = State::Holding(HoldReason::Commanded);
                Ok(())
            }
        }
    }

    /// One control period (see the module docs for the order of operations).
    pub fn step(&mut self, s: &Sample<S, P>, cmd: Option<Command>) -> TickOutputs<S> {
        self.status.tick = self.status.tick.wrapping_add(1);
        if s.overrun {
            self.status.timing.record_overrun();
        }

        // 1. positions.
        let mut pos_um = [PosUm::ZERO; S];
        let axes = s
            .enc
            .slaves
            .iter()
            .zip(self.cfg.slave_scale_q32.iter())
            .zip(self.pos_offset_um.iter());
        for (p, ((&c, &k), &off)) in pos_um.iter_mut().zip(axes) {
            *p = pos_from_counts(c, k, off);
        }
        let enc_master = self.edges.update(s.enc.master, s.enc.master_edges.as_ref());
        let live_master = self.master_from(enc_master);
        // Stale pressures (the board says its converter stopped) are not handed on: the
        // law keeps the last live ones, so the active damping's high-pass decays to 0
        // instead of acting on a frozen or restarting input.
        if self.pressure_ok {
            self.chambers = super::io::chamber_pressures(&s.pressure_bar);
        }

        // 2. instantaneous causes latch at once.
        let first_cause = self.latch_causes(s);

        // 3. the command.
        let reply = cmd.map(|c| self.command(c, live_master, &pos_um, first_cause));

        // 4. control.
        let mut error_um = [PosUm::ZERO; S];
        let mut law_dac = None;
        let mut fed_master = live_master;
        if self.state == State::Manual {
            if let Some(out) = self.manual_tick(live_master, &pos_um) {
                error_um = out.error_um;
                law_dac = Some(out.dac);
            }
        } else if matches!(self.state, State::Following | State::Holding(_)) {
            if self.cfg.master_source == MasterSource::Time {
                fed_master = self.master_from(enc_master);
            }
            if self.state == State::Holding(HoldReason::Commanded) {
                fed_master = self.held_master;
            }
            let inputs = self.inputs(fed_master, &pos_um);
            if let Some(law) = self.law.as_mut() {
                let out = law.tick(&inputs);
                error_um = out.error_um;
                law_dac = Some(out.dac);
                self.check_law(&out.error_um, &out.axis_fault);
                if self.state == State::Following {
                    if out.end_of_table {
                        self.held_master = fed_master;
                        self.state = State::Holding(HoldReason::EndOfTable);
                    } else if self.cfg.master_source == MasterSource::Encoder
                        && self.stall.update(
                            fed_master,
                            self.cfg.stall_min_move_counts,
                            self.cfg.stall_timeout_ticks,
                        )
                        && !self.near_table_end(fed_master)
                    {
                        let t = i32::try_from(self.cfg.stall_timeout_ticks).unwrap_or(i32::MAX);
                        self.raise(Fault::MasterStalled, t, t);
                    }
                }
            }
            if self.state == State::Following && self.cfg.master_source == MasterSource::Time {
                self.time_master = self.time_master.saturating_add(1);
            }
        }

        // 5. outputs.
        let controlling = matches!(
            self.state,
            State::Following | State::Holding(_) | State::Manual
        );
        let (dac, enable) = match (controlling, law_dac) {
            (true, Some(d)) => (d, true),
            _ => (self.null_codes(), false),
        };
        // The error stays what the law computed on the tick it ran — also the tick on
        // which a fault stopped the control (Status then shows the error that tripped
        // it); without a law tick it is zero.
        if law_dac.is_none() {
            error_um = [PosUm::ZERO; S];
        }
        self.jog_lockout_ticks =
            if self.status.state == State::Manual && self.state != State::Manual {
                JOG_DEADMAN_US.div_ceil(self.cfg.period_us.max(1))
            } else {
                self.jog_lockout_ticks.saturating_sub(1)
            };
        if self.state != State::Manual {
            // An approach lives only in Manual (a fault, Stop or Start ends it).
            self.approach = None;
        }
        let st = &mut self.status;
        st.state = self.state;
        st.fault = self.fault;
        st.fault_set = self.fault_set;
        st.master = fed_master;
        st.pos_um = pos_um;
        for ((t, &p), &e) in st
            .target_um
            .iter_mut()
            .zip(pos_um.iter())
            .zip(error_um.iter())
        {
            *t = p.saturating_add(e);
        }
        st.error_um = error_um;
        st.dac = dac;
        st.enable = enable;
        st.estop = s.estop;
        st.pressure_bar = s.pressure_bar;
        st.reference = *self.refs.states();
        st.pressure_ok = self.pressure_ok;
        st.manual = if self.state == State::Manual {
            self.manual.kinds()
        } else {
            [ManualKind::Hold; S]
        };
        TickOutputs { dac, enable, reply }
    }

    // Inlined: in the following path (bench-m4 `runtime_step_2axes`) a call costs ≈ 60
    // instructions more than the checks themselves; `manual_tick` has its own copy.
    #[inline(always)]
    pub(super) fn check_law(&mut self, error_um: &[PosUm; S], axis_fault: &[Option<LawFault>; S]) {
        let per_axis = error_um
            .iter()
            .zip(axis_fault.iter())
            .zip(self.cfg.following_error_limit_um.iter());
        // The first following error and the first controller fault, each with the error
        // that tripped it and the axis' limit (I24F8 µm raw).
        let mut raised = [None; 2];
        for (i, ((e, flt), lim)) in per_axis.enumerate() {
            let axis = u8::try_from(i).unwrap_or(u8::MAX);
            let [fe, ctl] = &mut raised;
            let ev = |f: Fault, lim: PosUm| (f, e.to_bits(), lim.to_bits());
            // The law's own limit when it flagged the axis (the setting the user made), else
            // the runtime's.
            if *flt == Some(LawFault::FollowingError) {
                let own = self
                    .law
                    .as_ref()
                    .and_then(|l| l.following_error_limit_um(i));
                fe.get_or_insert(ev(Fault::FollowingError { axis }, own.unwrap_or(*lim)));
            }
            if e.unsigned_abs() > lim.unsigned_abs() {
                fe.get_or_insert(ev(Fault::FollowingError { axis }, *lim));
            }
            if *flt == Some(LawFault::Other) {
                ctl.get_or_insert(ev(Fault::Controller { axis }, *lim));
            }
        }
        for (f, value, limit) in raised.into_iter().flatten() {
            self.raise(f, value, limit);
        }
    }

    /// One period on a board: latch the encoders, read the E-stop and the pressures,
    /// [`Runtime::step`], write the valves then the enable. Returns the command's reply.
    pub fn tick_io<B: Board<S, P>>(
        &mut self,
        board: &mut B,
        cmd: Option<Command>,
        overrun: bool,
    ) -> Option<Result<(), CommandError>> {
        let enc = board.latch();
        let edges = board.reference_edges();
        let mut homed = false;
        for (i, ((e, &k), &off)) in edges
            .iter()
            .zip(self.cfg.slave_scale_q32.iter())
            .zip(self.cfg.slave_offset_um.iter())
            .enumerate()
        {
            if let Some(c) = e {
                if self.refs.on_edge(i, pos_from_counts(*c, k, off)) {
                    homed = true;
                }
            }
        }
        if homed {
            let before = self.pos_offset_um;
            self.refresh_offsets();
            if self.state == State::Manual {
                // Homing while jogging to the switch: the measured position moved by the
                // offset change; the manual reference moves with it (no step).
                for (i, (&new, &old)) in self.pos_offset_um.iter().zip(before.iter()).enumerate() {
                    if new != old {
                        self.manual.rebase(i, new.saturating_sub(old));
                    }
                }
            }
        }
        let estop = board.estop_active();
        let pressure_bar = super::io::PressureInput::read(board);
        self.pressure_ok = super::io::PressureInput::healthy(board);
        let out = self.step(
            &Sample {
                enc,
                pressure_bar,
                estop,
                overrun,
            },
            cmd,
        );
        board.write(&out.dac);
        board.set_enable(out.enable);
        out.reply
    }
}
