//! Property tests of the contour estimator: against the `f64` ground truth within the
//! stated tolerance, and bounded bisection for any window contents.
//!
//! Stated tolerance (docs/contour.md): the adaptive estimate differs from the exact
//! signed distance by at most
//!
//! ```text
//! tol = 1.25 · s · (1 + E·κ_max) + 2 nm,
//! s   = min( ΔS²κ_max/8,  max( v·Ts²/(8Q), ΔS²κ_max/(8(H+1)²) ) )
//! ```
//!
//! s is the largest sagitta of an extra-point chord (h + 1 > Q·κ·v makes the chords
//! shorter than Ts/(Q·κ)); (1 + E·κ) covers a point E off the path; 1.25 covers the
//! change of κ along one period's segment (≤ 10 % here, ΔS ≤ ρ_min/10); 2 nm covers the
//! fixed-point rounding (0.2 nm measured).

use host_sim::contour_truth::TruthPath;
use hydra_core::units::{PosUm, VelUmPerS};
use hydra_xy::contour::{
    max_bisection_steps, ArcSpec, ContourWindow, InterpConfig, Interpolator, OrdinaryPoint,
    ParabolaSpec, Param, ParametricPath, PosFine, RelUm, UnitQ30, Xy,
};
use proptest::prelude::*;

const H: usize = 63;

#[derive(Debug, Clone)]
struct Case {
    feed_mm_s: f64,
    period_us: u32,
    q_s: f64,
    offset_um: f64,
    lag_periods: usize,
    seed: u64,
}

fn case() -> impl Strategy<Value = Case> {
    (
        10.0..600.0f64,
        250u32..=2000,
        0.25..4.0f64,
        0.0..200.0f64,
        0usize..12,
        any::<u64>(),
    )
        .prop_map(
            |(feed_mm_s, period_us, q_s, offset_um, lag_periods, seed)| Case {
                feed_mm_s,
                period_us,
                q_s,
                offset_um,
                lag_periods,
                seed,
            },
        )
}

struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Runs up to 40 periods from a random start of the path and returns the worst
/// |error| / tolerance over 3 points per period.
fn worst_ratio<P: ParametricPath>(path: &P, truth: &TruthPath, c: &Case) -> f64 {
    let coeffs = InterpConfig {
        period_us: c.period_us,
        q_s: c.q_s as f32,
        h_max: H as u16,
    }
    .build()
    .unwrap();
    let v = c.feed_mm_s * 1000.0;
    let ts = f64::from(c.period_us) * 1e-6;
    let ds = v * ts;
    let k = truth.max_curvature();
    let s = (ds * ds * k / 8.0)
        .min((v * ts * ts / (8.0 * c.q_s)).max(ds * ds * k / (8.0 * ((H + 1) as f64).powi(2))));
    let tol = 1.25 * s * (1.0 + c.offset_um * k) + 0.002;
    let mut w: Box<ContourWindow<16, H>> = Box::new(ContourWindow::new());
    let mut it = Interpolator::start(path, &mut w);
    let feed = VelUmPerS::from_num(v);
    let mut rng = Rng(c.seed);
    let mut worst = 0.0f64;
    for tick in 1..=40 {
        let r = it.step(&coeffs, path, feed, &mut w);
        if !r.advanced {
            break;
        }
        if tick > c.lag_periods {
            let u_ref = r.point.u.to_num::<f64>();
            for _ in 0..3 {
                let lag = rng.unit() * c.lag_periods as f64 * ds;
                let off = (2.0 * rng.unit() - 1.0) * c.offset_um;
                let u = truth.u_behind(u_ref, lag);
                let (b, n) = (truth.r(u), truth.left_normal(u));
                let p = Xy::new(
                    PosUm::from_num(b[0] + off * n[0]),
                    PosUm::from_num(b[1] + off * n[1]),
                );
                let exact = truth.nearest([p.x.to_num(), p.y.to_num()]).eps;
                let est = w.estimate(p).unwrap();
                let ratio = (est.eps_um.to_num::<f64>() - exact).abs() / tol;
                worst = worst.max(ratio);
            }
        }
        if r.finished {
            break;
        }
    }
    worst
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Circles of radius 5…60 mm either way round.
    #[test]
    fn adaptive_within_tolerance_on_circles(c in case(), r_mm in 5.0..60.0f64, ccw: bool, start in -180.0..180.0f64) {
        prop_assume!(c.feed_mm_s * f64::from(c.period_us) * 1e-3 <= r_mm * 100.0);
        let spec = ArcSpec {
            center_um: [-3000.0, 2000.0],
            radius_um: r_mm * 1000.0,
            start_deg: start,
            sweep_deg: if ccw { 350.0 } else { -350.0 },
        };
        let ratio = worst_ratio(&spec.build().unwrap(), &TruthPath::arc(&spec), &c);
        prop_assert!(ratio <= 1.0, "error / tolerance = {ratio}");
    }

    /// Parabolas with vertex radius 5…50 mm at any orientation, run from a random start
    /// through the vertex region.
    #[test]
    fn adaptive_within_tolerance_on_parabolas(c in case(), p_mm in 5.0..50.0f64, down: bool, axis in -180.0..180.0f64, x0 in -2.0..0.0f64) {
        prop_assume!(c.feed_mm_s * f64::from(c.period_us) * 1e-3 <= p_mm * 100.0);
        let p = p_mm * 1000.0;
        let spec = ParabolaSpec {
            vertex_um: [1000.0, -500.0],
            p_um: if down { -p } else { p },
            axis_deg: axis,
            x_start_um: x0 * p,
            x_end_um: 2.0 * p,
        };
        let ratio = worst_ratio(&spec.build().unwrap(), &TruthPath::parabola(&spec), &c);
        prop_assert!(ratio <= 1.0, "error / tolerance = {ratio}");
    }

    /// Any window contents — arbitrary positions, tangents, extra points (including
    /// absurd ones) — and any actual point: the estimate returns, its bisection takes at
    /// most ⌈log₂(h + 1)⌉ steps for the chosen segment's h, and its indices are in range.
    #[test]
    fn bisection_terminates_within_its_bound_for_any_input(
        pts in prop::collection::vec(
            ((-(1i64 << 40)..(1i64 << 40)), (-(1i64 << 40)..(1i64 << 40)), any::<i32>(), any::<i32>(),
             prop::collection::vec((any::<i32>(), any::<i32>()), 0..=H + 5)),
            1..12),
        px in -(1i32 << 30)..(1i32 << 30), py in -(1i32 << 30)..(1i32 << 30),
        near: bool,
    ) {
        let mut w: ContourWindow<8, H> = ContourWindow::new();
        for (x, y, tx, ty, ex) in &pts {
            let extras: Vec<Xy<RelUm>> = ex.iter().map(|&(a, b)| Xy::new(RelUm::from_bits(a), RelUm::from_bits(b))).collect();
            w.push(OrdinaryPoint {
                pos: Xy::new(PosFine::from_bits(*x), PosFine::from_bits(*y)),
                tangent: Xy::new(UnitQ30::from_bits(*tx), UnitQ30::from_bits(*ty)),
                u: Param::ZERO,
            }, &extras);
        }
        // Either an arbitrary point or one near the first window point.
        let p = if near {
            let s = w.point(0).unwrap().pos;
            Xy::new(
                PosUm::saturating_from_num(s.x.to_num::<f64>() + f64::from(px % 1000)),
                PosUm::saturating_from_num(s.y.to_num::<f64>() + f64::from(py % 1000)),
            )
        } else {
            Xy::new(PosUm::from_bits(px), PosUm::from_bits(py))
        };
        let e = w.estimate(p).unwrap();
        let seg = usize::from(e.segment);
        prop_assert!(seg < w.len());
        let h = w.extra_count(seg);
        prop_assert!(u32::from(e.bisection_steps) <= max_bisection_steps(h));
        prop_assert!(u32::from(e.bisection_steps) <= max_bisection_steps(H));
        prop_assert!(usize::from(e.sub_chord) <= h);
        prop_assert!(w.estimate_chord(p).is_some());
        prop_assert!(w.estimate_tangent(p).is_some());
    }
}
