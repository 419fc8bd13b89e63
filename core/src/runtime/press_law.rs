//! Force axes inside the runtime: a law `L` for the position slaves with some slaves
//! under the press law ([`crate::axis::press`]) instead.
//!
//! A stretch-bending machine runs table-following axes and a side press from one tick.
//! [`PressAxes`] is a law the runtime runs for such a machine (the simulator's; the
//! board's profile has no press slave yet): each tick it runs `L`
//! (the follower) over every slave, then replaces the outputs of each press slave with
//! its press law's, from the same inputs (the slave's position and its two chamber
//! pressures). So the press goes through [`super::TickLoop::run`] like every other axis:
//! its encoder is extended and checked for plausibility, stale pressure inputs latch
//! `pressure_input`, an E-stop or any latched fault puts its valve at null, and it runs
//! while the runtime is Following or Holding — also in a commanded Hold and after the end
//! of the table: a press holding the master keeps its force (and an approach under way
//! goes on to contact).
//!
//! | runtime | a press slave |
//! |---|---|
//! | [`Controller::restart`] | the press law restarts: its approach starts from the measured position |
//! | [`Controller::tick`] | the press law's valve code; `error_um` = approach reference − position during the approach (checked against the runtime's following-error limit of the slave), 0 under force control; `L`'s fault on the slave is dropped |
//! | [`Controller::tick_manual`] | `L`'s position law (a press is jogged and moved like any axis) |
//! | [`Controller::null_codes`] | the press valve's calibrated null |
//!
//! `L` still computes an output for a press slave (its table column, which should hold the
//! press' start position); that output is discarded.

use super::controller::{ControlInputs, ControlOutputs, Controller, Learned};
use crate::axis::{PosRef, PressCoeffs, PressOutput, PressState};
use crate::units::{DacCode, Master, PosUm};

/// One press slave: its coefficients, its state and its last output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct PressSlave {
    coeffs: PressCoeffs,
    state: PressState,
    last: PressOutput,
}

/// `L` with some slaves under force control (see the module docs).
#[derive(Clone, Debug)]
pub struct PressAxes<L, const S: usize> {
    law: L,
    press: [Option<PressSlave>; S],
}

/// A slave index beyond the law's slaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NoSuchSlave {
    /// The index asked for.
    pub axis: usize,
}

impl<L, const S: usize> PressAxes<L, S> {
    /// `law` with no press slave (it then behaves exactly as `law`).
    pub const fn new(law: L) -> Self {
        Self {
            law,
            press: [None; S],
        }
    }

    /// Puts slave `axis` under the press law with `coeffs` (`None`: back to `L`). Its
    /// press state restarts.
    pub fn set_press(
        &mut self,
        axis: usize,
        coeffs: Option<PressCoeffs>,
    ) -> Result<(), NoSuchSlave> {
        let slot = self.press.get_mut(axis).ok_or(NoSuchSlave { axis })?;
        *slot = coeffs.map(|coeffs| PressSlave {
            coeffs,
            state: PressState::default(),
            last: PressOutput::default(),
        });
        Ok(())
    }

    /// Whether slave `axis` is under the press law.
    pub fn is_press(&self, axis: usize) -> bool {
        matches!(self.press.get(axis), Some(Some(_)))
    }

    /// Slave `axis`' press output of the last tick (`None`: not a press slave).
    pub fn press_output(&self, axis: usize) -> Option<PressOutput> {
        self.press.get(axis).copied().flatten().map(|p| p.last)
    }

    /// The law of the position slaves.
    pub fn law(&self) -> &L {
        &self.law
    }

    /// The law of the position slaves, mutable (to configure it or load a table).
    pub fn law_mut(&mut self) -> &mut L {
        &mut self.law
    }
}

impl<L: Controller<S>, const S: usize> Controller<S> for PressAxes<L, S> {
    fn restart(&mut self, inputs: &ControlInputs<S>) {
        self.law.restart(inputs);
        for p in self.press.iter_mut().flatten() {
            p.state = PressState::default();
            p.last = PressOutput::default();
        }
    }

    fn tick(&mut self, inputs: &ControlInputs<S>) -> ControlOutputs<S> {
        let mut out = self.law.tick(inputs);
        let slaves = self
            .press
            .iter_mut()
            .zip(inputs.pos_um.iter().zip(inputs.pressure_bar.iter()))
            .zip(
                out.dac
                    .iter_mut()
                    .zip(out.error_um.iter_mut())
                    .zip(out.axis_fault.iter_mut()),
            );
        for ((slot, (&x, &[pa, pb])), ((dac, err), fault)) in slaves {
            let Some(p) = slot else { continue };
            p.last = p.state.tick(&p.coeffs, x, pa, pb);
            *dac = p.last.dac;
            *err = p.state.approach_error_um(x);
            *fault = None;
        }
        out
    }

    fn tick_manual(&mut self, inputs: &ControlInputs<S>, refs: &[PosRef; S]) -> ControlOutputs<S> {
        self.law.tick_manual(inputs, refs)
    }

    fn table_position_um(&self, master: Master) -> Option<[PosUm; S]> {
        self.law.table_position_um(master)
    }

    fn null_codes(&self) -> [DacCode; S] {
        let mut codes = self.law.null_codes();
        for (c, p) in codes.iter_mut().zip(self.press.iter()) {
            if let Some(p) = p {
                *c = p.coeffs.null_code();
            }
        }
        codes
    }

    fn master_span(&self) -> Option<(Master, Master)> {
        self.law.master_span()
    }

    fn following_error_limit_um(&self, axis: usize) -> Option<PosUm> {
        if self.is_press(axis) {
            None
        } else {
            self.law.following_error_limit_um(axis)
        }
    }

    fn learned(&self, axis: usize) -> Learned {
        if self.is_press(axis) {
            Learned::NONE
        } else {
            self.law.learned(axis)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::{PressConfig, PressGains, PressPhase};
    use crate::runtime::controller::mock::MockLaw;
    use crate::runtime::LawFault;
    use crate::units::PressureBar;
    use crate::valve::ValveCal;

    fn coeffs() -> PressCoeffs {
        PressConfig {
            area_a_mm2: 5026.5,
            area_b_mm2: 3436.1,
            approach_end_um: 60_000.0,
            approach_speed_um_per_s: 10_000.0,
            contact_force_n: 5000.0,
            contact_arm_ms: 0.0,
            force_set_n: 20_000.0,
            force_ramp_ms: 1000.0,
            gains: PressGains::default(),
            valve: ValveCal::default(),
        }
        .build(1000)
        .unwrap()
    }

    fn inputs(x1_um: i32, pa_bar: i32) -> ControlInputs<2> {
        ControlInputs {
            master: Master::from_num(100),
            pos_um: [PosUm::from_num(50), PosUm::from_num(x1_um)],
            pressure_bar: [
                [PressureBar::ZERO; 2],
                [PressureBar::from_num(pa_bar), PressureBar::ZERO],
            ],
        }
    }

    #[test]
    fn without_a_press_it_is_the_inner_law() {
        let mut a = PressAxes::<_, 2>::new(MockLaw::<2>::new());
        let mut b = MockLaw::<2>::new();
        let i = inputs(10_000, 0);
        assert_eq!(a.tick(&i), b.tick(&i));
        assert_eq!(a.null_codes(), b.null_codes());
        assert_eq!(a.set_press(2, Some(coeffs())), Err(NoSuchSlave { axis: 2 }));
    }

    #[test]
    fn a_press_slave_runs_the_press_law_and_the_others_the_inner_law() {
        let mut law = MockLaw::<2>::new();
        law.axis_fault = [None, Some(LawFault::FollowingError)];
        let mut a = PressAxes::<_, 2>::new(law.clone());
        a.set_press(1, Some(coeffs())).unwrap();
        let mut st = PressState::default();
        let c = coeffs();
        for k in 0..50 {
            // the force appears at tick 30
            let i = inputs(10_000 + 10 * k, if k < 30 { 0 } else { 20 });
            let o = a.tick(&i);
            let inner = law.tick(&i);
            let p = st.tick(&c, i.pos_um[1], i.pressure_bar[1][0], i.pressure_bar[1][1]);
            assert_eq!(o.dac[0], inner.dac[0]);
            assert_eq!(o.error_um[0], inner.error_um[0]);
            assert_eq!(o.dac[1], p.dac, "tick {k}");
            assert_eq!(
                o.axis_fault[1], None,
                "the inner law's fault on a press is dropped"
            );
            assert_eq!(a.press_output(1), Some(p));
            assert_eq!(
                a.press_output(1).unwrap().phase == PressPhase::Force,
                k >= 30
            );
            if k >= 30 {
                assert_eq!(o.error_um[1], PosUm::ZERO);
            }
        }
        assert_eq!(a.null_codes()[1], c.null_code());
        assert_eq!(a.following_error_limit_um(1), None);
    }

    #[test]
    fn a_restart_restarts_the_approach_from_the_measured_position() {
        let mut a = PressAxes::<_, 2>::new(MockLaw::<2>::new());
        a.set_press(1, Some(coeffs())).unwrap();
        for _ in 0..10 {
            a.tick(&inputs(10_000, 20));
        }
        assert_eq!(a.press_output(1).unwrap().phase, PressPhase::Force);
        let i = inputs(30_000, 0);
        a.restart(&i);
        let o = a.tick(&i);
        assert_eq!(a.press_output(1).unwrap().phase, PressPhase::Approach);
        // one tick of approach from 30 mm: the reference is 10 µm ahead (10 mm/s · 1 ms)
        assert_eq!(o.error_um[1], PosUm::from_num(10));
    }
}
