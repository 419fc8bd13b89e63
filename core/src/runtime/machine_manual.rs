//! The runtime's `Manual` state: the manual commands (jog, move, approach) and the
//! manual tick ([`super::manual`] gives the references, the law follows them).

use super::super::config::MasterSource;
use super::super::controller::{ControlInputs, ControlOutputs, Controller};
use super::super::manual::{Manual, MotionError};
use super::super::reference::RefState;
use super::{Command, CommandError, Runtime, State};
use crate::units::{Master, PosUm};

impl<C: Controller<S>, const S: usize, const P: usize> Runtime<C, S, P> {
    /// Jog, MoveTo or Approach (Idle or Manual; Idle enters Manual on success).
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
        if entering {
            self.manual = Manual::holding(pos_um, self.cfg.period_us);
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
                let before = self.manual;
                for (i, &to) in targets.iter().enumerate() {
                    let axis = u8::try_from(i).unwrap_or(u8::MAX);
                    if let Err(e) = self.manual.move_to(i, to, &limits) {
                        self.manual = before;
                        return Err(motion(axis)(e));
                    }
                }
                self.approach = Some(master);
            }
            _ => return Err(CommandError::Busy),
        }
        if entering {
            self.begin_control(&ControlInputs {
                master,
                pos_um: *pos_um,
            });
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
    pub(super) fn manual_tick(
        &mut self,
        live_master: Master,
        pos_um: &[PosUm; S],
    ) -> Option<ControlOutputs<S>> {
        let refs = self.manual.step();
        let inputs = ControlInputs {
            master: live_master,
            pos_um: *pos_um,
        };
        let out = self.law.as_mut()?.tick_manual(&inputs, &refs);
        self.check_law(&out.error_um, &out.axis_fault);
        if self.state == State::Manual && self.manual.at_rest() {
            if let Some(m0) = self.approach.take() {
                if live_master.saturating_sub(m0).unsigned_abs() <= self.cfg.resume_window_counts {
                    self.time_master = 0;
                    self.begin_control(&ControlInputs {
                        master: self.run_master(live_master),
                        pos_um: *pos_um,
                    });
                    self.state = State::Following;
                }
            }
        }
        Some(out)
    }
}
