//! Runtime tests: directed transitions, a proptest state-machine test of the safety
//! invariants, and a closed loop on a virtual board through the I/O traits.

use super::controller::mock::MockLaw;
use super::*;
use crate::units::{Counts, DacCode, Master, PosUm, PressureBar};
use proptest::prelude::*;

pub(super) type Rt = Runtime<MockLaw<2>, 2, 1>;

pub(super) fn rt() -> Rt {
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    Runtime::new(cfg, Some(MockLaw::new()), BootCause::Normal)
}

pub(super) fn sample(master: i32, slaves: [i32; 2]) -> Sample<2, 1> {
    Sample {
        enc: EncoderSample {
            master: Counts(master),
            slaves: [Counts(slaves[0]), Counts(slaves[1])],
            master_edges: None,
        },
        pressure_bar: [PressureBar::from_num(100)],
        estop: false,
        overrun: false,
    }
}

fn nulls() -> [DacCode; 2] {
    MockLaw::<2>::new().nulls
}

#[test]
fn starts_idle_with_nulls_and_enable_off() {
    let mut r = rt();
    let out = r.step(&sample(0, [0, 0]), None);
    assert_eq!(r.state(), State::Idle);
    assert_eq!(out.dac, nulls());
    assert!(!out.enable);
    assert_eq!(out.reply, None);
}

#[test]
fn start_hold_resume_stop() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), None);
    let out = r.step(&sample(0, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Following);
    assert!(out.enable);
    assert_eq!(r.law().unwrap().restarts, 1);
    // Target = master (ratio 1): slave at 0, master 5 → error 5 µm, code = null + 2·5.
    let out = r.step(&sample(5, [0, 0]), None);
    assert_eq!(out.dac[0].get(), 7 + 10);
    assert_eq!(r.status().error_um[0], PosUm::from_num(5));
    assert_eq!(r.status().target_um[1], PosUm::from_num(5));
    // Hold freezes the master at 5.
    let out = r.step(&sample(6, [5, 5]), Some(Command::Hold));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Holding(HoldReason::Commanded));
    r.step(&sample(50, [5, 5]), None);
    assert_eq!(r.status().master, Master::from_num(6));
    assert_eq!(r.status().error_um, [PosUm::from_num(1); 2]);
    // Master moved by 44 (< window 100): resume allowed.
    let out = r.step(&sample(50, [6, 6]), Some(Command::Start));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Following);
    assert_eq!(r.law().unwrap().restarts, 1, "resume is bumpless");
    let out = r.step(&sample(50, [6, 6]), Some(Command::Stop));
    assert_eq!(r.state(), State::Idle);
    assert_eq!(out.dac, nulls());
    assert!(!out.enable);
}

#[test]
fn resume_refused_when_master_moved() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Hold));
    assert_eq!(r.state(), State::Holding(HoldReason::Commanded));
    for m in (0..=200).step_by(20) {
        r.step(&sample(m, [0, 0]), None);
    }
    let out = r.step(&sample(200, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::MasterMoved)));
    assert_eq!(r.state(), State::Holding(HoldReason::Commanded));
}

#[test]
fn commands_without_law_are_refused() {
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    let mut r: Rt = Runtime::new(cfg, None, BootCause::Normal);
    let out = r.step(&sample(0, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::NoController)));
    assert_eq!(out.dac, [DacCode::NULL; 2]);
    assert!(r.install(MockLaw::new()).unwrap().is_none());
    let out = r.step(&sample(0, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(
        r.install(MockLaw::new()).unwrap_err(),
        CommandError::Busy,
        "no install while following"
    );
}

#[test]
fn following_error_faults_in_the_same_tick() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    // Slave 1 is 2500 µm behind (limit 2000); the slave encoder moved only 1000 counts
    // per tick so there is no encoder fault.
    r.step(&sample(0, [0, -1000]), None);
    r.step(&sample(0, [0, -2000]), None);
    assert_eq!(r.state(), State::Following);
    let out = r.step(&sample(0, [0, -2500]), None);
    assert_eq!(r.state(), State::Fault);
    assert_eq!(out.dac, nulls(), "nulls in the detecting tick");
    assert!(!out.enable);
    let rec = r.fault().unwrap();
    assert_eq!(rec.fault, Fault::FollowingError { axis: 1 });
    assert_eq!(rec.fault.code(), 0x0601);
    // Latched: stays faulted with everything back in range, Start refused.
    let out = r.step(&sample(0, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::Faulted)));
    assert_eq!(r.state(), State::Fault);
    // Only ClearFault leaves Fault.
    let out = r.step(&sample(0, [0, 0]), Some(Command::ClearFault));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Idle);
    assert_eq!(r.fault(), None);
}

#[test]
fn the_fault_history_keeps_each_cause_with_its_value_and_limit() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    r.step(&sample(0, [0, -1000]), None);
    r.step(&sample(0, [0, -2000]), None);
    r.step(&sample(0, [0, -2500]), None);
    // An E-stop held for 5 ticks while latched: one event, not five.
    let mut s = sample(0, [0, -2500]);
    s.estop = true;
    for _ in 0..5 {
        r.step(&s, None);
    }
    let h: std::vec::Vec<FaultEvent> = r.fault_history().oldest_ordered().copied().collect();
    assert_eq!(h.len(), 2, "{h:?}");
    assert_eq!(h[0].fault, Fault::FollowingError { axis: 1 });
    assert_eq!(h[0].tick, 4);
    // 2 500 µm behind against the 2 000 µm limit, I24F8 raw.
    assert_eq!((h[0].value, h[0].limit), (2500 << 8, 2000 << 8));
    assert_eq!((h[1].fault, h[1].tick), (Fault::EStop, 5));
    s.estop = false;
    r.step(&s, Some(Command::ClearFault));
    // A master jump of 61 counts against the limit of 60.
    r.step(&sample(61, [0, -2500]), None);
    let last = *r.fault_history().recent().unwrap();
    assert_eq!(last.fault, Fault::EncoderJump { channel: 0 });
    assert_eq!((last.value, last.limit), (61, 60));
    // Only the last 16 are kept, oldest first.
    let mut m = 61;
    for _ in 0..20 {
        r.step(&sample(m, [0, -2500]), Some(Command::ClearFault));
        m += 100;
        r.step(&sample(m, [0, -2500]), None);
    }
    let h: std::vec::Vec<FaultEvent> = r.fault_history().oldest_ordered().copied().collect();
    assert_eq!(h.len(), FAULT_HISTORY_LEN);
    assert!(h.windows(2).all(|w| w[0].tick < w[1].tick));
    assert_eq!(h[15].value, 100);
}

#[test]
fn estop_latches_and_clear_needs_release() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    let mut s = sample(0, [0, 0]);
    s.estop = true;
    let out = r.step(&s, None);
    assert_eq!(r.fault().unwrap().fault, Fault::EStop);
    assert!(!out.enable);
    let out = r.step(&s, Some(Command::ClearFault));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::CauseActive(Fault::EStop)))
    );
    assert_eq!(r.state(), State::Fault);
    s.estop = false;
    // Releasing alone does not clear.
    r.step(&s, None);
    assert_eq!(r.state(), State::Fault);
    let out = r.step(&s, Some(Command::ClearFault));
    assert_eq!(out.reply, Some(Ok(())));
    assert_eq!(r.state(), State::Idle);
}

#[test]
fn estop_faults_even_in_idle_and_first_cause_is_kept() {
    let mut r = rt();
    let mut s = sample(0, [0, 0]);
    s.estop = true;
    s.overrun = true;
    r.step(&s, None);
    assert_eq!(r.fault().unwrap().fault, Fault::EStop);
    assert!(r.status().fault_set.contains(FaultKind::Overrun));
    assert_eq!(r.status().timing.overruns, 1);
}

#[test]
fn encoder_jump_is_a_fault_and_clears_after_a_clean_tick() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), None);
    r.step(&sample(61, [0, 0]), None); // master limit 60 counts/tick
    assert_eq!(r.fault().unwrap().fault, Fault::EncoderJump { channel: 0 });
    let out = r.step(&sample(61, [1001, 0]), Some(Command::ClearFault));
    assert_eq!(
        out.reply,
        Some(Err(CommandError::CauseActive(Fault::EncoderJump {
            channel: 1
        })))
    );
    let out = r.step(&sample(61, [1001, 0]), Some(Command::ClearFault));
    assert_eq!(out.reply, Some(Ok(())));
}

#[test]
fn watchdog_boot_is_latched() {
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    let mut r: Rt = Runtime::new(cfg, Some(MockLaw::new()), BootCause::Watchdog);
    assert_eq!(r.state(), State::Fault);
    assert_eq!(r.status().fault.unwrap().fault.code(), 0x0200);
    let out = r.step(&sample(0, [0, 0]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::Faulted)));
    let out = r.step(&sample(0, [0, 0]), Some(Command::ClearFault));
    assert_eq!(out.reply, Some(Ok(())));
}

#[test]
fn master_stall_after_motion() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    // Waiting for a master that has not moved: never a stall.
    for _ in 0..5000 {
        r.step(&sample(0, [0, 0]), None);
    }
    assert_eq!(r.state(), State::Following);
    // Moves, then stops for the 1 s timeout.
    for m in 1..=20 {
        r.step(&sample(m, [m, m]), None);
    }
    for _ in 0..999 {
        r.step(&sample(20, [20, 20]), None);
    }
    assert_eq!(r.state(), State::Following);
    r.step(&sample(20, [20, 20]), None);
    assert_eq!(r.fault().unwrap().fault, Fault::MasterStalled);
}

#[test]
fn end_of_table_holds_and_refuses_resume() {
    let mut r = rt();
    r.law_mut().unwrap().end_master = 10;
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    for m in 1..=11 {
        r.step(&sample(m, [m, m]), None);
    }
    assert_eq!(r.state(), State::Holding(HoldReason::EndOfTable));
    // Master at rest at the end: no stall fault while holding.
    for _ in 0..3000 {
        r.step(&sample(11, [11, 11]), None);
    }
    assert_eq!(r.state(), State::Holding(HoldReason::EndOfTable));
    let out = r.step(&sample(11, [11, 11]), Some(Command::Start));
    assert_eq!(out.reply, Some(Err(CommandError::EndOfTable)));
    assert!(r.at_safe_point());
    r.install(MockLaw::new()).unwrap();
    assert_eq!(r.state(), State::Idle);
}

#[test]
fn controller_fault_and_overrun() {
    let mut r = rt();
    r.step(&sample(0, [0, 0]), Some(Command::Start));
    r.law_mut().unwrap().axis_fault = [None, Some(LawFault::Other)];
    let out = r.step(&sample(0, [0, 0]), None);
    assert_eq!(r.fault().unwrap().fault, Fault::Controller { axis: 1 });
    assert_eq!(out.dac, nulls());
    r.law_mut().unwrap().axis_fault = [None; 2];
    r.step(&sample(0, [0, 0]), Some(Command::ClearFault));
    let mut s = sample(0, [0, 0]);
    s.overrun = true;
    let out = r.step(&s, Some(Command::ClearFault));
    assert_eq!(r.fault().unwrap().fault, Fault::Overrun);
    assert_eq!(
        out.reply,
        Some(Err(CommandError::CauseActive(Fault::Overrun)))
    );
}

#[test]
fn time_master_advances_only_while_following() {
    let cfg = RuntimeConfig::<2> {
        master_source: MasterSource::Time,
        ..Default::default()
    };
    let mut r: Rt = Runtime::new(
        cfg.build().unwrap(),
        Some(MockLaw::new()),
        BootCause::Normal,
    );
    r.step(&sample(12345, [0, 0]), Some(Command::Start));
    assert_eq!(r.status().master, Master::ZERO);
    for k in 1..=10 {
        r.step(&sample(12345, [k, k]), None);
        assert_eq!(r.status().master, Master::from_num(k));
    }
    r.step(&sample(0, [10, 10]), Some(Command::Hold));
    for _ in 0..10 {
        r.step(&sample(0, [11, 11]), None);
        assert_eq!(r.status().master, Master::from_num(11));
    }
    r.step(&sample(0, [11, 11]), Some(Command::Start));
    r.step(&sample(0, [12, 12]), None);
    assert_eq!(r.status().master, Master::from_num(12));
}

#[test]
fn slave_scale_and_offset() {
    let cfg = RuntimeConfig::<2> {
        slave_um_per_count: [0.5, -2.0],
        slave_offset_um: [20_000.0, 0.0],
        ..Default::default()
    };
    let mut r: Rt = Runtime::new(
        cfg.build().unwrap(),
        Some(MockLaw::new()),
        BootCause::Normal,
    );
    r.step(&sample(0, [1001, 7]), None);
    assert_eq!(r.status().pos_um[0], PosUm::from_num(20_500.5));
    assert_eq!(r.status().pos_um[1], PosUm::from_num(-14));
    // Far beyond the range: saturates, no panic.
    r.step(&sample(0, [i32::MAX, i32::MIN]), None);
    assert_eq!(r.status().pos_um[0], PosUm::MAX);
    assert_eq!(r.status().pos_um[1], PosUm::MAX);
}

// ---- proptest state machine ----------------------------------------------------------

/// One tick of random stimulus.
#[derive(Clone, Debug)]
struct Ev {
    cmd: Option<Command>,
    estop: bool,
    overrun: bool,
    master_step: i32,
    slave_dev: [i32; 2],
    law_fault: bool,
    end: bool,
}

fn manual_limits() -> MotionLimits {
    MotionLimits {
        vel_um_per_s: 50_000,
        acc_um_per_s2: 500_000,
        jerk_um_per_s3: 5_000_000,
    }
}

fn ev() -> impl Strategy<Value = Ev> {
    let cmd = prop_oneof![
        12 => Just(None),
        2 => Just(Some(Command::Start)),
        1 => Just(Some(Command::Hold)),
        1 => Just(Some(Command::Stop)),
        2 => Just(Some(Command::ClearFault)),
        1 => (0u8..3, -20_000i32..20_000).prop_map(|(axis, v)| Some(Command::Jog {
            axis,
            speed: crate::units::VelUmPerS::from_num(v),
            limits: manual_limits(),
            range: (PosUm::from_num(-1e6), PosUm::from_num(1e6)),
        })),
        1 => (0u8..3, -2000i32..2000).prop_map(|(axis, to)| Some(Command::MoveTo {
            axis,
            to: PosUm::from_num(to),
            limits: manual_limits(),
            range: (PosUm::from_num(-1e6), PosUm::from_num(1e6)),
        })),
        1 => Just(Some(Command::Approach { limits: manual_limits() })),
    ];
    let master_step = prop_oneof![90 => -3i32..=3, 8 => Just(0), 2 => -200i32..=200];
    let dev = prop_oneof![97 => -50i32..=50, 3 => -3000i32..=3000];
    (
        cmd,
        proptest::bool::weighted(0.01),
        proptest::bool::weighted(0.005),
        master_step,
        [dev.clone(), dev],
        proptest::bool::weighted(0.005),
        proptest::bool::weighted(0.01),
    )
        .prop_map(
            |(cmd, estop, overrun, master_step, slave_dev, law_fault, end)| Ev {
                cmd,
                estop,
                overrun,
                master_step,
                slave_dev,
                law_fault,
                end,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    /// Safety invariants over random command/fault sequences:
    /// - Fault or Idle ⇒ every valve at its null and the enable off, in that very tick;
    /// - enable on ⇔ Following, Holding or Manual;
    /// - an instantaneous cause (E-stop, overrun, encoder step) ⇒ Fault after the tick;
    /// - Fault is left only by an accepted ClearFault in a tick without a cause;
    /// - a latched record exists ⇔ Fault;
    /// - a refused command changes no state (other than through a fault);
    /// - controlling after the tick ⇒ every following error within its limit.
    #[test]
    fn safety_invariants(evs in proptest::collection::vec(ev(), 1..300), boot_wd: bool) {
        let cfg = RuntimeConfig::<2>::default().build().unwrap();
        let boot = if boot_wd { BootCause::Watchdog } else { BootCause::Normal };
        let mut r: Rt = Runtime::new(cfg, Some(MockLaw::new()), boot);
        let lim = cfg.following_error_limit_um;
        let mut master = 0i32;
        let mut prev_slaves = [0i32; 2];
        let mut prev_master = 0i32;
        let mut first = true;
        // An accepted Approach not yet ended: the only way Manual ends in Following.
        let mut approach = false;
        for e in evs {
            master = master.wrapping_add(e.master_step);
            // Slaves sit on the target (ratio 1) plus a deviation.
            let slaves = [master.wrapping_add(e.slave_dev[0]), master.wrapping_add(e.slave_dev[1])];
            {
                let law = r.law_mut().unwrap();
                law.axis_fault = [e.law_fault.then_some(LawFault::Other), None];
                law.end_master = if e.end { i64::MIN } else { 1 << 40 };
            }
            let mut s = sample(master, slaves);
            s.estop = e.estop;
            s.overrun = e.overrun;
            let jump = !first && (
                master.wrapping_sub(prev_master).unsigned_abs() > cfg.master_step_limit
                || slaves.iter().zip(prev_slaves.iter()).zip(cfg.slave_step_limit.iter())
                    .any(|((a, b), l)| a.wrapping_sub(*b).unsigned_abs() > *l));
            let cause = e.estop || e.overrun || jump;
            let before = r.state();
            let out = r.step(&s, e.cmd);
            let after = r.state();
            first = false;
            prev_master = master;
            prev_slaves = slaves;

            match after {
                State::Fault | State::Idle => {
                    prop_assert_eq!(out.dac, nulls());
                    prop_assert!(!out.enable);
                }
                State::Following | State::Holding(_) | State::Manual => {
                    prop_assert!(out.enable);
                    for (err, l) in r.status().error_um.iter().zip(lim.iter()) {
                        prop_assert!(err.unsigned_abs() <= l.unsigned_abs());
                    }
                }
            }
            prop_assert_eq!(r.status().enable, out.enable);
            prop_assert_eq!(r.fault().is_some(), after == State::Fault);
            if cause {
                prop_assert_eq!(after, State::Fault);
            }
            if before == State::Fault && after != State::Fault {
                prop_assert_eq!(e.cmd, Some(Command::ClearFault));
                prop_assert_eq!(out.reply, Some(Ok(())));
                prop_assert!(!cause);
                prop_assert_eq!(after, State::Idle);
            }
            // The law's end of table may move Following → Holding in the tick of a refusal.
            let law_moved = before == State::Following
                && after == State::Holding(HoldReason::EndOfTable);
            // The end of an accepted approach starts following on its own, in any tick —
            // also in one whose command is refused (a Start refused Busy while the
            // approach ends).
            let approach_ended = approach && before == State::Manual && after == State::Following;
            if matches!(e.cmd, Some(Command::Approach { .. })) && out.reply == Some(Ok(())) {
                approach = true;
            } else if after != State::Manual
                || (matches!(e.cmd, Some(Command::Hold | Command::Stop))
                    && out.reply == Some(Ok(())))
            {
                // Left Manual, or an accepted Hold or Stop (the approach ends).
                approach = false;
            }
            if let Some(Err(_)) = out.reply {
                prop_assert!(after == before || after == State::Fault || law_moved
                    || approach_ended,
                    "refused command changed {:?} → {:?}", before, after);
            }
            if e.cmd.is_none() && before != after {
                // Without a command only a fault, the end of the table or the end of an
                // approach changes state.
                prop_assert!(after == State::Fault || law_moved || approach_ended);
            }
        }
    }
}

// ---- virtual board: the runtime through the I/O traits ----------------------------------

/// A toy board: each slave is an integrator driven by its valve code when enabled.
struct VirtualBoard {
    master: i32,
    slave_um: [i64; 2],
    codes: [DacCode; 2],
    enable: bool,
    estop: bool,
    enc16: [encoder::Extender16; 2],
}

impl EncoderInput<2> for VirtualBoard {
    fn latch(&mut self) -> EncoderSample<2> {
        // Slaves go through 16-bit counters, as on TIM3/TIM4.
        let s0 = self.enc16[0].update(self.slave_um[0] as u16);
        let s1 = self.enc16[1].update(self.slave_um[1] as u16);
        EncoderSample {
            master: Counts(self.master),
            slaves: [s0, s1],
            master_edges: None,
        }
    }
}

impl PressureInput<1> for VirtualBoard {
    fn read(&mut self) -> [PressureBar; 1] {
        [PressureBar::from_num(42)]
    }
}

impl SafetyInput for VirtualBoard {
    fn estop_active(&mut self) -> bool {
        self.estop
    }
}

impl ValveOutput<2> for VirtualBoard {
    fn write(&mut self, codes: &[DacCode; 2]) {
        self.codes = *codes;
    }
    fn set_enable(&mut self, on: bool) {
        self.enable = on;
    }
}

impl VirtualBoard {
    fn advance(&mut self) {
        if self.enable {
            for (x, c) in self.slave_um.iter_mut().zip(self.codes.iter()) {
                // Flow ∝ opening relative to the valve null (7): 1 µm per 4 LSB per tick.
                *x += i64::from(c.get() - 7) / 4;
            }
        }
    }
}

#[test]
fn closed_loop_on_a_virtual_board_crosses_16_bit_wrap() {
    let mut b = VirtualBoard {
        master: 0,
        slave_um: [0; 2],
        codes: [DacCode::NULL; 2],
        enable: false,
        estop: false,
        enc16: [encoder::Extender16::default(); 2],
    };
    let mut r = rt();
    let mut cmd = Some(Command::Start);
    let mut worst = 0i64;
    // Master ramps 30 counts/tick to 90 000 (past 2^16 counts on the slaves).
    for k in 0..4000 {
        b.master = (k * 30).min(90_000);
        let reply = r.tick_io(&mut b, cmd.take(), false);
        if k == 0 {
            assert_eq!(reply, Some(Ok(())));
        }
        b.advance();
        if k > 100 {
            worst = worst.max((i64::from(b.master) - b.slave_um[0]).abs());
        }
    }
    assert_eq!(r.state(), State::Following);
    assert!(b.enable);
    // P-law on an integrator lags by v/(gain·k) = 30/(2/4) = 60 µm at constant speed.
    assert!(worst <= 61, "worst lag {worst} µm");
    assert!(
        (b.slave_um[0] - 90_000).abs() <= 2,
        "settled at {}",
        b.slave_um[0]
    );
    assert_eq!(r.status().pos_um[0], PosUm::from_num(b.slave_um[0]));
    assert_eq!(r.status().pressure_bar[0], PressureBar::from_num(42));
    // E-stop: valves to null and enable off in the same tick.
    b.estop = true;
    r.tick_io(&mut b, None, false);
    assert_eq!(b.codes, nulls());
    assert!(!b.enable);
    assert_eq!(r.status().fault.unwrap().fault, Fault::EStop);
}

/// A board whose four pressure inputs change every tick and can go stale.
struct PressureBoard {
    bar: i32,
    live: bool,
}

impl EncoderInput<2> for PressureBoard {
    fn latch(&mut self) -> EncoderSample<2> {
        EncoderSample {
            master: Counts(0),
            slaves: [Counts(0); 2],
            master_edges: None,
        }
    }
}

impl PressureInput<4> for PressureBoard {
    fn read(&mut self) -> [PressureBar; 4] {
        [0, 1, 2, 3].map(|k| PressureBar::from_num(self.bar + k))
    }
    fn healthy(&mut self) -> bool {
        self.live
    }
}

impl SafetyInput for PressureBoard {
    fn estop_active(&mut self) -> bool {
        false
    }
}

impl ValveOutput<2> for PressureBoard {
    fn write(&mut self, _codes: &[DacCode; 2]) {}
    fn set_enable(&mut self, _on: bool) {}
}

/// The law gets slave k's chambers from inputs 2k, 2k + 1 while they are live, and the
/// last live ones while the board says they are stale (the active damping then decays
/// instead of acting on a frozen or restarting converter).
#[test]
fn the_law_gets_each_slaves_chambers_and_keeps_the_last_live_ones() {
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    let mut law = MockLaw::<2>::new();
    let mut r: Runtime<&mut MockLaw<2>, 2, 4> =
        Runtime::new(cfg, Some(&mut law), BootCause::Normal);
    let mut b = PressureBoard {
        bar: 100,
        live: true,
    };
    r.tick_io(&mut b, Some(Command::Start), false);
    r.tick_io(&mut b, None, false);
    let bar = |x: i32| PressureBar::from_num(x);
    let want = [[bar(100), bar(101)], [bar(102), bar(103)]];
    assert_eq!(r.law().map(|l| l.pressures), Some(want));
    b.bar = 150;
    b.live = false;
    r.tick_io(&mut b, None, false);
    assert_eq!(
        r.law().map(|l| l.pressures),
        Some(want),
        "stale: the last live ones"
    );
    b.live = true;
    r.tick_io(&mut b, None, false);
    assert_eq!(
        r.law().map(|l| l.pressures),
        Some([[bar(150), bar(151)], [bar(152), bar(153)]])
    );
}

/// A runtime over `&mut` laws (the board's static law buffers) runs them like owned
/// ones, and `install` swaps the references: the old law comes back untouched.
#[test]
fn laws_by_reference_run_and_swap() {
    let cfg = RuntimeConfig::<2>::default().build().unwrap();
    let (mut a, mut b) = (MockLaw::<2>::new(), MockLaw::<2>::new());
    b.gain = 3;
    let mut owned = rt();
    let mut r: Runtime<&mut MockLaw<2>, 2, 1> = Runtime::new(cfg, Some(&mut a), BootCause::Normal);
    for (k, cmd) in [(0, None), (0, Some(Command::Start)), (5, None), (9, None)] {
        let o1 = owned.step(&sample(k, [0, 0]), cmd);
        let o2 = r.step(&sample(k, [0, 0]), cmd);
        assert_eq!((o1.dac, o1.reply), (o2.dac, o2.reply));
    }
    // Not at a safe point while following: refused.
    assert!(r.install(&mut b).is_err());
    r.step(&sample(9, [9, 9]), Some(Command::Stop));
    let mut b2 = MockLaw::<2>::new();
    b2.gain = 3;
    let old = r.install(&mut b2).unwrap().unwrap();
    assert_eq!(old.restarts, 1, "the old law comes back as it ran");
    r.step(&sample(9, [0, 0]), Some(Command::Start));
    // The new law (gain 3) runs: error 9 µm → null + 27.
    assert_eq!(r.step(&sample(9, [0, 0]), None).dac[0].get(), 7 + 27);
}
