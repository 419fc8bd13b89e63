//! The manual references on their own: the ramp's limits and deadman, braking inside
//! the position limits, S-curve moves and a move braked early.

use super::*;
use std::vec::Vec;

const T_US: u32 = 1000;

fn lim(vel_mm_s: u32, acc_mm_s2: u32, jerk_mm_s3: u32) -> MotionLimits {
    MotionLimits {
        vel_um_per_s: vel_mm_s * 1000,
        acc_um_per_s2: acc_mm_s2 * 1000,
        jerk_um_per_s3: jerk_mm_s3 * 1000,
    }
}

fn um(x: f64) -> PosUm {
    PosUm::from_num(x)
}

fn speed(mm_s: f64) -> VelUmPerS {
    VelUmPerS::from_num(mm_s * 1000.0)
}

/// Ramp state (p, v, a) of axis 0 in µm, µm/s, µm/s² (f64).
fn ramp_state(m: &Manual<1>) -> Option<(f64, f64, f64)> {
    match m.axes[0] {
        AxisMotion::Ramp(r) => {
            let q = (1u64 << Q) as f64;
            let t = f64::from(T_US) * 1e-6;
            Some((r.p as f64 / q, r.v as f64 / q / t, r.a as f64 / q / t / t))
        }
        _ => None,
    }
}

/// Runs `n` ticks; the references.
fn run(m: &mut Manual<1>, n: usize) -> Vec<PosRef> {
    (0..n).map(|_| m.step()[0]).collect()
}

#[test]
fn a_jog_respects_acceleration_and_jerk_then_the_deadman_stops_it() {
    let mut m = Manual::<1>::holding(&[um(10_000.0)], T_US);
    let l = lim(0, 200, 4000);
    m.jog(0, speed(20.0), &l, None).unwrap();
    let (mut prev_a, mut top_v) = (0.0f64, 0.0f64);
    let mut reached = None;
    for k in 0..2000 {
        m.step();
        let Some((_, v, a)) = ramp_state(&m) else {
            break;
        };
        assert!(a.abs() <= 200_000.0 * 1.0001, "tick {k}: a = {a}");
        assert!(
            (a - prev_a).abs() <= 4_000_000.0 * 1e-3 * 1.0001,
            "tick {k}: jerk"
        );
        assert!(v <= 20_000.0 * 1.0001, "tick {k}: v = {v}");
        top_v = top_v.max(v);
        if reached.is_none() && v == 20_000.0 {
            reached = Some(k);
        }
        prev_a = a;
    }
    // 20 mm/s at 200 mm/s² and 4 m/s³: 0.05 s jerk + 0.05 s constant + 0.05 s jerk.
    let k = reached.expect("reached the jog speed");
    assert!((140..=160).contains(&k), "reached 20 mm/s at tick {k}");
    assert_eq!(top_v, 20_000.0);
    // No renewal: the deadman (300 ms) brakes it to rest, then it holds.
    assert_eq!(m.kinds(), [ManualKind::Hold]);
    assert!(m.at_rest());
}

#[test]
fn renewing_a_jog_keeps_it_going_and_speed_zero_brakes() {
    let mut m = Manual::<1>::holding(&[um(0.0)], T_US);
    let l = lim(0, 500, 10_000);
    for _ in 0..10 {
        m.jog(0, speed(-5.0), &l, None).unwrap();
        run(&mut m, 100);
    }
    let (p, v, _) = ramp_state(&m).unwrap();
    assert_eq!(v, -5000.0);
    // 1 s at 5 mm/s less the ramp (A not reached: 2·√(v/J) = 45 ms, ≈ 0.11 mm lost).
    assert!((-4900.0..-4880.0).contains(&p), "p = {p}");
    m.jog(0, speed(0.0), &l, None).unwrap();
    let refs = run(&mut m, 200);
    assert!(m.at_rest());
    // Braking never reverses: the reference is monotone down.
    for w in refs.windows(2) {
        assert!(w[1].x_ref_um <= w[0].x_ref_um);
    }
}

#[test]
fn a_referenced_jog_stops_inside_the_limits_and_cannot_jog_out() {
    let range = Some((um(0.0), um(100_000.0)));
    let l = lim(0, 300, 3000);
    let mut m = Manual::<1>::holding(&[um(90_000.0)], T_US);
    let mut refs = Vec::new();
    for k in 0..30 {
        // Renewed every 100 ms; once against the limit a renewal may be refused.
        let r = m.jog(0, speed(80.0), &l, range);
        assert!(k > 5 || r.is_ok(), "{r:?}");
        refs.extend(run(&mut m, 100));
    }
    refs.extend(run(&mut m, 1000));
    assert!(m.at_rest(), "at rest against the limit");
    let last = refs.last().map_or(um(0.0), |r| r.x_ref_um);
    // Stopped by braking within 2 mm of the limit and short of it: the clamp (the last
    // guard) never acted, so the speed changed by at most A·T² per tick throughout.
    assert!(last > um(98_000.0) && last < um(100_000.0), "{last:?}");
    let a_t2 = 300_000.0 * 1e-6 + 2.0 / 256.0;
    for w in refs.windows(3) {
        let [a, b, c] = [w[0], w[1], w[2]].map(|r| r.x_ref_um.to_num::<f64>());
        assert!(
            (c - 2.0 * b + a).abs() <= a_t2,
            "Δv {} µm/tick",
            c - 2.0 * b + a
        );
    }
    // From there a jog further out is refused, back in is allowed.
    let mut at_max = Manual::<1>::holding(&[um(100_000.0)], T_US);
    assert_eq!(
        at_max.jog(0, speed(1.0), &l, range),
        Err(MotionError::OutsideLimits)
    );
    at_max.jog(0, speed(-1.0), &l, range).unwrap();
    // Unreferenced (no range): no position limit.
    at_max.jog(0, speed(1.0), &l, None).unwrap();
}

#[test]
fn a_jog_from_outside_the_limits_back_in_never_steps_the_reference() {
    // Referenced below the minimum (set-position, drift with the valves off): a jog in
    // is allowed and starts from where the slave is, not from the limit.
    let range = Some((um(0.0), um(100_000.0)));
    let l = lim(0, 300, 3000);
    let mut m = Manual::<1>::holding(&[um(-5_000.0)], T_US);
    assert_eq!(
        m.jog(0, speed(-1.0), &l, range),
        Err(MotionError::OutsideLimits)
    );
    m.jog(0, speed(10.0), &l, range).unwrap();
    let refs = run(&mut m, 250);
    let mut prev = -5_000.0;
    for r in &refs {
        let x = r.x_ref_um.to_num::<f64>();
        assert!((0.0..=10.0 + 1e-3).contains(&(x - prev)), "{prev} → {x}");
        prev = x;
    }
    assert!(prev < 0.0, "still on its way in: {prev}");
}

#[test]
fn a_jog_found_past_a_limit_by_its_renewal_brakes_without_a_step() {
    // Jogging up unreferenced; a home edge puts the slave at 101 mm in a frame whose
    // limit is 100 mm; the next renewal (with the limits) is refused and brakes it.
    let range = Some((um(0.0), um(100_000.0)));
    let l = lim(0, 300, 3000);
    let mut m = Manual::<1>::holding(&[um(0.0)], T_US);
    m.jog(0, speed(10.0), &l, None).unwrap();
    run(&mut m, 200);
    m.rebase(0, um(101_000.0));
    assert_eq!(
        m.jog(0, speed(10.0), &l, range),
        Err(MotionError::OutsideLimits)
    );
    let mut prev = m.step()[0].x_ref_um.to_num::<f64>();
    for r in run(&mut m, 300) {
        let x = r.x_ref_um.to_num::<f64>();
        assert!((0.0..=10.0 + 1e-3).contains(&(x - prev)), "{prev} → {x}");
        prev = x;
    }
    assert!(m.at_rest(), "braked to rest");
}

#[test]
fn a_renewal_takes_the_new_acceleration_and_rebase_moves_every_kind_of_reference() {
    let mut m = Manual::<1>::holding(&[um(0.0)], T_US);
    m.jog(0, speed(5.0), &lim(0, 10, 100), None).unwrap();
    run(&mut m, 100);
    m.jog(0, speed(5.0), &lim(0, 500, 5000), None).unwrap();
    let AxisMotion::Ramp(r) = m.axes[0] else {
        panic!("a ramp")
    };
    assert_eq!(Some(r.acc), per_tick_q36(500_000.0, T_US, 2));
    assert_eq!(Some(r.jerk), per_tick_q36(5_000_000.0, T_US, 3));
    // Rebase: a ramp, a hold and a move all shift by the offset, nothing else changes.
    let before = m.step()[0].x_ref_um;
    m.rebase(0, um(-1_000.0));
    let after = m.step()[0].x_ref_um;
    let d = (after - before).to_num::<f64>();
    assert!((-1_000.0 + 0.0..=-1_000.0 + 6.0).contains(&d), "{d}");
    let mut h = Manual::<1>::holding(&[um(200.0)], T_US);
    h.rebase(0, um(50.0));
    assert_eq!(h.step()[0].x_ref_um, um(250.0));
    h.move_to(0, um(1_250.0), &lim(50, 500, 5000)).unwrap();
    h.rebase(0, um(-250.0));
    run(&mut h, 2_000);
    assert_eq!(
        h.step()[0].x_ref_um,
        um(1_000.0),
        "the target moved with it"
    );
    h.rebase(7, um(1.0)); // no such axis: nothing
}

#[test]
fn a_move_follows_the_s_curve_to_exactly_its_target() {
    let mut m = Manual::<1>::holding(&[um(10_000.0)], T_US);
    let l = lim(50, 500, 5000);
    m.move_to(0, um(60_000.0), &l).unwrap();
    assert_eq!(m.kinds(), [ManualKind::Move]);
    assert_eq!(
        m.jog(0, speed(1.0), &l, None).map(|_| ()),
        Ok(()),
        "a jog takes over"
    );
    let mut m = Manual::<1>::holding(&[um(10_000.0)], T_US);
    m.move_to(0, um(60_000.0), &l).unwrap();
    assert_eq!(m.move_to(0, um(0.0), &l), Err(MotionError::Moving));
    let refs = run(&mut m, 3000);
    assert!(m.at_rest());
    assert_eq!(refs.last().unwrap().x_ref_um, um(60_000.0));
    for w in refs.windows(2) {
        assert!(w[1].x_ref_um >= w[0].x_ref_um, "monotone");
        let step = (w[1].x_ref_um - w[0].x_ref_um).to_num::<f64>();
        assert!(step <= 50.0 + 0.01, "≤ vmax·T");
    }
    let vmax = refs
        .iter()
        .map(|r| r.v_ff_um_per_s.to_num::<f64>())
        .fold(0.0, f64::max);
    assert!((49_900.0..=50_000.0).contains(&vmax), "{vmax}");
    let amax = refs
        .iter()
        .map(|r| r.a_ff_um_per_s2.to_num::<i32>().abs())
        .max()
        .unwrap();
    assert!((490_000..=500_000).contains(&amax), "{amax}");
    // Downwards too, and a zero-length move is at rest at once.
    m.move_to(0, um(-5_000.0), &l).unwrap();
    run(&mut m, 3000);
    assert!(m.at_rest());
    m.move_to(0, um(-5_000.0), &l).unwrap();
    run(&mut m, 1);
    assert!(m.at_rest());
}

#[test]
fn a_braked_move_stops_short_without_a_step() {
    let mut m = Manual::<1>::holding(&[um(0.0)], T_US);
    let l = lim(40, 400, 4000);
    m.move_to(0, um(100_000.0), &l).unwrap();
    let mut refs = run(&mut m, 600);
    m.stop_all();
    assert_eq!(m.kinds(), [ManualKind::Jog]);
    refs.extend(run(&mut m, 1000));
    assert!(m.at_rest());
    let end = refs.last().unwrap().x_ref_um.to_num::<f64>();
    assert!(end < 40_000.0, "stopped short: {end}");
    for w in refs.windows(3) {
        let v1 = (w[1].x_ref_um - w[0].x_ref_um).to_num::<f64>();
        let v2 = (w[2].x_ref_um - w[1].x_ref_um).to_num::<f64>();
        // Velocity change per tick ≤ A·T² (0.4 µm) plus rounding.
        assert!((v2 - v1).abs() <= 0.4 + 0.02, "{v1} → {v2}");
        assert!(v2 >= -0.01, "never reverses");
    }
}

#[test]
fn impossible_limits_are_refused() {
    let mut m = Manual::<1>::holding(&[um(0.0)], T_US);
    assert_eq!(
        m.move_to(0, um(1.0), &lim(0, 1, 1)),
        Err(MotionError::Limits)
    );
    assert_eq!(
        m.move_to(0, um(1.0), &lim(1, 0, 1)),
        Err(MotionError::Limits)
    );
    assert_eq!(
        m.jog(0, speed(1.0), &lim(1, 1, 0), None),
        Err(MotionError::Limits)
    );
    assert_eq!(
        m.jog(1, speed(1.0), &lim(1, 1, 1), None),
        Err(MotionError::Limits)
    );
    assert!(m.at_rest(), "nothing changed");
}
