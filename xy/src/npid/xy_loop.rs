//! One complete X–Y period with contour estimation: the seed-003 interpolator, the
//! seed-003 adaptive estimator and the cross-coupled nonlinear PID (the `nccc-est`
//! controller of `host-sim xy`).
//!
//! ```text
//! reference = interpolator.step(path, feed)      (pushes the new ordinary and extra points)
//! (ε, θ_f)  = window.estimate(P)                 (signed contour error, chord tangent at the foot)
//! U         = Cnp::tick_estimated(reference, P, ε, θ_f)
//! ```
//!
//! The window must cover the axes' lag: with `N` ordinary points and a feed of v µm/s at
//! period Ts it spans (N − 1)·v·Ts µm of path. If the estimator has no estimate (empty
//! window), the tick falls back to ε = 0 (independent axes for that period).
//!
//! [`EstimatedXy::tick`] is the per-period entry point: no allocation, no float, no
//! panic. Its cost is the interpolator's (1 + h path evaluations), the estimator's (N
//! squared distances, three segment distances, ⌈log₂(H + 1)⌉ bisection steps) and three
//! nonlinear PIDs (five TD steps, up to nine `β·fal` terms).

use super::ccc::{Cnp, XyCoeffs, XyOutput};
use super::contour_model::PathFrame;
use super::feedforward::{VelocityFf, VelocityFfCoeffs};
use super::npid::NpidCoeffs;
use crate::contour::{ContourWindow, InterpCoeffs, Interpolator, ParametricPath, Reference, Xy};
use hydra_core::units::{CmdLsb, PosUm, VelUmPerS};

/// Interpolator, estimation window and cross-coupled nonlinear PID of one X–Y pair.
#[derive(Clone, Debug)]
pub struct EstimatedXy<const N: usize, const H: usize> {
    window: ContourWindow<N, H>,
    interp: Interpolator,
    /// The three nonlinear PIDs.
    pub ctl: Cnp,
    /// Velocity feed-forward of X and Y.
    ff: [VelocityFf; 2],
    /// Has the feed-forward seen a reference (it starts at rest at the first one)?
    ff_primed: bool,
}

/// One period's result: the motion command and the controller's output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XyPeriod {
    /// The interpolator's reference for this period.
    pub reference: Reference,
    /// Valve commands, ε used, u_c.
    pub output: XyOutput,
}

impl<const N: usize, const H: usize> EstimatedXy<N, H> {
    /// Starts at the beginning of `path` with the controller at rest there.
    pub fn start<P: ParametricPath>(path: &P, ctl: Cnp) -> Self {
        let mut window = ContourWindow::new();
        let interp = Interpolator::start(path, &mut window);
        Self {
            window,
            interp,
            ctl,
            ff: [VelocityFf::default(); 2],
            ff_primed: false,
        }
    }

    /// The interpolator (its parameter, whether the path is finished).
    pub fn interpolator(&self) -> &Interpolator {
        &self.interp
    }

    /// One period without feed-forward: interpolate at `feed`, estimate the contour
    /// error of `measured_um`, run the cross-coupled nonlinear PID.
    ///
    /// Bit for bit [`EstimatedXy::tick_with_feedforward`] with
    /// [`VelocityFfCoeffs::NONE`], without evaluating the feed-forward: with zero gains
    /// it gives 0 and leaves each axis' state at rest at the new reference, which is
    /// what this sets.
    #[inline]
    pub fn tick<P: ParametricPath>(
        &mut self,
        interp: &InterpCoeffs,
        coeffs: &XyCoeffs<NpidCoeffs>,
        path: &P,
        feed: VelUmPerS,
        measured_um: [PosUm; 2],
    ) -> XyPeriod {
        self.period(interp, coeffs, None, path, feed, measured_um)
    }

    /// One period with velocity feed-forward `[X, Y]` computed from the new reference
    /// ([`VelocityFf`]) and added to the axis laws' outputs.
    #[inline]
    pub fn tick_with_feedforward<P: ParametricPath>(
        &mut self,
        interp: &InterpCoeffs,
        coeffs: &XyCoeffs<NpidCoeffs>,
        ff: &[VelocityFfCoeffs; 2],
        path: &P,
        feed: VelUmPerS,
        measured_um: [PosUm; 2],
    ) -> XyPeriod {
        self.period(interp, coeffs, Some(ff), path, feed, measured_um)
    }

    /// The period of both ticks (`ff = None`: zero feed-forward, see [`Self::tick`]).
    #[inline(always)]
    fn period<P: ParametricPath>(
        &mut self,
        interp: &InterpCoeffs,
        coeffs: &XyCoeffs<NpidCoeffs>,
        ff: Option<&[VelocityFfCoeffs; 2]>,
        path: &P,
        feed: VelUmPerS,
        measured_um: [PosUm; 2],
    ) -> XyPeriod {
        let reference = self.interp.step(interp, path, feed, &mut self.window);
        let r = reference.pos_um();
        match ff {
            Some([fcx, fcy]) => {
                if !self.ff_primed {
                    self.ff = [VelocityFf::at_rest(r.x), VelocityFf::at_rest(r.y)];
                    self.ff_primed = true;
                }
                let [fx, fy] = &mut self.ff;
                self.ctl
                    .set_feedforward([fx.step(fcx, r.x), fy.step(fcy, r.y)]);
            }
            None => {
                // VelocityFf::step with zero gains: output 0, state at rest at r.
                self.ff = [VelocityFf::at_rest(r.x), VelocityFf::at_rest(r.y)];
                self.ff_primed = true;
                self.ctl.set_feedforward([CmdLsb::ZERO; 2]);
            }
        }
        let [mx, my] = measured_um;
        let (eps, frame) = match self.window.estimate(Xy::new(mx, my)) {
            Some(e) => (
                e.eps_pos_um(),
                PathFrame::from_contour(e.tangent, Default::default()),
            ),
            None => (
                PosUm::ZERO,
                PathFrame::from_contour(reference.point.tangent, Default::default()),
            ),
        };
        let output = self
            .ctl
            .tick_estimated(coeffs, [r.x, r.y], measured_um, eps, &frame);
        XyPeriod { reference, output }
    }
}

#[cfg(test)]
mod tests {
    use super::super::fal::FalConfig;
    use super::super::fhan::FhanConfig;
    use super::super::npid::NpidConfig;
    use super::*;
    use crate::contour::{InterpConfig, ParabolaSpec};

    #[test]
    fn tick_is_tick_with_zero_feedforward() {
        let path = ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 20_000.0,
            axis_deg: 0.0,
            x_start_um: -5_000.0,
            x_end_um: 5_000.0,
        }
        .build()
        .unwrap();
        let ic = InterpConfig {
            period_us: 1000,
            q_s: 1.0,
            h_max: 15,
        }
        .build()
        .unwrap();
        let td = FhanConfig {
            r_um_per_s2: 5e7,
            h0_s: 1e-3,
        };
        let fal = |alpha: f64, delta: f64| FalConfig { alpha, delta };
        let law = NpidConfig {
            period_s: 1e-3,
            td_reference: td,
            td_measurement: td,
            beta0: 15.0,
            beta1: 2.9,
            beta2: 0.0,
            fal0: fal(1.0, 1.0),
            fal1: fal(0.8, 20.0),
            fal2: fal(1.0, 1.0),
            integral_limit_um_s: 66.0,
            output_limit_lsb: 2047.0,
        }
        .build()
        .unwrap();
        let c = XyCoeffs {
            x: law,
            y: law,
            contour: law,
        };
        let start = [PosUm::from_num(-5_000), PosUm::from_num(625)];
        let ctl = Cnp::at_rest(
            Default::default(),
            Default::default(),
            Default::default(),
            start,
        );
        let mut a = EstimatedXy::<16, 15>::start(&path, ctl);
        let mut b = a.clone();
        let feed = VelUmPerS::from_num(50_000);
        let mut m = start;
        for k in 0..300 {
            let ripple = PosUm::from_bits((k % 7 - 3) << 8);
            let pa = a.tick(&ic, &c, &path, feed, m);
            let pb = b.tick_with_feedforward(&ic, &c, &[VelocityFfCoeffs::NONE; 2], &path, feed, m);
            assert_eq!(pa, pb);
            assert_eq!(a.ctl, b.ctl);
            assert_eq!(a.ff, b.ff);
            let r = pa.reference.pos_um();
            m = [r.x + ripple, r.y - ripple];
        }
    }
}
