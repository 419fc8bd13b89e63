//! Plant sanity: the simulated reference machine against the closed forms of PLANT.md.

use host_sim::cmd::open_loop::{simulate, Sample};
use host_sim::plant::HydraulicAxis;
use host_sim::scenario::{AxisCfg, Scenario};

const H: f64 = 10e-6;

fn tangent() -> (Scenario, AxisCfg) {
    let s = Scenario::default();
    let a = s.axes[0].clone();
    (s, a)
}

fn plant(cfg: &AxisCfg, s: &Scenario, x0_mm: f64) -> HydraulicAxis {
    cfg.plant(s.supply(), x0_mm * 1e-3)
}

/// Hydraulic natural frequency at mid-stroke: a small load step excites the oil spring;
/// the period of the velocity oscillation is compared with
/// `√(E·A_A²/(m·V_A) + E·A_B²/(m·V_B)) / 2π`. The Coulomb friction is removed for this
/// test (the formula is the frictionless spring-mass; a 400 N friction stops a small
/// oscillation within one cycle), the viscous friction stays (ζ ≈ 0.014).
#[test]
fn natural_frequency_at_mid_stroke() {
    let (s, mut cfg) = tangent();
    cfg.cylinder.coulomb_n = 0.0;
    let mut ax = plant(&cfg, &s, 250.0);
    let want = ax.cylinder.natural_frequency_hz(0.25);
    assert!(
        (want - 56.0).abs() < 0.5,
        "PLANT.md: about 56 Hz, formula {want}"
    );
    ax.cylinder.load_n = 1000.0; // 1 kN step: ≈ 27 µm of oil-spring compression
    let n = (0.3 / H) as usize;
    let mut v = Vec::with_capacity(n);
    for _ in 0..n {
        ax.step(0.0, H);
        v.push(ax.v_m_per_s());
    }
    let amplitude = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(amplitude < 0.05, "small step: peak speed {amplitude} m/s");
    // Upward zero crossings of the speed (the creep speed is < 0.1 % of the amplitude).
    let ups: Vec<f64> = v
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < 0.0 && w[1] >= 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) * H)
        .collect();
    assert!(ups.len() >= 10, "{} cycles", ups.len());
    let f = (ups.len() - 1) as f64 / (ups[ups.len() - 1] - ups[0]);
    eprintln!("natural frequency at mid-stroke: measured {f:.2} Hz, formula {want:.2} Hz");
    assert!(
        (f / want - 1.0).abs() < 0.05,
        "measured {f:.2} Hz, formula {want:.2} Hz"
    );
}

/// Full-opening no-load speed, closed form. At steady speed the flows through the two
/// metering lands are `A_A·v` and `A_B·v`, so `p_A = p_s − (A_A·v/K_v)²`,
/// `p_B = (A_B·v/K_v)²` extending (and mirrored retracting), and the force balance gives
///
/// ```text
/// extend:  v² = K_v²·(A_A·p_s − F_f(v)) / (A_A³ + A_B³)
/// retract: v² = K_v²·(A_B·p_s − F_f(v)) / (A_A³ + A_B³)
/// ```
///
/// with the friction `F_f(v) = c·v + F_c·tanh(v/v_s)` (solved by fixed-point iteration;
/// the leakage, 0.1 % of the flow, is left out).
fn closed_form_speed(ax: &HydraulicAxis, extend: bool) -> f64 {
    let c = &ax.cylinder;
    let (aa, ab) = (c.area_a_m2, c.area_b_m2);
    let kv = ax.valve.kv;
    let ps = ax.supply.supply_pa;
    let area = if extend { aa } else { ab };
    let mut v = 0.1;
    for _ in 0..50 {
        let ff = c.friction_n(v);
        v = kv * ((area * ps - ff) / (aa.powi(3) + ab.powi(3))).sqrt();
    }
    v
}

fn run(ax: &mut HydraulicAxis, u: f64, seconds: f64) -> Vec<Sample> {
    simulate(ax, &[(0.0, u), (seconds, u)], H, 1e-3)
}

#[test]
fn full_opening_no_load_speeds() {
    let (s, cfg) = tangent();
    for (u, x0, extend) in [(1.0, 20.0, true), (-1.0, 480.0, false)] {
        let mut ax = plant(&cfg, &s, x0);
        let want = closed_form_speed(&ax, extend);
        let r = run(&mut ax, u, 0.5);
        // Mean speed over 0.3…0.5 s (the transients have decayed by then).
        let (a, b) = (&r[300], &r[500]);
        let got = ((b.x_mm - a.x_mm) / (b.t - a.t) * 1e-3).abs();
        eprintln!(
            "full opening u = {u:+}: simulated {:.2} mm/s, closed form {:.2} mm/s",
            got * 1e3,
            want * 1e3
        );
        assert!(
            (got / want - 1.0).abs() < 0.02,
            "u = {u}: simulated {got:.5} m/s, closed form {want:.5} m/s"
        );
        // Still inside the stroke: the measurement is not an end stop's doing.
        assert!(b.x_mm > 30.0 && b.x_mm < 470.0);
    }
}

/// Hard use: full opening into the end stops and fast full reversals (cavitation on one
/// side, pressure peaks on the other). Pressures stay within `[0, 1.1·p_s]`, the piston
/// within the stroke (plus the stops' elastic deflection).
#[test]
fn pressures_within_clamps() {
    let (s, cfg) = tangent();
    let mut ax = plant(&cfg, &s, 400.0);
    let pmax = 1.1 * ax.supply.supply_pa;
    let mut lo = f64::MAX;
    let mut hi = f64::MIN;
    let (mut xmin, mut xmax) = (f64::MAX, f64::MIN);
    // 1 s into the far end stop, a 7 Hz full-opening square wave, 4.5 s into the other stop.
    let mut t = 0.0;
    while t < 6.5 {
        let u = if t < 1.0 {
            1.0
        } else if t < 2.0 {
            if ((t - 1.0) * 14.0) as i64 % 2 == 0 {
                -1.0
            } else {
                1.0
            }
        } else {
            -1.0
        };
        ax.step(u, H);
        let (pa, pb) = ax.pressures_pa();
        lo = lo.min(pa).min(pb);
        hi = hi.max(pa).max(pb);
        xmin = xmin.min(ax.x_m());
        xmax = xmax.max(ax.x_m());
        t += H;
    }
    eprintln!(
        "hard use: pressures {:.3} … {:.3} bar, x {:.4} … {:.4} mm",
        lo * 1e-5,
        hi * 1e-5,
        xmin * 1e3,
        xmax * 1e3
    );
    assert!(lo >= 0.0 && hi <= pmax, "pressures {lo} … {hi} Pa");
    // The test is not vacuous: the reversals cavitate a chamber and the stops load the
    // other to the supply pressure.
    assert!(lo < 1e5, "lowest pressure {lo} Pa");
    assert!(hi > 0.99 * ax.supply.supply_pa, "highest pressure {hi} Pa");
    assert!(xmin > -1e-4 && xmax < 0.5 + 1e-4, "x in {xmin} … {xmax} m");
    assert!(
        xmin < 1e-3 && xmax > 0.499,
        "both stops reached: {xmin} … {xmax}"
    );
}

/// Halving the RK4 step changes an open-loop response (position, speed, pressures) by
/// far less than 1 %.
#[test]
fn rk4_step_halving_open_loop() {
    let (s, cfg) = tangent();
    let cmd = [
        (0.0, 0.3),
        (0.1, -0.5),
        (0.25, 0.05),
        (0.4, 1.0),
        (0.5, 0.0),
    ];
    let a = simulate(&mut plant(&cfg, &s, 250.0), &cmd, H, 1e-3);
    let b = simulate(&mut plant(&cfg, &s, 250.0), &cmd, H / 2.0, 1e-3);
    assert_eq!(a.len(), b.len());
    let worst = |f: fn(&Sample) -> f64| {
        let span = a.iter().map(f).fold(0.0f64, |m, x| m.max(x.abs()));
        a.iter()
            .zip(&b)
            .map(|(p, q)| (f(p) - f(q)).abs())
            .fold(0.0, f64::max)
            / span
    };
    for (what, rel) in [
        ("x", worst(|r| r.x_mm - 250.0)),
        ("v", worst(|r| r.v_mm_s)),
        ("pA", worst(|r| r.pa_bar)),
        ("pB", worst(|r| r.pb_bar)),
    ] {
        assert!(
            rel < 1e-3,
            "{what}: step halving changes it by {:.4} %",
            rel * 100.0
        );
    }
}

/// At rest with the spool centred the pressures are in leakage and force balance: the
/// piston starts without a jolt and only creeps.
#[test]
fn initial_state_balanced() {
    let (s, cfg) = tangent();
    let mut ax = plant(&cfg, &s, 250.0);
    let (pa, pb) = ax.pressures_pa();
    let c = ax.cylinder;
    assert!(
        (c.hydraulic_n(pa, pb)).abs() < 1e-6,
        "force {}",
        c.hydraulic_n(pa, pb)
    );
    assert!(pa > 0.0 && pb > 0.0 && pa < 160e5 && pb < 160e5);
    let r = run(&mut ax, 0.0, 0.5);
    let last = r.last().unwrap();
    assert!(
        (last.x_mm - 250.0).abs() < 0.1,
        "creep {} mm in 0.5 s",
        last.x_mm - 250.0
    );
}
