//! The runtime's `Manual` state: the manual commands (jog, move, approach, test) and the
//! manual tick ([`super::manual`] gives the references, the law follows them).

use super::super::config::MasterSource;
use super::super::controller::{ControlOutputs, Controller};
use super::super::manual::{Manual, MotionError, MotionLimits};
use super::super::reference::RefState;
use super::{Command, CommandError, Runtime, State};
use crate::axis::PosRef;
use crate::units::{Master, PosUm};

/// How close every slave must be to the table's value at the live master for an
/// approach to start following, µm: the law then starts from an error of at most this
/// (1.1 LSB/µm × 10 µm = 11 LSB, 0.5 % of the valve's range, with the shipped gains).
pub const APPROACH_TOLERANCE_UM: i32 = 10;

/// [`APPROACH_TOLERANCE_UM`] as a position (I24F8), made once, not in the tick.
const APPROACH_TOLERANCE: PosUm = PosUm::from_bits(APPROACH_TOLERANCE_UM << 8);

impl<C: Controller<S>, const S: usize, const P: usize> Runtime<C, S, P> {
    /// Jog, MoveTo, Approach or Test (Idle or Manual; Idle enters Manual on success).
    pub(super) fn manual_command(
        &mut self,
        cmd: Command,
        master: Master,
        pos_um: &[PosUm; S],
    ) -> Result<(), CommandError> {
        match self.state {
            State::Fault => return Err(CommandError::Faulted),
            State::Following | State::Holding(_) => return Err(CommandError::Busy),
            State::Idle | State::Manual => {}
        }
        if self.law.is_none() {
            return Err(CommandError::NoController);
        }
        let entering = self.state == State::Idle;
        let jog_renewal = matches!(cmd, Command::Jog { speed, .. } if speed.to_bits() != 0);
        if self.jog_lockout_ticks > 0 && jog_renewal {
            // Within the deadman time after leaving Manual: a renewal of the jog that was
            // stopped, not a new command — also once a move, an approach or a test (a
            // command of its own, never a renewal: it may follow a Stop at once) has
            // entered Manual again.
            return Err(CommandError::Busy);
        }
        if entering {
            self.manual = Manual::holding(pos_um, self.cfg.period_us);
            self.approach = None;
        }
        if self.approach.is_some() && !matches!(cmd, Command::Approach { .. }) {
            // Following starts when the approach ends: nothing may move the slaves
            // off their way to the table meanwhile (Hold cancels the approach).
            return Err(CommandError::Busy);
        }
        let referenced = |rt: &Self, axis: u8| -> Result<bool, CommandError> {
            rt.refs
                .states()
                .get(usize::from(axis))
                .map(|s| *s == RefState::Referenced)
                .ok_or(CommandError::NoAxis { axis })
        };
        let motion = |axis: u8| move |error: MotionError| CommandError::Motion { axis, error };
        match cmd {
            Command::Jog {
                axis,
                speed,
                limits,
                range,
            } => {
                let range = referenced(self, axis)?.then_some(range);
                self.manual
                    .jog(usize::from(axis), speed, &limits, range)
                    .map_err(motion(axis))?;
            }
            Command::MoveTo {
                axis,
                to,
                limits,
                range,
            } => {
                if !referenced(self, axis)? {
                    return Err(CommandError::NotReferenced { axis });
                }
                if to < range.0 || to > range.1 {
                    return Err(motion(axis)(MotionError::OutsideLimits));
                }
                self.manual
                    .move_to(usize::from(axis), to, &limits)
                    .map_err(motion(axis))?;
            }
            Command::Test {
                axis,
                spec,
                range,
                max_speed_um_per_s,
            } => {
                if !referenced(self, axis)? {
                    return Err(CommandError::NotReferenced { axis });
                }
                // The following-error limit in force: the runtime's, or the law's own
                // where it is lower.
                let i = usize::from(axis);
                let runtime = self
                    .cfg
                    .following_error_limit_um
                    .get(i)
                    .copied()
                    .ok_or(CommandError::NoAxis { axis })?
                    .saturating_abs();
                let own = self
                    .law
                    .as_ref()
                    .and_then(|l| l.following_error_limit_um(i))
                    .map_or(runtime, PosUm::saturating_abs);
                self.manual
                    .test(i, &spec, range, max_speed_um_per_s, runtime.min(own))
                    .map_err(motion(axis))?;
            }
            Command::Approach { limits } => {
                if !self.manual.at_rest() {
                    return Err(CommandError::Busy);
                }
                if let Some(axis) = self.refs.first_unreferenced() {
                    return Err(CommandError::NotReferenced { axis });
                }
                let m = self.run_master(master);
                let targets = self
                    .law
                    .as_ref()
                    .and_then(|l| l.table_position_um(m))
                    .ok_or(CommandError::NoController)?;
                if let Err((axis, e)) = self.plan_approach(&targets, &limits) {
                    return Err(motion(axis)(e));
                }
                self.approach = Some((master, limits));
            }
            _ => return Err(CommandError::Busy),
        }
        if entering {
            self.begin_control(&self.inputs(master, pos_um));
            self.state = State::Manual;
        }
        Ok(())
    }

    /// The master a run starts from: the live one, or 0 for a time master.
    pub(super) fn run_master(&self, live: Master) -> Master {
        if self.cfg.master_source == MasterSource::Time {
            Master::ZERO
        } else {
            live
        }
    }

    /// One tick in `Manual`: every slave's reference, the law toward it, the fault
    /// checks; the end of an approach starts following.
    /// Out of line: `Runtime::step`'s following path (the hot one, `runtime_step_2axes`
    /// in bench-m4) must not carry the manual tick's code and registers.
    #[inline(never)]
    pub(super) fn manual_tick(
        &mut self,
        live_master: Master,
        pos_um: &[PosUm; S],
    ) -> Option<ControlOutputs<S>> {
        let refs = self.manual.step();
        let inputs = self.inputs(live_master, pos_um);
        let out = self.law.as_mut()?.tick_manual(&inputs, &refs);
        self.check_law(&out.error_um, &out.axis_fault);
        if self.state == State::Manual && self.manual.at_rest() {
            if let Some((m0, limits)) = self.approach.take() {
                self.end_approach(m0, &limits, live_master, &refs, pos_um);
            }
        }
        Some(out)
    }

    /// Plans a move of every slave (all at rest) to `targets`; on a refusal every slave
    /// holds where it was and the slave and reason are returned. (No copy of the manual
    /// state — two planned moves, over a kilobyte — on the tick's stack: the slaves were
    /// at rest, so their hold positions are all there is to restore.)
    fn plan_approach(
        &mut self,
        targets: &[PosUm; S],
        limits: &MotionLimits,
    ) -> Result<(), (u8, MotionError)> {
        let Some(held) = self.manual.held_positions() else {
            return Err((0, MotionError::Moving));
        };
        for (i, &to) in targets.iter().enumerate() {
            if let Err(e) = self.manual.move_to(i, to, limits) {
                self.manual = Manual::holding(&held, self.cfg.period_us);
                return Err((u8::try_from(i).unwrap_or(u8::MAX), e));
            }
        }
        Ok(())
    }

    /// Every slave has arrived (`held`: this tick's references, at rest). Following
    /// starts when each is within [`APPROACH_TOLERANCE_UM`] of the table's value at the
    /// live master; a master that moved meanwhile (still within the resume window of the
    /// command's `m0`) gets a new approach to its value, one beyond the window leaves
    /// the slaves holding in `Manual`.
    fn end_approach(
        &mut self,
        m0: Master,
        limits: &MotionLimits,
        live_master: Master,
        held: &[PosRef; S],
        pos_um: &[PosUm; S],
    ) {
        if live_master.saturating_sub(m0).unsigned_abs() > self.cfg.resume_window_counts {
            return;
        }
        let m = self.run_master(live_master);
        let Some(targets) = self.law.as_ref().and_then(|l| l.table_position_um(m)) else {
            return;
        };
        let tol = APPROACH_TOLERANCE;
        let arrived = targets
            .iter()
            .zip(held.iter())
            .all(|(t, h)| t.saturating_sub(h.x_ref_um).saturating_abs() <= tol);
        if arrived {
            self.time_master = 0;
            self.begin_control(&self.inputs(m, pos_um));
            self.state = State::Following;
        } else if self.plan_approach(&targets, limits).is_ok() {
            self.approach = Some((m0, *limits));
        }
    }
}
