//! Contour-error estimation (SPEC §C): exactness on a straight line, the sign convention
//! on both sides of a line, circle and parabola, against the `f64` ground truth.

use host_sim::contour_truth::TruthPath;
use hydra_core::units::{PosUm, VelUmPerS};
use hydra_xy::contour::{
    ArcSpec, ContourWindow, InterpConfig, Interpolator, LineSpec, ParabolaSpec, ParametricPath, Xy,
};

type Win = ContourWindow<32, 63>;

/// One compared point: the three estimates, the exact ε and the reference point/tangent.
struct Cmp {
    adaptive: f64,
    chord: f64,
    tangent: f64,
    exact: f64,
    offset: f64,
    p: [f64; 2],
    reference: [f64; 2],
    ref_tangent: [f64; 2],
    u_foot: f64,
    u_exact: f64,
    foot: [f64; 2],
    foot_exact: [f64; 2],
}

/// Runs `path` at `feed_mm_s` (1 ms, Q = 1 s) and, every period after the first
/// `lag_periods`, places points behind the reference by each `lags` fraction of
/// `lag_periods` periods and off the path by each of `offsets` µm along the left normal.
fn run<P: ParametricPath>(
    path: &P,
    truth: &TruthPath,
    feed_mm_s: f64,
    lag_periods: usize,
    lags: &[f64],
    offsets: &[f64],
) -> Vec<Cmp> {
    let coeffs = InterpConfig::default().build().unwrap();
    let mut w: Box<Win> = Box::new(ContourWindow::new());
    let mut it = Interpolator::start(path, &mut w);
    let feed = VelUmPerS::from_num(feed_mm_s * 1000.0);
    let ds = feed_mm_s; // µm per 1 ms period
    let mut out = Vec::new();
    for tick in 1..100_000 {
        let r = it.step(&coeffs, path, feed, &mut w);
        if !r.advanced {
            break;
        }
        if tick > lag_periods {
            let u_ref = r.point.u.to_num::<f64>();
            for &lf in lags {
                for &off in offsets {
                    let u = truth.u_behind(u_ref, lf * lag_periods as f64 * ds);
                    let (b, n) = (truth.r(u), truth.left_normal(u));
                    let p = Xy::new(
                        PosUm::from_num(b[0] + off * n[0]),
                        PosUm::from_num(b[1] + off * n[1]),
                    );
                    let pf = [p.x.to_num::<f64>(), p.y.to_num::<f64>()];
                    let t = r.point.tangent;
                    let est = w.estimate(p).unwrap();
                    let near = truth.nearest(pf);
                    out.push(Cmp {
                        adaptive: est.eps_um.to_num(),
                        u_foot: est.u_foot.to_num(),
                        u_exact: near.u,
                        foot: [est.foot.x.to_num(), est.foot.y.to_num()],
                        foot_exact: near.foot,
                        chord: w.estimate_chord(p).unwrap().eps_um.to_num(),
                        tangent: w.estimate_tangent(p).unwrap().to_num(),
                        exact: near.eps,
                        offset: off,
                        p: pf,
                        reference: [r.point.pos.x.to_num(), r.point.pos.y.to_num()],
                        ref_tangent: [t.x.to_num(), t.y.to_num()],
                    });
                }
            }
        }
        if r.finished {
            break;
        }
    }
    assert!(!out.is_empty());
    out
}

const LAGS: [f64; 4] = [0.0, 0.3, 0.77, 1.0];
const OFFSETS: [f64; 6] = [-50.0, -7.3, -0.01, 0.02, 3.1, 50.0];

/// On a straight line every method is exact up to the fixed-point rounding (points to
/// 0.24 nm, the actual point to 3.9 nm but the truth uses the rounded point): measured
/// 0.2 nm; the test allows 1 nm. The estimate also equals SPEC §D's line formula
/// ε = −sin θ·E1 + cos θ·E2 with E = V − P at the reference V.
#[test]
fn straight_line_is_exact_for_every_method() {
    for (end, feed) in [
        ([40_000.0, 30_000.0], 200.0),
        ([-25_000.0, 3_000.0], 500.0),
        ([0.0, -20_000.0], 50.0),
        ([13_000.0, 13_000.0], 1000.0),
    ] {
        let spec = LineSpec {
            start_um: [1234.5, -987.25],
            end_um: end,
        };
        let line = spec.build().unwrap();
        let truth = TruthPath::line(&spec);
        let rows = run(&line, &truth, feed, 10, &LAGS, &OFFSETS);
        for c in &rows {
            for (name, v) in [
                ("adaptive", c.adaptive),
                ("chord", c.chord),
                ("tangent", c.tangent),
            ] {
                assert!(
                    (v - c.exact).abs() < 1e-3,
                    "{name} {v} vs exact {} (end {end:?})",
                    c.exact
                );
            }
            // SPEC §D, line: ε = −sin θ·(x_V − x_P) + cos θ·(y_V − y_P).
            let (e1, e2) = (c.reference[0] - c.p[0], c.reference[1] - c.p[1]);
            let eps_d = -c.ref_tangent[1] * e1 + c.ref_tangent[0] * e2;
            assert!(
                (c.adaptive - eps_d).abs() < 1e-3,
                "{} vs §D {eps_d}",
                c.adaptive
            );
        }
    }
}

/// Sign convention: ε > 0 when P is right of the direction of travel, < 0 when left, on
/// a line, a counter-clockwise and a clockwise circle and a parabola opening either way;
/// the ground truth agrees and |ε| is the offset.
#[test]
fn sign_convention_on_both_sides() {
    let check = |rows: Vec<Cmp>, what: &str| {
        for c in rows {
            let want = -c.offset; // offset is along the left normal
            assert_eq!(c.exact.signum(), want.signum(), "{what}: truth sign");
            assert_eq!(
                c.adaptive.signum(),
                want.signum(),
                "{what}: {} for offset {}",
                c.adaptive,
                c.offset
            );
            // Within the stated tolerance (≤ 300 mm/s, Ts = 1 ms, Q = 1 s: 0.047 µm).
            assert!(
                (c.adaptive - c.exact).abs() < 0.05,
                "{what}: {} vs {}",
                c.adaptive,
                c.exact
            );
            assert!(
                (c.exact.abs() - c.offset.abs()).abs() < 0.01,
                "{what}: |ε| {} vs {}",
                c.exact,
                c.offset
            );
        }
    };
    let offs = [-40.0, -1.0, 1.0, 40.0];
    let line = LineSpec {
        start_um: [0.0, 0.0],
        end_um: [-30_000.0, 10_000.0],
    };
    check(
        run(
            &line.build().unwrap(),
            &TruthPath::line(&line),
            200.0,
            5,
            &[0.0, 0.5, 1.0],
            &offs,
        ),
        "line",
    );
    for sweep in [300.0, -300.0] {
        let arc = ArcSpec {
            center_um: [5000.0, 5000.0],
            radius_um: 8000.0,
            start_deg: 20.0,
            sweep_deg: sweep,
        };
        check(
            run(
                &arc.build().unwrap(),
                &TruthPath::arc(&arc),
                300.0,
                5,
                &[0.0, 0.5, 1.0],
                &offs,
            ),
            if sweep > 0.0 {
                "ccw circle"
            } else {
                "cw circle"
            },
        );
    }
    for (p, axis) in [(10_000.0, 0.0), (-6_000.0, 75.0)] {
        let par = ParabolaSpec {
            vertex_um: [100.0, -200.0],
            p_um: p,
            axis_deg: axis,
            x_start_um: -15_000.0,
            x_end_um: 15_000.0,
        };
        check(
            run(
                &par.build().unwrap(),
                &TruthPath::parabola(&par),
                250.0,
                5,
                &[0.0, 0.5, 1.0],
                &offs,
            ),
            "parabola",
        );
    }
}

/// Inside a counter-clockwise circle is left of travel: negative; outside positive.
#[test]
fn circle_inside_is_negative_for_counter_clockwise() {
    let arc = ArcSpec {
        center_um: [0.0, 0.0],
        radius_um: 10_000.0,
        start_deg: 0.0,
        sweep_deg: 90.0,
    };
    let path = arc.build().unwrap();
    let coeffs = InterpConfig::default().build().unwrap();
    let mut w: Box<Win> = Box::new(ContourWindow::new());
    let mut it = Interpolator::start(&path, &mut w);
    for _ in 0..20 {
        it.step(&coeffs, &path, VelUmPerS::from_num(200_000), &mut w);
    }
    // Reference near angle 0.4 rad; a point on the 0.35 rad ray.
    let ray = |r: f64| {
        Xy::new(
            PosUm::from_num(r * 0.35f64.cos()),
            PosUm::from_num(r * 0.35f64.sin()),
        )
    };
    let inside = w.estimate(ray(9_970.0)).unwrap().eps_um.to_num::<f64>();
    let outside = w.estimate(ray(10_030.0)).unwrap().eps_um.to_num::<f64>();
    assert!((inside + 30.0).abs() < 0.01, "{inside}");
    assert!((outside - 30.0).abs() < 0.01, "{outside}");
}

/// The foot point and its path parameter. The perpendicular foot on the final chord
/// lies within e·L/(2ρ) of the exact foot (the chord's tilt against the normal at a
/// point e off the path: 0.025 µm for e = 50 µm, L = 10 µm, ρ = 10 mm). `u_foot` is
/// interpolated linearly over the ordinary segment: for an arc-length parameter (circle)
/// it is as good as the foot (measured 0.033 µm); otherwise off by up to
/// ΔS²·|d²u/ds²|/8 more (0.55 µm of u on the default parabola at 500 mm/s, measured
/// 0.87 µm; a tangent-angle error below 10⁻⁴ rad).
#[test]
fn foot_point_and_parameter_match_the_exact_foot() {
    let par = ParabolaSpec {
        vertex_um: [0.0, 0.0],
        p_um: 10_000.0,
        axis_deg: 0.0,
        x_start_um: -20_000.0,
        x_end_um: 20_000.0,
    };
    let arc = ArcSpec {
        center_um: [0.0, 10_000.0],
        radius_um: 10_000.0,
        start_deg: -90.0,
        sweep_deg: 360.0,
    };
    // The full circle's start and end are the same point: compare u modulo its length.
    let circ = TruthPath::arc(&arc).domain().1;
    let worst = |rows: Vec<Cmp>| {
        let (mut du, mut df) = (0.0f64, 0.0f64);
        for c in &rows {
            let d = (c.u_foot - c.u_exact).abs();
            du = du.max(d.min((circ - d).abs()));
            df = df.max((c.foot[0] - c.foot_exact[0]).hypot(c.foot[1] - c.foot_exact[1]));
        }
        (du, df)
    };
    let (du, df) = worst(run(
        &par.build().unwrap(),
        &TruthPath::parabola(&par),
        500.0,
        10,
        &LAGS,
        &OFFSETS,
    ));
    println!("parabola: max |u_foot − u| = {du} µm, max |F − F_exact| = {df} µm");
    assert!(du < 1.5, "{du}");
    assert!(df < 0.05, "{df}");
    let (du, df) = worst(run(
        &arc.build().unwrap(),
        &TruthPath::arc(&arc),
        500.0,
        10,
        &LAGS,
        &OFFSETS,
    ));
    println!("circle: max |u_foot − u| = {du} µm, max |F − F_exact| = {df} µm");
    assert!(du < 0.1, "{du}");
    assert!(df < 0.05, "{df}");
}
