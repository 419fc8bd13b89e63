//! Property tests of the S-curve over limits and distances spanning six decades each.
//!
//! Every case draws D, V, A, J log-uniformly over six decades and a period that splits
//! the move into 1 … 3000 ticks (so periods range from far shorter than a jerk phase
//! to longer than the whole move). Reference values are computed independently of the
//! planner: the optimum move time by bisection on the peak velocity, positions from the
//! plan's exact closed form.

use super::*;
use crate::units::PosUm;
use proptest::prelude::*;

/// Stated bound of a position sample against the exact profile, LSB.
const POS_BOUND_LSB: f64 = 0.5 + 1.0 / 256.0;

fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.ln()..hi.ln()).prop_map(f64::exp)
}

/// The least move time for D under V, A, J, found without the planner: with peak
/// velocity w the acceleration half lasts `ta(w)` (w/A + A/J if A is reached, else
/// 2√(w/J)) and covers w·ta(w)/2, so the move lasts ta(w) + D/w, which falls as w
/// grows; the best w is the largest w ≤ V with w·ta(w) ≤ D (bisection).
fn optimum_time(d: f64, v: f64, a: f64, j: f64) -> f64 {
    let ta = |w: f64| {
        if w >= a * a / j {
            w / a + a / j
        } else {
            2.0 * (w / j).sqrt()
        }
    };
    let fits = |w: f64| w * ta(w) <= d;
    let w = if fits(v) {
        v
    } else {
        let (mut lo, mut hi) = (0.0, v);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    ta(w) + d / w
}

#[derive(Debug, Clone, Copy)]
struct Case {
    d_lsb: u64,
    v: f64,
    a: f64,
    j: f64,
    ticks: f64,
}

fn case() -> impl Strategy<Value = Case> {
    // µm units ×256 = LSB of PosUm: D 1 µm … 1 m, V 10 µm/s … 10 m/s,
    // A 100 µm/s² … 100 m/s², J 1 mm/s³ … 1000 m/s³, 1 … 3000 periods per move.
    (
        log_uniform(1.0, 1e6),
        log_uniform(10.0, 1e7),
        log_uniform(1e2, 1e8),
        log_uniform(1e3, 1e9),
        log_uniform(1.0, 3000.0),
    )
        .prop_map(|(d, v, a, j, ticks)| Case {
            d_lsb: (d * 256.0).round() as u64,
            v: v * 256.0,
            a: a * 256.0,
            j: j * 256.0,
            ticks,
        })
}

fn limits(c: &Case) -> Limits {
    Limits {
        vel_lsb_per_s: c.v,
        acc_lsb_per_s2: c.a,
        jerk_lsb_per_s3: c.j,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn profile_properties(c in case()) {
        let plan = Plan::new(c.d_lsb, &limits(&c)).unwrap();
        let t_opt = optimum_time(c.d_lsb as f64, c.v, c.a, c.j);
        prop_assert!((plan.duration_s() - t_opt).abs() <= 1e-9 * t_opt, "{} vs {}", plan.duration_s(), t_opt);
        let t = (plan.duration_s() / c.ticks).min(MAX_PERIOD_S);
        let p = Profile::new(&plan, t).unwrap();
        let d = p.distance_lsb();
        // Duration: the last sample is the first period at or after the optimum.
        let t_last = f64::from(p.end_tick()) * t;
        prop_assert!(t_last >= t_opt * (1.0 - 1e-9) && t_last < t_opt + t * (1.0 + 1e-9));
        prop_assert_eq!(p.position_at(0), 0);
        prop_assert_eq!(p.position_at(p.end_tick()), d);
        prop_assert_eq!(p.position_at(p.end_tick().saturating_add(7)), d);

        let (vt, at2) = (c.v * t, c.a * t * t);
        let mut cur = Cursor::new();
        let mut hist = [0i64; 3];
        let mut n = 0usize;
        while !cur.done(&p) {
            let k = cur.tick();
            let s = cur.next(&p);
            let exact = plan.state_at(f64::from(k) * t);
            prop_assert!((s as f64 - exact.0).abs() <= POS_BOUND_LSB,
                "k {} s {} exact {}", k, s, exact.0);
            // Velocity and acceleration samples never exceed the limits.
            let smp = p.sample(k);
            prop_assert!(p.vel_to_lsb_per_s(smp.vel_q) <= c.v * (1.0 + 1e-12));
            prop_assert!(p.acc_to_lsb_per_s2(smp.acc_q).abs() <= c.a * (1.0 + 1e-12));
            prop_assert!(smp.vel_q >= 0);
            prop_assert_eq!(smp.pos_lsb, p.position_at(k));
            // Finite differences: monotone, |Δs| ≤ V·T, |Δ²s| ≤ A·T², each up to the
            // rounding of the samples involved (2·bound for Δ, 4·bound for Δ²).
            if n >= 1 {
                let ds = s - hist[0];
                prop_assert!(ds >= 0, "not monotone at k {}", k);
                prop_assert!((ds as f64) <= vt + 2.0 * POS_BOUND_LSB, "Δs {} > V·T {} at k {}", ds, vt, k);
            }
            if n >= 2 {
                let dds = s - 2 * hist[0] + hist[1];
                prop_assert!((dds as f64).abs() <= at2 + 4.0 * POS_BOUND_LSB,
                    "Δ²s {} > A·T² {} at k {}", dds, at2, k);
            }
            hist = [s, hist[0], hist[1]];
            n += 1;
        }
        prop_assert_eq!(hist[0], d);
        prop_assert_eq!(n, p.end_tick() as usize + 1);
    }

    #[test]
    fn line_straight_and_simultaneous(
        from in prop::array::uniform3(-1e6f64..1e6),
        to in prop::array::uniform3(-1e6f64..1e6),
        v in log_uniform(10.0, 1e7),
        a in log_uniform(1e2, 1e8),
        j in log_uniform(1e3, 1e9),
        ticks in log_uniform(1.0, 2000.0),
    ) {
        let from = from.map(PosUm::from_num);
        let to = to.map(PosUm::from_num);
        let lim = PathLimits { vel_um_per_s: v, acc_um_per_s2: a, jerk_um_per_s3: j };
        let probe = LineMove::plan(from, to, &lim, 1.0).unwrap();
        let t = (probe.profile().plan().duration_s() / ticks).min(MAX_PERIOD_S);
        let mv = LineMove::plan(from, to, &lim, t).unwrap();
        let l = mv.leader();
        let delta: [f64; 3] = core::array::from_fn(|i| f64::from(to[i].to_bits()) - f64::from(from[i].to_bits()));
        // The path's peak velocity and acceleration are the path limits or below.
        let plan = mv.profile().plan();
        prop_assert!(plan.peak_vel * mv.path_per_leader() / 256.0 <= v * (1.0 + 1e-9));
        prop_assert!(plan.peak_acc * mv.path_per_leader() / 256.0 <= a * (1.0 + 1e-9));
        let mut cur = Cursor::new();
        let mut prev = from;
        while !cur.done(mv.profile()) {
            let x = mv.next(&mut cur);
            let sl = f64::from(x[l].to_bits()) - f64::from(from[l].to_bits());
            for i in 0..3 {
                let xi = f64::from(x[i].to_bits()) - f64::from(from[i].to_bits());
                // On the line through the leader's point, within ½ LSB per axis.
                prop_assert!((xi - delta[i] / delta[l] * sl).abs() <= 0.5 + 1e-6);
                // Every axis moves monotonically toward its target.
                let step = f64::from(x[i].to_bits()) - f64::from(prev[i].to_bits());
                prop_assert!(step * delta[i] >= 0.0);
            }
            prev = x;
        }
        // All axes arrive together, exactly, at the last tick.
        prop_assert_eq!(prev, to);
        prop_assert_eq!(mv.axes_at_tick(mv.profile().end_tick()), to);
        prop_assert_eq!(mv.axes_at_tick(0), from);
    }
}

/// The largest deviation from the exact profile over many random moves, so the bound
/// in the docs is a measured figure: run with `--nocapture` to print it.
#[test]
fn measured_error_bound() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let (mut worst, mut pure_steps_back, mut samples) = (0.0f64, 0u64, 0u64);
    for _ in 0..300 {
        let c = case().new_tree(&mut runner).unwrap().current();
        let plan = Plan::new(c.d_lsb, &limits(&c)).unwrap();
        let t = (plan.duration_s() / c.ticks).min(MAX_PERIOD_S);
        let p = Profile::new(&plan, t).unwrap();
        let mut prev = 0;
        for k in 0..=p.end_tick() {
            let s = p.position_at(k);
            let exact = plan.state_at(f64::from(k) * t).0;
            worst = worst.max((s as f64 - exact).abs());
            pure_steps_back += u64::from(s < prev);
            prev = s;
            samples += 1;
        }
    }
    std::println!(
        "S-curve: {samples} samples, max |error| = {worst:.6} LSB, pure-function steps back: {pure_steps_back}"
    );
    assert!(worst <= POS_BOUND_LSB);
}
