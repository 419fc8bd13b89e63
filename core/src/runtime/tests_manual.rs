//! Runtime tests of the `Manual` state: entering and leaving it, the refusals, the
//! deadman through the runtime, and the approach that starts following.

use super::controller::mock::MockLaw;
use super::tests::{rt, sample, Rt};
use super::*;
use crate::units::{DacCode, PosUm, VelUmPerS};

const LIM: MotionLimits = MotionLimits {
    vel_um_per_s: 20_000,
    acc_um_per_s2: 200_000,
    jerk_um_per_s3: 4_000_000,
};

const RANGE: (PosUm, PosUm) = (PosUm::ZERO, PosUm::from_bits(100_000 << 8));

fn jog(axis: u8, mm_s: f64) -> Command {
    Command::Jog {
        axis,
        speed: VelUmPerS::from_num(mm_s * 1000.0),
        limits: LIM,
        range: RANGE,
    }
}

fn move_to(axis: u8, to_um: i32) -> Command {
    Command::MoveTo {
        axis,
        to: PosUm::from_num(to_um),
        limits: LIM,
        range: RANGE,
    }
}

/// Ticks with the slaves exactly on last tick's target (a perfect axis, µm counts).
fn follow(r: &mut Rt, master: i32, n: usize) {
    for _ in 0..n {
        let t = r
            .status()
            .target_um
            .map(|t| t.to_num::<f64>().round() as i32);
        r.step(&sample(master, t), None);
    }
}

#[test]
fn a_jog_enters_manual_with_valves_powered_and_stop_leaves_it() {
    let mut r = rt();
    r.step(&sample(0, [1000, 2000]), None);
    let out = r.step(&sample(0, [1000, 2000]), Some(jog(0, 5.0)));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Manual);
    assert!(out.enable);
    assert_eq!(r.law().unwrap().restarts, 1);
    assert_eq!(r.status().manual, [ManualKind::Jog, ManualKind::Hold]);
    follow(&mut r, 0, 100);
    // Axis 0 moved up, axis 1 holds where it was.
    assert!(r.status().pos_um[0] > PosUm::from_num(1100));
    assert_eq!(r.status().target_um[1], PosUm::from_num(2000));
    // Start while a slave moves: Busy; Stop: valves to null at once.
    let out = r.step(&sample(0, [1200, 2000]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::Busy)));
    let out = r.step(&sample(0, [1200, 2000]), Some(Command::Stop));
    assert_eq!(r.state(), State::Idle);
    assert_eq!(out.dac, r.null_codes());
    assert!(!out.enable);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
}

#[test]
fn the_deadman_brakes_a_jog_nobody_renews() {
    let mut r = rt();
    let out = r.step(&sample(0, [0, 50_000]), Some(jog(1, -10.0)));
    assert_eq!(out.reply, Some(Ok(())));
    follow(&mut r, 0, 299);
    assert_eq!(r.status().manual[1], ManualKind::Jog);
    // 300 ms after the last renewal the target speed is 0; braking takes ≈ 0.1 s.
    follow(&mut r, 0, 200);
    assert_eq!(r.status().manual[1], ManualKind::Hold);
    assert_eq!(r.state(), State::Manual, "holding under control");
    let x = r.status().target_um[1];
    follow(&mut r, 0, 50);
    assert_eq!(r.status().target_um[1], x);
}

#[test]
fn manual_motions_are_refused_where_they_make_no_sense() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    let out = r.step(&sample(0, [0, 0]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Err(CommandError::Busy)), "while following");
    r.step(&sample(0, [0, 0]), Some(Command::Stop));
    // Outside the range, a missing axis, impossible limits: nothing changes.
    let out = r.step(&sample(0, [0, 0]), Some(move_to(0, 150_000)));
    let outside = CommandError::Motion {
        axis: 0,
        error: MotionError::OutsideLimits,
    };
    assert_eq!(out.reply, Some(Err(outside)));
    assert_eq!(r.state(), State::Idle);
    let out = r.step(&sample(0, [0, 0]), Some(move_to(2, 1000)));
    assert_eq!(out.reply, Some(Err(CommandError::NoAxis { axis: 2 })));
    let zero = Command::MoveTo {
        axis: 0,
        to: PosUm::from_num(10),
        limits: MotionLimits {
            jerk_um_per_s3: 0,
            ..LIM
        },
        range: RANGE,
    };
    let out = r.step(&sample(0, [0, 0]), Some(zero));
    let limits = CommandError::Motion {
        axis: 0,
        error: MotionError::Limits,
    };
    assert_eq!(out.reply, Some(Err(limits)));
    assert_eq!(r.state(), State::Idle);
    // A move on a moving axis is refused; Hold brakes it to rest and stays in Manual.
    r.step(&sample(0, [0, 0]), Some(move_to(0, 50_000)));
    follow(&mut r, 0, 200);
    let out = r.step(
        &sample(0, [r.status().pos_um[0].to_num(), 0]),
        Some(move_to(0, 0)),
    );
    let moving = CommandError::Motion {
        axis: 0,
        error: MotionError::Moving,
    };
    assert_eq!(out.reply, Some(Err(moving)));
    r.step(
        &sample(0, [r.status().pos_um[0].to_num(), 0]),
        Some(Command::Hold),
    );
    follow(&mut r, 0, 500);
    assert_eq!(r.state(), State::Manual);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
    assert!(
        r.status().pos_um[0] < PosUm::from_num(49_000),
        "braked short"
    );
    // In Fault: Faulted; without a law: NoController.
    let mut s = sample(0, [0, 0]);
    s.estop = true;
    r.step(&s, None);
    let out = r.step(&s, Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Err(CommandError::Faulted)));
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    let mut bare: Rt = Runtime::new(cfg, None, BootCause::Normal);
    let out = bare.step(&sample(0, [0, 0]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Err(CommandError::NoController)));
}

#[test]
fn a_move_reaches_its_target_and_an_unreferenced_axis_cannot_move() {
    let mut r = rt();
    r.step(&sample(0, [10_000, 0]), Some(move_to(0, 30_000)));
    assert_eq!(r.status().manual[0], ManualKind::Move);
    // 20 mm at 20 mm/s, 200 mm/s², 4 m/s³: ≈ 1.15 s.
    follow(&mut r, 0, 1300);
    assert_eq!(r.status().manual[0], ManualKind::Hold);
    assert_eq!(r.status().target_um[0], PosUm::from_num(30_000));
    assert_eq!(r.status().pos_um[0], PosUm::from_num(30_000));

    let cfg = RuntimeConfig::<2> {
        slave_reference: [ReferenceMode::Incremental, ReferenceMode::Absolute],
        ..RuntimeConfig::default()
    };
    let mut r: Rt = Runtime::new(
        cfg.build().unwrap(),
        Some(MockLaw::new()),
        BootCause::Normal,
    );
    let out = r.step(&sample(0, [0, 0]), Some(move_to(0, 1000)));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::NotReferenced { axis: 0 }))
    );
    // A jog is allowed unreferenced (to find the home switch), without position limits.
    let out = r.step(&sample(0, [0, 0]), Some(jog(0, -1.0)));
    assert_eq!(out.reply, Some(Ok(())));
    let out = r.step(&sample(0, [0, 0]), Some(Command::Approach { limits: LIM }));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::Busy)),
        "a slave is moving"
    );
}

#[test]
fn the_approach_moves_to_the_table_then_follows_bumplessly() {
    let mut r = rt();
    // The mock's table: target = master (µm per count); master at 5 000, slaves at 0 / 9 000.
    r.step(&sample(5000, [0, 9000]), None);
    let out = r.step(
        &sample(5000, [0, 9000]),
        Some(Command::Approach { limits: LIM }),
    );
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Manual);
    assert_eq!(r.status().manual, [ManualKind::Move; 2]);
    follow(&mut r, 5000, 1000);
    assert_eq!(r.state(), State::Following);
    assert_eq!(r.law().unwrap().restarts, 2, "restarted for the run");
    assert_eq!(r.status().error_um, [PosUm::ZERO; 2], "on the table");
    assert_eq!(r.status().target_um, [PosUm::from_num(5000); 2]);
    // Master moved beyond the resume window (100) during an approach: the slaves hold.
    let mut r = rt();
    r.step(
        &sample(5000, [0, 9000]),
        Some(Command::Approach { limits: LIM }),
    );
    for m in 0..1000 {
        follow(&mut r, 5000 + 2 * m.min(100), 1);
    }
    assert_eq!(r.state(), State::Manual);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
}

/// Ticks with a perfect axis; the largest change of any slave's target from one tick to
/// the next, µm.
fn largest_target_step(r: &mut Rt, master: impl Fn(usize) -> i32, n: usize) -> f64 {
    let mut worst = 0.0f64;
    for k in 0..n {
        let before = r.status().target_um;
        follow(r, master(k), 1);
        for (a, b) in before.iter().zip(r.status().target_um.iter()) {
            worst = worst.max((*b - *a).to_num::<f64>().abs());
        }
    }
    worst
}

#[test]
fn an_approach_whose_master_crept_replans_and_starts_following_without_a_step() {
    let mut r = rt();
    r.step(&sample(5000, [0, 9000]), None);
    r.step(
        &sample(5000, [0, 9000]),
        Some(Command::Approach { limits: LIM }),
    );
    // The master creeps 60 counts (60 µm of table, within the resume window of 100)
    // during the approach: the slaves arrive at the old value, then at the new one.
    let master = |k: usize| 5000 + (k as i32 / 10).min(60);
    let step = largest_target_step(&mut r, master, 1500);
    assert_eq!(r.state(), State::Following);
    assert_eq!(r.status().target_um, [PosUm::from_num(5060); 2]);
    // At 20 mm/s the S-curve moves ≤ 20 µm per tick; the switch adds nothing.
    assert!(step <= 20.5, "the target stepped by {step} µm");
}

#[test]
fn nothing_revives_an_approach_that_was_interrupted() {
    // A jog while an approach is on its way is refused; Hold cancels the approach.
    let mut r = rt();
    r.step(
        &sample(5000, [0, 9000]),
        Some(Command::Approach { limits: LIM }),
    );
    follow(&mut r, 5000, 10);
    let out = r.step(&sample(5000, [10, 8990]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Err(CommandError::Busy)));
    r.step(&sample(5000, [10, 8990]), Some(Command::Hold));
    follow(&mut r, 5000, 1500);
    assert_eq!(r.state(), State::Manual, "held, not following");
    // A fault during an approach, ClearFault, then a jog that ends at rest: it stays in
    // Manual instead of starting to follow from wherever the jog left the slaves.
    let mut r = rt();
    r.step(
        &sample(5000, [0, 9000]),
        Some(Command::Approach { limits: LIM }),
    );
    follow(&mut r, 5000, 10);
    let mut s = sample(5000, [10, 8990]);
    s.estop = true;
    r.step(&s, None);
    assert_eq!(r.state(), State::Fault);
    follow(&mut r, 5000, 400);
    assert_eq!(
        r.step(&sample(5000, [10, 8990]), Some(Command::ClearFault))
            .reply,
        Some(Ok(()))
    );
    let out = r.step(&sample(5000, [10, 8990]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Ok(())));
    follow(&mut r, 5000, 1000);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
    assert_eq!(r.state(), State::Manual);
}

#[test]
fn a_stopped_jog_is_not_revived_by_its_next_renewal() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(jog(0, 1.0)));
    follow(&mut r, 0, 50);
    r.step(&sample(0, [50, 0]), Some(Command::Stop));
    assert_eq!(r.state(), State::Idle);
    // The jogging host renews 100 ms later: refused, the valves stay off.
    follow(&mut r, 0, 99);
    let out = r.step(&sample(0, [50, 0]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Err(CommandError::Busy)));
    assert!(!out.enable);
    // A move is a command of its own, not a renewal: allowed at once (then stopped).
    let out = r.step(&sample(0, [50, 0]), Some(move_to(0, 1000)));
    assert_eq!(out.reply, Some(Ok(())));
    // …and the still-renewing host's next jog cannot take the move over.
    let out = r.step(&sample(0, [50, 0]), Some(jog(0, 1.0)));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::Busy)),
        "not a revival via the move"
    );
    r.step(&sample(0, [50, 0]), Some(Command::Stop));
    let out = r.step(&sample(0, [50, 0]), Some(jog(0, 1.0)));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::Busy)),
        "the Stop locks jogs again"
    );
    // After the deadman time a jog is a new command again.
    follow(&mut r, 0, 300);
    let out = r.step(&sample(0, [50, 0]), Some(jog(0, 1.0)));
    assert_eq!(out.reply, Some(Ok(())));
}

#[test]
fn manual_keeps_the_safety_rules() {
    // A following error beyond the runtime's limit latches a fault from Manual too.
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(move_to(0, 50_000)));
    for _ in 0..2000 {
        r.step(&sample(0, [0, 0]), None);
    }
    assert_eq!(r.state(), State::Fault);
    assert_eq!(r.fault().unwrap().fault, Fault::FollowingError { axis: 0 });
    assert_eq!(r.status().dac, [DacCode::new_clamped(7); 2]);
    assert!(!r.status().enable);
}

fn test_move(axis: u8, profile: TestProfile, amplitude_um: u32) -> Command {
    Command::Test {
        axis,
        spec: TestSpec {
            profile,
            amplitude_um,
            duration_ms: 100,
            dwell_ms: 20,
            f_start_mhz: 1000,
            f_end_mhz: 20_000,
        },
        range: RANGE,
        max_speed_um_per_s: 200_000,
    }
}

#[test]
fn a_test_move_excites_one_slave_about_where_it_holds_then_holds_there() {
    let mut r = rt();
    let out = r.step(
        &sample(0, [40_000, 2000]),
        Some(test_move(0, TestProfile::Step, 500)),
    );
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Manual);
    assert!(out.enable, "under the law's control, valves powered");
    assert_eq!(r.status().manual, [ManualKind::Test, ManualKind::Hold]);
    let mut seen = std::vec::Vec::new();
    for _ in 0..100 {
        seen.push(r.status().target_um[0].to_num::<i32>());
        follow(&mut r, 0, 1);
    }
    // +A, 0, −A, 0, +A about 40 000 µm by 20 ms levels; the other slave holds.
    for v in [40_500, 40_000, 39_500] {
        assert!(seen.contains(&v), "{v} in {seen:?}");
    }
    assert!(seen.iter().all(|v| (39_500..=40_500).contains(v)));
    assert_eq!(r.status().target_um[1], PosUm::from_num(2000));
    follow(&mut r, 0, 2);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
    assert_eq!(
        r.status().target_um[0],
        PosUm::from_num(40_000),
        "back at its centre"
    );
    assert_eq!(r.state(), State::Manual);
}

#[test]
fn a_test_move_is_refused_outside_limits_too_fast_or_on_a_moving_slave() {
    let mut r = rt();
    let refused = |error| Some(Err(CommandError::Motion { axis: 0, error }));
    let at = [50_000, 30_000];
    // A chirp of 1 mm about 1.5 mm, plus the following-error limit of 2 mm, leaves the
    // range at 0 (a runtime of its own: the slaves cannot jump).
    let mut low = rt();
    let out = low.step(
        &sample(0, [1500, 30_000]),
        Some(test_move(0, TestProfile::Chirp, 1000)),
    );
    assert_eq!(out.reply, refused(MotionError::OutsideLimits));
    assert_eq!(low.state(), State::Idle, "nothing moved");
    // A chirp ends (or holds) by a step back to its centre of up to A: A below e too.
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Chirp, 2000)));
    assert_eq!(out.reply, refused(MotionError::TestStep));
    // A step of 2 mm (a PRBS of 1 mm: −1 → +1) would trip the 2 mm following-error limit.
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Step, 2000)));
    assert_eq!(out.reply, refused(MotionError::TestStep));
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Prbs, 1000)));
    assert_eq!(out.reply, refused(MotionError::TestStep));
    assert_eq!(r.state(), State::Idle, "nothing moved");
    // A chirp of 1.9 mm to 20 Hz: 239 mm/s peak, above 200 mm/s.
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Chirp, 1900)));
    assert_eq!(out.reply, refused(MotionError::TooFast));
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Step, 0)));
    assert_eq!(out.reply, refused(MotionError::TestSpec));
    // While slave 0 jogs, a test on it is refused; Hold brakes it (the test's centre).
    r.step(&sample(0, at), Some(jog(0, 1.0)));
    let out = r.step(&sample(0, at), Some(test_move(0, TestProfile::Step, 100)));
    assert_eq!(out.reply, refused(MotionError::Moving));
    let out = r.step(&sample(0, at), Some(test_move(1, TestProfile::Step, 100)));
    assert_eq!(
        out.reply,
        Some(Ok(())),
        "the other slave may test meanwhile"
    );
    follow(&mut r, 0, 5);
    assert_eq!(r.status().target_um[1], PosUm::from_num(30_100));
    r.step(&sample(0, at), Some(Command::Hold));
    follow(&mut r, 0, 200);
    assert_eq!(r.status().manual, [ManualKind::Hold; 2]);
    assert_eq!(
        r.status().target_um[1],
        PosUm::from_num(30_000),
        "held at the test's centre"
    );
}
