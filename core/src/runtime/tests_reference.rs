//! Runtime tests of the position reference (set-position, homing, Start refused while a
//! slave is unreferenced) and of the pressure-input health rule.

use super::controller::mock::MockLaw;
use super::*;
use crate::units::{Counts, DacCode, PosUm, PressureBar};

type Rt = Runtime<MockLaw<2>, 2, 1>;

fn rt(cfg: RuntimeConfig<2>) -> Rt {
    Runtime::new(
        cfg.build().unwrap(),
        Some(MockLaw::new()),
        BootCause::Normal,
    )
}

fn incremental() -> RuntimeConfig<2> {
    RuntimeConfig {
        slave_reference: [ReferenceMode::Incremental, ReferenceMode::Absolute],
        home_position_um: [150_000.0, 0.0],
        ..RuntimeConfig::default()
    }
}

/// A board whose encoders, reference edges and pressure health the test sets.
#[derive(Default)]
struct Board1 {
    master: i32,
    slaves: [i32; 2],
    edge: [Option<Counts>; 2],
    pressure_dead: bool,
    codes: [DacCode; 2],
    enable: bool,
}

impl EncoderInput<2> for Board1 {
    fn latch(&mut self) -> EncoderSample<2> {
        EncoderSample {
            master: Counts(self.master),
            slaves: [Counts(self.slaves[0]), Counts(self.slaves[1])],
            master_edges: None,
        }
    }
    fn reference_edges(&mut self) -> [Option<Counts>; 2] {
        core::mem::take(&mut self.edge)
    }
}
impl PressureInput<1> for Board1 {
    fn read(&mut self) -> [PressureBar; 1] {
        [PressureBar::from_num(80)]
    }
    fn healthy(&mut self) -> bool {
        !self.pressure_dead
    }
}
impl SafetyInput for Board1 {
    fn estop_active(&mut self) -> bool {
        false
    }
}
impl ValveOutput<2> for Board1 {
    fn write(&mut self, codes: &[DacCode; 2]) {
        self.codes = *codes;
    }
    fn set_enable(&mut self, on: bool) {
        self.enable = on;
    }
}

#[test]
fn start_is_refused_until_every_slave_is_referenced() {
    let mut r = rt(incremental());
    let mut b = Board1 {
        slaves: [1234, 0],
        ..Board1::default()
    };
    assert_eq!(
        r.tick_io(&mut b, Some(Command::Start), false),
        Some(Err(CommandError::NotReferenced { axis: 0 }))
    );
    // Hold from Idle also starts control: refused the same way.
    assert_eq!(
        r.tick_io(&mut b, Some(Command::Hold), false),
        Some(Err(CommandError::NotReferenced { axis: 0 }))
    );
    assert_eq!(r.state(), State::Idle);
    assert!(!b.enable);
    assert_eq!(r.status().reference[0], RefState::Unreferenced);
    // The operator states that slave 0 is at 3 µm (where the mock law's target is, so
    // Start does not trip the following error): it measured 1234 µm.
    let at = PosUm::from_num(3);
    assert_eq!(
        r.tick_io(
            &mut b,
            Some(Command::SetPosition {
                axis: 0,
                pos_um: at
            }),
            false
        ),
        Some(Ok(()))
    );
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().pos_um[0], at);
    assert_eq!(r.status().reference, [RefState::Referenced; 2]);
    assert_eq!(r.tick_io(&mut b, Some(Command::Start), false), Some(Ok(())));
    assert_eq!(r.state(), State::Following);
    // No reference change while controlling; no such axis.
    assert_eq!(
        r.tick_io(&mut b, Some(Command::Home { axis: 0 }), false),
        Some(Err(CommandError::Busy))
    );
    r.tick_io(&mut b, Some(Command::Stop), false);
    assert_eq!(
        r.tick_io(
            &mut b,
            Some(Command::SetPosition {
                axis: 2,
                pos_um: at
            }),
            false
        ),
        Some(Err(CommandError::NoAxis { axis: 2 }))
    );
}

#[test]
fn homing_references_at_the_latched_edge_count() {
    let mut r = rt(incremental());
    let mut b = Board1::default();
    r.tick_io(&mut b, Some(Command::Home { axis: 0 }), false);
    assert_eq!(r.status().reference[0], RefState::Homing);
    // The axis moves across its index: the count at the edge was 400, the axis is at
    // 520 when the tick reads it. Home position 150 mm at the edge.
    b.slaves[0] = 520;
    b.edge[0] = Some(Counts(400));
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().reference[0], RefState::Referenced);
    assert_eq!(r.status().pos_um[0], PosUm::from_num(150_120));
    assert_eq!(r.tick_io(&mut b, Some(Command::Start), false), Some(Ok(())));
    // An edge that is not armed changes nothing.
    r.tick_io(&mut b, Some(Command::Stop), false);
    b.edge[0] = Some(Counts(0));
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().pos_um[0], PosUm::from_num(150_120));
}

#[test]
fn homing_while_jogging_to_the_switch_moves_the_reference_with_the_frame() {
    // Home armed in Idle, then a jog toward the switch (the commissioning workflow): the
    // edge re-references the axis mid-jog, and the manual reference follows the new
    // frame, so the error the law sees does not step.
    let mut r = rt(incremental());
    let mut b = Board1::default();
    r.tick_io(&mut b, Some(Command::Home { axis: 0 }), false);
    let jog = Command::Jog {
        axis: 0,
        speed: crate::units::VelUmPerS::from_num(-5_000),
        limits: MotionLimits {
            vel_um_per_s: 10_000,
            acc_um_per_s2: 100_000,
            jerk_um_per_s3: 1_000_000,
        },
        range: (PosUm::ZERO, PosUm::from_num(500_000)),
    };
    assert_eq!(r.tick_io(&mut b, Some(jog), false), Some(Ok(())));
    let mut worst = 0.0f64;
    for k in 0..200 {
        // A perfect axis: it is where the last target was (1 µm per count).
        let target = r.status().target_um[0] - r.status().pos_um[0];
        b.slaves[0] += target.to_num::<f64>().round() as i32;
        if k == 100 {
            b.edge[0] = Some(Counts(b.slaves[0]));
        }
        r.tick_io(&mut b, None, false);
        worst = worst.max(r.status().error_um[0].to_num::<f64>().abs());
    }
    assert_eq!(r.status().reference[0], RefState::Referenced);
    assert_eq!(r.state(), State::Manual);
    assert!(
        r.status().pos_um[0] > PosUm::from_num(149_000),
        "in the new frame"
    );
    assert!(worst < 10.0, "the error stepped by {worst} µm at the edge");
}

#[test]
fn absolute_offsets_are_restored_and_reported() {
    let mut r = rt(RuntimeConfig::default());
    assert_eq!(r.absolute_offset_um(1), Some(PosUm::ZERO));
    r.restore_reference_offset(1, PosUm::from_num(-30)).unwrap();
    let mut b = Board1 {
        slaves: [0, 100],
        ..Board1::default()
    };
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().pos_um[1], PosUm::from_num(70));
    assert_eq!(
        r.restore_reference_offset(5, PosUm::ZERO),
        Err(CommandError::NoAxis { axis: 5 })
    );
    let mut r2 = rt(incremental());
    assert_eq!(r2.absolute_offset_um(0), None, "incremental: not persisted");
    // A persisted offset never makes an incremental axis look referenced.
    assert_eq!(
        r2.restore_reference_offset(0, PosUm::from_num(5)),
        Err(CommandError::NoAxis { axis: 0 })
    );
    assert_eq!(r2.status().reference[0], RefState::Unreferenced);
}

#[test]
fn dead_pressure_inputs_fault_only_when_required() {
    let mut b = Board1 {
        pressure_dead: true,
        ..Board1::default()
    };
    let mut free = rt(RuntimeConfig::default());
    free.tick_io(&mut b, Some(Command::Start), false);
    free.tick_io(&mut b, None, false);
    assert_eq!(free.state(), State::Following, "reported, not a fault");
    assert!(!free.status().pressure_ok);
    let mut req = rt(RuntimeConfig {
        pressure_required: true,
        ..RuntimeConfig::default()
    });
    req.tick_io(&mut b, Some(Command::Start), false);
    assert_eq!(req.state(), State::Fault);
    assert_eq!(req.fault().map(|f| f.fault), Some(Fault::PressureInput));
    assert!(!b.enable, "valves unpowered in the tick that saw it");
    assert_eq!(
        req.tick_io(&mut b, Some(Command::ClearFault), false),
        Some(Err(CommandError::CauseActive(Fault::PressureInput)))
    );
    b.pressure_dead = false;
    assert_eq!(
        req.tick_io(&mut b, Some(Command::ClearFault), false),
        Some(Ok(()))
    );
}

/// A new encoder scale reads the same counts in the new unit, keeps the slave's top
/// speed in µm/s (the count limit scales), drops an incremental slave's reference (its
/// offset was in the old scale) and keeps an absolute one's; refused while moving and
/// for an impossible scale, nothing changed.
#[test]
fn a_new_encoder_scale_reads_the_counts_anew_and_drops_an_incremental_reference() {
    let mut r = rt(incremental());
    let mut b = Board1 {
        slaves: [1000, 2000],
        ..Board1::default()
    };
    r.tick_io(
        &mut b,
        Some(Command::SetPosition {
            axis: 0,
            pos_um: PosUm::from_num(5000),
        }),
        false,
    );
    assert_eq!(r.status().reference[0], RefState::Referenced);
    // The scale in force, sent again (a settings file loaded back): the reference stays.
    assert_eq!(r.set_um_per_count(0, 1.0), Ok(()));
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().reference[0], RefState::Referenced);
    let limit0 = r.coeffs().slave_step_limit[0];
    assert_eq!(r.set_um_per_count(0, 0.5), Ok(()));
    assert_eq!(r.set_um_per_count(1, -2.0), Ok(()));
    assert_eq!(r.um_per_count(0), Some(0.5));
    assert_eq!(r.um_per_count(1), Some(-2.0));
    // Twice the counts for the same top speed on slave 0.
    assert_eq!(r.coeffs().slave_step_limit[0], 2 * limit0);
    r.tick_io(&mut b, None, false);
    assert_eq!(r.status().reference[0], RefState::Unreferenced);
    assert_eq!(r.status().reference[1], RefState::Referenced);
    assert_eq!(r.status().pos_um[0], PosUm::from_num(500));
    assert_eq!(r.status().pos_um[1], PosUm::from_num(-4000));
    assert_eq!(
        r.tick_io(&mut b, Some(Command::Start), false),
        Some(Err(CommandError::NotReferenced { axis: 0 }))
    );
    // Impossible scales and a missing slave: refused, the scale kept.
    for k in [0.0, 0.0001, 1001.0, f32::NAN] {
        assert_eq!(
            r.set_um_per_count(0, k),
            Err(CommandError::NoAxis { axis: 0 })
        );
    }
    assert_eq!(
        r.set_um_per_count(2, 1.0),
        Err(CommandError::NoAxis { axis: 2 })
    );
    assert_eq!(r.um_per_count(0), Some(0.5));
    // Not while following.
    let mut r = rt(incremental());
    let mut b = Board1::default();
    r.tick_io(
        &mut b,
        Some(Command::SetPosition {
            axis: 0,
            pos_um: PosUm::from_num(0),
        }),
        false,
    );
    assert_eq!(r.tick_io(&mut b, Some(Command::Start), false), Some(Ok(())));
    assert_eq!(r.set_um_per_count(0, 0.5), Err(CommandError::Busy));
    assert_eq!(r.um_per_count(0), Some(1.0));
}
