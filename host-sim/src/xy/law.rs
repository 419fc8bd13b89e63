//! The X–Y controllers as a runtime law: the interpolator, the feed schedule and one of
//! the four controllers behind core's [`Controller`] trait, so an `xy` run goes through
//! the core's [`hydra_core::runtime::Runtime`] as the board's laws do — its fault rules
//! (following error per axis, encoder plausibility) live, a latched fault unpowering the
//! valves.
//!
//! The runtime's master is its time master (`MasterSource::Time`: one count per tick while
//! following, frozen while holding), so tick k of the run is master count k and the feed
//! schedule's time is k · 1 ms. At the path's end the law reports the end of its table:
//! the runtime holds, the law keeps regulating at the final reference point.
//!
//! Outputs: the valve command in DAC LSB rounded to the DAC's integer code (±2047 clamp),
//! as the board writes it; the following error of each axis is reference − measured, µm.

use super::gains::Gains;
use super::{ControllerKind, XyScenario, RAMP_S, TS, WINDOW_H, WINDOW_N};
use crate::contour_truth::TruthPath;
use anyhow::Result;
use hydra_core::runtime::{ControlInputs, ControlOutputs, Controller};
use hydra_core::units::{DacCode, PosUm, VelUmPerS};
use hydra_xy::contour::{
    curvature_per_m, ContourWindow, InterpCoeffs, InterpConfig, Interpolator, ParametricPath,
};
use hydra_xy::npid::{
    Ccc, Cnp, CrossCoupled, EstimatedXy, NpidCoeffs, PathFrame, PidCoeffs, VelocityFf,
    VelocityFfCoeffs, XyCoeffs, XyOutput,
};

/// The controller of a run.
enum Ctl {
    Linear(Ccc, XyCoeffs<PidCoeffs>, bool),
    Nonlinear(Cnp, XyCoeffs<NpidCoeffs>),
    Estimated(Box<EstimatedXy<WINDOW_N, WINDOW_H>>, XyCoeffs<NpidCoeffs>),
}

/// What the law computed at its last tick (for the trace).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct XyTick {
    /// Reference point, path coordinates, µm.
    pub reference_um: [f64; 2],
    /// Valve commands before rounding to DAC codes, LSB.
    pub command_lsb: [f64; 2],
    /// The controller's ε (model or estimate), µm.
    pub controller_contour_um: f64,
    /// The interpolator reached the path's end.
    pub finished: bool,
}

/// The X–Y law of one run over `path` (exact geometry `truth` for the feed schedule).
pub struct XyLaw<'a, P: ParametricPath> {
    path: &'a P,
    truth: &'a TruthPath,
    interp_c: InterpCoeffs,
    ctl: Ctl,
    ffc: [VelocityFfCoeffs; 2],
    ff: [VelocityFf; 2],
    window: Box<ContourWindow<WINDOW_N, WINDOW_H>>,
    interp: Interpolator,
    total_len: f64,
    feed: f64,
    decel: f64,
    u_path: f64,
    /// The last tick.
    pub last: XyTick,
}

fn um(v: f64) -> PosUm {
    PosUm::saturating_from_num(v)
}

impl<'a, P: ParametricPath> XyLaw<'a, P> {
    /// The law of `s` at rest at the path's start.
    pub fn new(s: &XyScenario, path: &'a P, truth: &'a TruthPath) -> Result<Self> {
        let interp_c = InterpConfig {
            period_us: 1000,
            q_s: 1.0,
            h_max: WINDOW_H as u16,
        }
        .build()
        .map_err(|e| anyhow::anyhow!("interpolator: {e:?}"))?;
        let start = truth.r(truth.domain().0);
        let g: &Gains = &s.gains;
        let p0 = [um(start[0]), um(start[1])];
        macro_rules! at_rest {
            () => {
                CrossCoupled::at_rest(
                    Default::default(),
                    Default::default(),
                    Default::default(),
                    p0,
                )
            };
        }
        let ctl = match s.controller {
            ControllerKind::Independent | ControllerKind::Ccc => {
                let c = g.linear_coeffs(s.controller == ControllerKind::Independent)?;
                Ctl::Linear(at_rest!(), c, s.controller == ControllerKind::Ccc)
            }
            ControllerKind::Nccc => Ctl::Nonlinear(at_rest!(), g.nonlinear_coeffs(false)?),
            ControllerKind::NcccEst => {
                let c = g.nonlinear_coeffs(true)?;
                Ctl::Estimated(Box::new(EstimatedXy::start(path, at_rest!())), c)
            }
        };
        let mut window: Box<ContourWindow<WINDOW_N, WINDOW_H>> = Box::default();
        let interp = Interpolator::start(path, &mut *window);
        let feed = s.feed_mm_per_s * 1000.0;
        Ok(Self {
            path,
            truth,
            interp_c,
            ctl,
            ffc: g.ff_coeffs()?,
            ff: [VelocityFf::at_rest(p0[0]), VelocityFf::at_rest(p0[1])],
            window,
            interp,
            total_len: truth.arc_length(truth.domain().1),
            feed,
            decel: feed / RAMP_S,
            u_path: truth.domain().0,
            last: XyTick::default(),
        })
    }

    /// The feed at time `t`: a cosine ramp up over [`RAMP_S`], then constant, then a
    /// constant deceleration to the end of the path (never below 0.5 mm/s), µm/s.
    fn feed_at(&self, t: f64) -> VelUmPerS {
        let ramp = if t < RAMP_S {
            0.5 - 0.5 * (std::f64::consts::PI * t / RAMP_S).cos()
        } else {
            1.0
        };
        let remaining = (self.total_len - self.truth.arc_length(self.u_path)).max(0.0);
        let f = (self.feed * ramp).min((2.0 * self.decel * remaining).sqrt().max(500.0));
        VelUmPerS::saturating_from_num(f)
    }
}

impl<P: ParametricPath> Controller<2> for XyLaw<'_, P> {
    fn restart(&mut self, _inputs: &ControlInputs<2>) {
        // Built at rest at the path's start; a run starts once.
    }

    fn tick(&mut self, inputs: &ControlInputs<2>) -> ControlOutputs<2> {
        let t = inputs.master.to_num::<f64>() * TS;
        let meas = inputs.pos_um;
        let fq = self.feed_at(t);
        let (reference, out, fin, u_now): ([PosUm; 2], XyOutput, bool, f64) = match &mut self.ctl {
            Ctl::Estimated(e, c) => {
                let per =
                    e.tick_with_feedforward(&self.interp_c, c, &self.ffc, self.path, fq, meas);
                let r = per.reference.pos_um();
                (
                    [r.x, r.y],
                    per.output,
                    per.reference.finished,
                    per.reference.point.u.to_num(),
                )
            }
            other => {
                let rf = self
                    .interp
                    .step(&self.interp_c, self.path, fq, &mut *self.window);
                let r = rf.pos_um();
                let pt = self.path.eval(rf.point.u);
                let kappa = curvature_per_m(&pt).unwrap_or_default();
                let frame = PathFrame::from_contour(rf.point.tangent, kappa);
                let refp = [r.x, r.y];
                let u_ff = [
                    self.ff[0].step(&self.ffc[0], r.x),
                    self.ff[1].step(&self.ffc[1], r.y),
                ];
                let out = match other {
                    Ctl::Linear(st, c, model) => {
                        st.set_feedforward(u_ff);
                        if *model {
                            st.tick_model(c, refp, meas, &frame)
                        } else {
                            st.tick_independent(c, refp, meas, &frame)
                        }
                    }
                    Ctl::Nonlinear(st, c) => {
                        st.set_feedforward(u_ff);
                        st.tick_model(c, refp, meas, &frame)
                    }
                    // Matched by the outer arm.
                    Ctl::Estimated(..) => XyOutput::default(),
                };
                (refp, out, rf.finished, rf.point.u.to_num())
            }
        };
        self.u_path = u_now;
        let cmd = [
            out.command[0].to_num::<f64>(),
            out.command[1].to_num::<f64>(),
        ];
        self.last = XyTick {
            reference_um: [reference[0].to_num(), reference[1].to_num()],
            command_lsb: cmd,
            controller_contour_um: out.contour_error_um.to_num(),
            finished: fin,
        };
        let mut o = ControlOutputs::at([DacCode::NULL; 2]);
        for k in 0..2 {
            o.dac[k] = DacCode::new_clamped(cmd[k].round().clamp(-4096.0, 4096.0) as i32);
            o.error_um[k] = reference[k].saturating_sub(meas[k]);
        }
        o.end_of_table = fin;
        o
    }

    /// The contouring law has no per-axis position mode: manual motion is a controller
    /// fault on both axes (the runtime latches it, valves at null).
    fn tick_manual(
        &mut self,
        _inputs: &ControlInputs<2>,
        _refs: &[hydra_core::axis::PosRef; 2],
    ) -> ControlOutputs<2> {
        ControlOutputs {
            axis_fault: [Some(hydra_core::runtime::LawFault::Other); 2],
            ..ControlOutputs::at(self.null_codes())
        }
    }

    fn null_codes(&self) -> [DacCode; 2] {
        [DacCode::NULL; 2]
    }
}
