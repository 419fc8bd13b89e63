//! Contour-estimation figures (SPEC §C) on the patent's test path: a parabola.
//!
//! Set-up (the host-sim `contour-estimate` defaults): parabola y = x²/(2p), p = 10 mm,
//! x from −20 mm to +20 mm (vertex radius 10 mm), feed 200 mm/s, Ts = 1 ms
//! (ΔS = 200 µm per period), the firmware's window [`DefaultWindow`] (16 ordinary points,
//! up to 63 extra points per segment).
//!
//! * `contour_interp_step`: [`Interpolator::step`] — one period of the parametric
//!   interpolator: the ordinary point (the motion command) and the segment's extra
//!   points h = ⌊Q·κ·v⌋ (Q = 1 s: h = 20 at the vertex) written into the window. Averaged
//!   over the first 256 periods of the path (x from −20 mm through the vertex to
//!   +10 mm); the path restarts every 256 calls in both the call and the baseline loop.
//! * `contour_estimate_typical`: [`ContourWindow::estimate`] with the window as it is
//!   8 periods past the vertex (the path's highest curvature: the most extra points),
//!   for 64 actual points P lagging the reference by 0 … 10 periods and ±50 µm off the
//!   path (a spread like host-sim's).
//! * `contour_estimate_worst`: the estimator's worst case: Q = 1000 s so every segment
//!   holds the full 63 extra points (6 bisection steps), the window full; P swept over
//!   lags 0 … 15 periods in half periods × offsets −200, 0, +200 µm (93 points, each
//!   timed over 32 calls) and the costliest point measured; the profile run traces the
//!   point the sweep picked (`bench-m4.sh` passes it on the command line).

use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::units::{PosUm, VelUmPerS};
use hydra_xy::contour::{
    ContourEstimate, DefaultWindow, InterpCoeffs, InterpConfig, Interpolator, Parabola,
    ParabolaSpec, Reference, Xy,
};

/// Feed, µm/s.
const FEED_UM_PER_S: i32 = 200_000;
/// Calls between two restarts of the interpolator figure.
const RESTART_EVERY: u32 = 256;

/// The patent-test parabola, run from `x_start_um` (−20 mm: the whole test path).
fn parabola_from(x_start_um: f64) -> Option<Parabola> {
    ParabolaSpec {
        vertex_um: [0.0, 0.0],
        p_um: 10_000.0,
        axis_deg: 0.0,
        x_start_um,
        x_end_um: 20_000.0,
    }
    .build()
    .ok()
}

/// The patent-test parabola.
fn parabola() -> Option<Parabola> {
    parabola_from(-20_000.0)
}

/// The window 8 periods past the vertex: the same parabola started 1.5 mm before the
/// vertex and run 16 periods (the window's 16 ordinary points span 7 periods before to
/// 8.5 after the vertex). Starting close by keeps the set-up out of the profile trace.
fn window_past_vertex(q_s: f32) -> Option<DefaultWindow> {
    window_after(&parabola_from(-1_500.0)?, q_s, 16)
}

fn coeffs(q_s: f32) -> Option<InterpCoeffs> {
    InterpConfig {
        period_us: 1000,
        q_s,
        h_max: 63,
    }
    .build()
    .ok()
}

fn feed() -> VelUmPerS {
    VelUmPerS::from_num(FEED_UM_PER_S)
}

/// The window after `ticks` periods of the interpolator at `q_s`.
fn window_after(path: &Parabola, q_s: f32, ticks: u32) -> Option<DefaultWindow> {
    let c = coeffs(q_s)?;
    let mut w = DefaultWindow::new();
    let mut it = Interpolator::start(path, &mut w);
    for _ in 0..ticks {
        it.step(&c, path, feed(), &mut w);
    }
    (w.len() == w.capacity()).then_some(w)
}

/// The actual point `lag` periods behind the newest ordinary point (linear between
/// ordinary points) and `offset_um` along the left normal (set-up only, f64).
fn point_behind(w: &DefaultWindow, lag: f64, offset_um: f64) -> Option<Xy<PosUm>> {
    let newest = w.len().checked_sub(1)? as f64;
    let at = (newest - lag).max(0.0);
    let i = at as usize;
    let frac = at - i as f64;
    let a = w.point(i)?;
    let b = w.point((i + 1).min(w.len() - 1))?;
    let (ax, ay) = (a.pos.x.to_num::<f64>(), a.pos.y.to_num::<f64>());
    let (bx, by) = (b.pos.x.to_num::<f64>(), b.pos.y.to_num::<f64>());
    let (tx, ty) = (a.tangent.x.to_num::<f64>(), a.tangent.y.to_num::<f64>());
    let x = ax + (bx - ax) * frac - ty * offset_um;
    let y = ay + (by - ay) * frac + tx * offset_um;
    Some(Xy::new(PosUm::from_num(x), PosUm::from_num(y)))
}

/// The measured call: one estimate.
#[inline(never)]
fn estimate(w: &DefaultWindow, p: Xy<PosUm>) -> Option<ContourEstimate> {
    w.estimate(p)
}

/// `contour_estimate_typical`.
pub struct EstimateTypical {
    window: DefaultWindow,
    points: [Xy<PosUm>; 64],
    out: Option<ContourEstimate>,
}

impl EstimateTypical {
    /// The window 8 periods past the vertex (Q = 1 s) and the 64 actual points.
    pub fn new() -> Option<Self> {
        let window = window_past_vertex(1.0)?;
        let mut points = [Xy::new(PosUm::ZERO, PosUm::ZERO); 64];
        for (j, p) in points.iter_mut().enumerate() {
            // A deterministic spread: lag 0 … 10 periods, offset −50 … +50 µm.
            let lag = ((j * 37) % 64) as f64 / 63.0 * 10.0;
            let off = (((j * 23) % 64) as f64 / 63.0 * 2.0 - 1.0) * 50.0;
            *p = point_behind(&window, lag, off)?;
        }
        Some(Self {
            window,
            points,
            out: None,
        })
    }
}

impl Figure for EstimateTypical {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        let p = self.points[(k % 64) as usize];
        self.out = estimate(&self.window, p);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        black_box(self.points[(k % 64) as usize]);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        self.out.is_some_and(|e| !e.saturated)
    }

    fn profile_warm_up(&self) -> u32 {
        0
    }
}

/// One fixed actual point against a fixed window.
struct FixedPoint<'a> {
    window: &'a DefaultWindow,
    p: Xy<PosUm>,
    out: Option<ContourEstimate>,
}

impl Figure for FixedPoint<'_> {
    #[inline(always)]
    fn call(&mut self, _k: u32) {
        self.out = estimate(self.window, black_box(self.p));
    }

    #[inline(always)]
    fn baseline(&mut self, _k: u32) {
        black_box(self.p);
        black_box(&mut self.out);
    }
}

/// `contour_estimate_worst`.
pub struct EstimateWorst {
    window: DefaultWindow,
    p: Xy<PosUm>,
    /// Lag of P behind the reference, half periods, and its offset from the path, µm.
    lag2: u32,
    offset_um: i32,
    out: Option<ContourEstimate>,
}

/// How [`EstimateWorst`] picks its actual point P.
#[derive(Clone, Copy)]
pub enum WorstPick {
    /// Time the 93 candidates (SysTick, 32 calls each) and keep the costliest.
    Sweep,
    /// The candidate a sweep picked (profile run): lag in half periods, offset in µm.
    Given(u32, i32),
}

impl EstimateWorst {
    /// The full-extra-points window and P picked by `pick`.
    pub fn new(pick: WorstPick) -> Option<Self> {
        let window = window_past_vertex(1000.0)?;
        let (mut lag2, mut offset_um) = match pick {
            WorstPick::Given(l2, off) => (l2, off),
            WorstPick::Sweep => (15, 200),
        };
        let mut p = point_behind(&window, f64::from(lag2) / 2.0, f64::from(offset_um))?;
        if let WorstPick::Sweep = pick {
            let mut worst = 0;
            for l2 in 0..=30u32 {
                for off in [-200, 0, 200] {
                    let cand = point_behind(&window, f64::from(l2) / 2.0, f64::from(off))?;
                    let mut f = FixedPoint {
                        window: &window,
                        p: cand,
                        out: None,
                    };
                    let t = crate::harness::measure_calls(&mut f, 32);
                    if t > worst {
                        (worst, p, lag2, offset_um) = (t, cand, l2, off);
                    }
                }
            }
        }
        Some(Self {
            window,
            p,
            lag2,
            offset_um,
            out: None,
        })
    }
}

impl Figure for EstimateWorst {
    #[inline(always)]
    fn call(&mut self, _k: u32) {
        self.out = estimate(&self.window, black_box(self.p));
    }

    #[inline(always)]
    fn baseline(&mut self, _k: u32) {
        black_box(self.p);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        self.out
            .is_some_and(|e| !e.saturated && e.bisection_steps == 6)
    }

    fn profile_warm_up(&self) -> u32 {
        0
    }

    fn describe(&self, w: &mut dyn core::fmt::Write) {
        // `select=<lag2>:<offset>` is read back by bench-m4.sh for the profile run.
        let _ = write!(
            w,
            " select={}:{} (P lags {} half periods, {} µm off the path",
            self.lag2, self.offset_um, self.lag2, self.offset_um
        );
        if let Some(e) = self.out {
            let _ = write!(
                w,
                "; segment {}, chord {}, {} bisection steps",
                e.segment, e.sub_chord, e.bisection_steps
            );
        }
        let _ = write!(w, ")");
    }
}

/// The measured call: one interpolator period.
#[inline(never)]
fn interp_step(
    it: &mut Interpolator,
    c: &InterpCoeffs,
    path: &Parabola,
    w: &mut DefaultWindow,
) -> Reference {
    it.step(c, path, feed(), w)
}

/// `contour_interp_step`.
pub struct InterpStep {
    path: Parabola,
    coeffs: InterpCoeffs,
    window: DefaultWindow,
    it: Interpolator,
    out: Option<Reference>,
}

impl InterpStep {
    /// The parabola at its start, Q = 1 s.
    pub fn new() -> Option<Self> {
        let path = parabola()?;
        let mut window = DefaultWindow::new();
        let it = Interpolator::start(&path, &mut window);
        Some(Self {
            path,
            coeffs: coeffs(1.0)?,
            window,
            it,
            out: None,
        })
    }

    /// Every [`RESTART_EVERY`] calls (in both loops): back to the path's start.
    #[inline(always)]
    fn restart(&mut self, k: u32) {
        if k.is_multiple_of(RESTART_EVERY) {
            self.it = Interpolator::start(&self.path, &mut self.window);
        }
    }
}

impl Figure for InterpStep {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.restart(k);
        self.out = Some(interp_step(
            &mut self.it,
            &self.coeffs,
            &self.path,
            &mut self.window,
        ));
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.restart(k);
        black_box(&mut self.it);
        black_box(&mut self.window);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        self.out.is_some_and(|r| r.advanced && !r.finished)
    }

    /// One call after the restart at k = 0 (the restart is not traced).
    fn profile_warm_up(&self) -> u32 {
        1
    }
}
