//! The step test's law: P-only position control of one axis toward a reference that
//! steps after [`STEP_DELAY_TICKS`] ticks, run by the runtime like every law of a run
//! (`TickLoop::run` over a [`crate::sim::board::SampledBoard`]).
//!
//! ```text
//! x_ref(k) = x_0            k < 3
//!          = x_0 + Δx       k ≥ 3          µm (x_0 the quantised start, Δx the step)
//! u(k)     = law(x_ref(k) − x(k))          the axis law's own form (positional or
//!                                          incremental), LSB → the valve's output stage
//! ```

use hydra_core::axis::{position_law, AxisCoeffs, PosRef, PosState};
use hydra_core::runtime::{ControlInputs, ControlOutputs, Controller};
use hydra_core::units::{DacCode, PosUm};

/// Ticks at the start reference before the step.
pub const STEP_DELAY_TICKS: u32 = 3;

/// One axis' step test law (see the module docs).
#[derive(Clone, Debug)]
pub struct StepLaw {
    coeffs: AxisCoeffs,
    state: PosState,
    /// The reference before and after the step, µm.
    refs_um: [PosUm; 2],
    ticks: u32,
}

impl StepLaw {
    /// The law with axis coefficients `coeffs` stepping from `from_um` to `to_um`.
    pub fn new(coeffs: AxisCoeffs, from_um: PosUm, to_um: PosUm) -> Self {
        Self {
            coeffs,
            state: PosState::default(),
            refs_um: [from_um, to_um],
            ticks: 0,
        }
    }
}

impl Controller<1> for StepLaw {
    fn restart(&mut self, _inputs: &ControlInputs<1>) {
        self.state.reset();
        self.ticks = 0;
    }

    fn tick(&mut self, inputs: &ControlInputs<1>) -> ControlOutputs<1> {
        let x_ref_um = self.refs_um[usize::from(self.ticks >= STEP_DELAY_TICKS)];
        self.ticks = self.ticks.saturating_add(1);
        let r = PosRef {
            x_ref_um,
            ..PosRef::default()
        };
        let [x] = inputs.pos_um;
        let u = position_law(&self.coeffs, &mut self.state, &r, x);
        let mut out = ControlOutputs::at([self.coeffs.valve.output(u)]);
        out.error_um = [x_ref_um.saturating_sub(x)];
        out
    }

    fn tick_manual(
        &mut self,
        _inputs: &ControlInputs<1>,
        _refs: &[PosRef; 1],
    ) -> ControlOutputs<1> {
        ControlOutputs::at(self.null_codes())
    }

    fn null_codes(&self) -> [DacCode; 1] {
        [self.coeffs.valve.null_code()]
    }
}
