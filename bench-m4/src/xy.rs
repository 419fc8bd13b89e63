//! The full X–Y cross-coupled tick with estimation (SPEC §C + §D):
//! [`EstimatedXy::tick_with_feedforward`] — one period of the interpolator (the ordinary
//! point and its extra points into the window), the adaptive contour estimate of the
//! measured point, the cross-coupled nonlinear PID (two axis laws with TD-I/TD-II and
//! three `fal` each, the contour law on ε, the distribution along the normal) and the
//! velocity feed-forward with friction compensation of both axes (host-sim's identified
//! gains: every host-sim X–Y controller runs it).
//!
//! Set-up: host-sim's X–Y scenario (`host-sim/src/xy`): the parabola y = x²/(2·20 mm),
//! x from −40 to +40 mm, feed 50 mm/s (50 µm per 1 ms period, 2 366 periods for the
//! path), Q = 1 s, window 64 ordinary points × up to 15 extra points, the nonlinear
//! gains of `crate::npid` (fal power laws with α < 1: the conservative case; the
//! tuned defaults in `xy/gains.rs` use α = 1). The measured point is the reference of three periods earlier with a
//! ±2 µm ripple (a servo lagging 150 µm along the path): the estimator searches a window
//! position well behind the newest point. The 2 300 calls of a run (warm-up included)
//! cover the path through the vertex without reaching its end.
//!
//! `xy_contour_part` ([`XyContourPart`]) is the contour half of the same tick alone —
//! [`Interpolator::step`] + [`ContourWindow::estimate`] on the same path, window, feed and
//! measured points — so the interpolator/estimator share of the X–Y budget is measured
//! directly rather than by subtraction.

use crate::harness::Figure;
use crate::npid::{axis_coeffs, contour_coeffs};
use core::hint::black_box;
use hydra_core::units::{CmdLsb, PosUm, VelUmPerS};
use hydra_xy::contour::{
    ContourEstimate, ContourWindow, InterpCoeffs, InterpConfig, Interpolator, Parabola,
    ParabolaSpec, Reference, Xy,
};
use hydra_xy::npid::{
    CrossCoupled, EstimatedXy, NpidCoeffs, VelocityFfCoeffs, VelocityFfConfig, XyCoeffs, XyPeriod,
};

/// Ordinary points in the window (host-sim `WINDOW_N`).
const N: usize = 64;
/// Extra points per segment (host-sim `WINDOW_H`).
const H: usize = 15;
/// Feed, µm/s.
const FEED_UM_PER_S: i32 = 50_000;
/// The measured point lags the reference by this many periods.
const LAG: usize = 3;

/// The measured call: one X–Y period, with the velocity feed-forward and friction
/// compensation every host-sim X–Y controller runs.
#[inline(never)]
fn tick(
    xy: &mut EstimatedXy<N, H>,
    ic: &InterpCoeffs,
    c: &XyCoeffs<NpidCoeffs>,
    ff: &[VelocityFfCoeffs; 2],
    path: &Parabola,
    measured: [PosUm; 2],
) -> XyPeriod {
    xy.tick_with_feedforward(
        ic,
        c,
        ff,
        path,
        VelUmPerS::from_num(FEED_UM_PER_S),
        measured,
    )
}

/// host-sim's identified X–Y feed-forward (`host-sim/src/xy/gains.rs` defaults): extend /
/// retract LSB per mm/s, friction deflection D_c µm; lead 2 ms, reversal band 4 mm/s.
fn feedforward() -> Option<[VelocityFfCoeffs; 2]> {
    let ff = |k: [f64; 2], d_c: f64| {
        VelocityFfConfig {
            period_s: 1e-3,
            extend_lsb_per_mm_s: k[0],
            retract_lsb_per_mm_s: k[1],
            lead_s: 0.002,
            friction_deflection_um: d_c,
            friction_speed_mm_s: 4.0,
        }
        .build()
        .ok()
    };
    Some([ff([13.713, 16.766], 10.732)?, ff([19.410, 23.818], 10.683)?])
}

/// The measured point of call `k`: the reference `LAG` periods back (`refs` holds the
/// last `LAG + 1`, newest at `k % (LAG + 1)`), with a ±2 µm ripple.
#[inline(always)]
fn lagged(refs: &[[PosUm; 2]; LAG + 1], k: u32) -> [PosUm; 2] {
    let back = (k as usize + 1) % (LAG + 1);
    let ripple = PosUm::from_bits(((k & 7) as i32 - 4) * (1 << 7));
    let [x, y] = refs[back];
    [x + ripple, y - ripple]
}

/// `xy_cross_coupled_estimated`.
pub struct XyEstimated {
    path: Parabola,
    ic: InterpCoeffs,
    c: XyCoeffs<NpidCoeffs>,
    ff: [VelocityFfCoeffs; 2],
    xy: EstimatedXy<N, H>,
    /// The last references, newest at `k % (LAG + 1)`.
    refs: [[PosUm; 2]; LAG + 1],
    measured: [PosUm; 2],
    out: Option<XyPeriod>,
}

impl XyEstimated {
    /// The controller at rest at the path's start.
    pub fn new() -> Option<Self> {
        let path = ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 20_000.0,
            axis_deg: 0.0,
            x_start_um: -40_000.0,
            x_end_um: 40_000.0,
        }
        .build()
        .ok()?;
        let ic = InterpConfig {
            period_us: 1000,
            q_s: 1.0,
            h_max: H as u16,
        }
        .build()
        .ok()?;
        let axis = axis_coeffs()?;
        let c = XyCoeffs {
            x: axis,
            y: axis,
            contour: contour_coeffs()?,
        };
        let start = [PosUm::from_num(-40_000), PosUm::from_num(40_000)];
        let ctl = CrossCoupled::at_rest(
            Default::default(),
            Default::default(),
            Default::default(),
            start,
        );
        Some(Self {
            xy: EstimatedXy::start(&path, ctl),
            path,
            ic,
            c,
            ff: feedforward()?,
            refs: [start; LAG + 1],
            measured: start,
            out: None,
        })
    }

    /// The measured point of call `k` ([`lagged`]).
    #[inline(always)]
    fn next_inputs(&mut self, k: u32) {
        self.measured = lagged(&self.refs, k);
    }
}

impl Figure for XyEstimated {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.next_inputs(k);
        let per = tick(
            &mut self.xy,
            &self.ic,
            &self.c,
            &self.ff,
            &self.path,
            self.measured,
        );
        let r = per.reference.pos_um();
        self.refs[k as usize % (LAG + 1)] = [r.x, r.y];
        self.out = Some(per);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.next_inputs(k);
        black_box(&mut self.measured);
        let r = black_box(self.refs[0]);
        self.refs[k as usize % (LAG + 1)] = r;
        black_box(&mut self.out);
    }

    /// The path is still running and the commands are inside the DAC range.
    fn healthy(&self) -> bool {
        self.out.is_some_and(|p| {
            p.reference.advanced
                && !p.reference.finished
                && p.output
                    .command
                    .iter()
                    .all(|u| u.saturating_abs() < CmdLsb::from_num(2047))
        })
    }
}

/// The measured call of `xy_contour_part`: the contour half of one X–Y period, its
/// outputs written in place (as the control loop consumes them).
#[inline(never)]
fn contour_part(
    it: &mut Interpolator,
    w: &mut ContourWindow<N, H>,
    ic: &InterpCoeffs,
    path: &Parabola,
    measured: Xy<PosUm>,
    out: &mut (Reference, Option<ContourEstimate>),
) {
    out.0 = it.step(ic, path, VelUmPerS::from_num(FEED_UM_PER_S), w);
    out.1 = w.estimate(measured);
}

/// `xy_contour_part`: the contour half of `xy_cross_coupled_estimated` —
/// [`Interpolator::step`] + [`ContourWindow::estimate`] in the same set-up (same path,
/// window, feed and measured points), without the nonlinear PIDs.
pub struct XyContourPart {
    path: Parabola,
    ic: InterpCoeffs,
    it: Interpolator,
    window: ContourWindow<N, H>,
    refs: [[PosUm; 2]; LAG + 1],
    measured: [PosUm; 2],
    out: (Reference, Option<ContourEstimate>),
}

impl XyContourPart {
    /// At the path's start.
    pub fn new() -> Option<Self> {
        let x = XyEstimated::new()?;
        let mut window = ContourWindow::new();
        let it = Interpolator::start(&x.path, &mut window);
        Some(Self {
            path: x.path,
            ic: x.ic,
            it,
            window,
            refs: x.refs,
            measured: x.measured,
            out: (
                Reference {
                    point: Default::default(),
                    extra_points: 0,
                    advanced: false,
                    finished: false,
                },
                None,
            ),
        })
    }

    /// The measured point of call `k` ([`lagged`]).
    #[inline(always)]
    fn next_inputs(&mut self, k: u32) {
        self.measured = lagged(&self.refs, k);
    }
}

impl Figure for XyContourPart {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.next_inputs(k);
        let [mx, my] = self.measured;
        contour_part(
            &mut self.it,
            &mut self.window,
            &self.ic,
            &self.path,
            Xy::new(mx, my),
            &mut self.out,
        );
        let r = self.out.0.pos_um();
        self.refs[k as usize % (LAG + 1)] = [r.x, r.y];
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.next_inputs(k);
        black_box(&mut self.measured);
        let r = black_box(self.refs[0]);
        self.refs[k as usize % (LAG + 1)] = r;
        black_box(&mut self.out);
    }

    /// The path is still running and every call had an estimate.
    fn healthy(&self) -> bool {
        let (r, e) = &self.out;
        r.advanced && !r.finished && e.is_some()
    }
}
