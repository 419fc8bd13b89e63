//! The PLC server against the handler and a mock device: ownership between the serial
//! host and the PLC, every exception, the parameter channel, commands and the heartbeat.

use super::handler_tests::{loaded_rig, nak_code, Rig};
use super::msg::{NakCode, ParamId, Request, Response};
use crate::plc::map::{CommandBit, StatusBit};
use crate::plc::server::{param_result, ACK_DONE, ACK_ENABLE_OFF};
use crate::plc::{Exception, Live, Server, Side};
use crate::runtime::Status;

type Srv = Server<1>;

fn write(r: &mut Rig, s: &mut Srv, start: u16, v: &[u16], now_ms: u32) -> Result<(), Exception> {
    s.write(&mut r.h, &mut r.dev, &mut r.flash, start, v, now_ms)
}

fn holding(s: &Srv, start: u16, n: usize) -> std::vec::Vec<u16> {
    let mut out = std::vec![0u16; n];
    s.read_holding(start, &mut out).unwrap();
    out
}

fn input(r: &Rig, s: &Srv, start: u16, n: usize) -> std::vec::Vec<u16> {
    use crate::runtime::{FaultSet, ManualKind, RefState, State};
    use crate::units::{DacCode, Master, PosUm, PressureBar};
    let st: Status<1, 2> = Status {
        tick: 0,
        state: State::Idle,
        fault: None,
        fault_set: FaultSet::EMPTY,
        master: Master::ZERO,
        pos_um: [PosUm::ZERO],
        target_um: [PosUm::ZERO],
        error_um: [PosUm::ZERO],
        dac: [DacCode::NULL],
        enable: false,
        estop: false,
        pressure_bar: [PressureBar::ZERO; 2],
        timing: Default::default(),
        reference: [RefState::Referenced],
        pressure_ok: true,
        manual: [ManualKind::Hold],
    };
    let live = Live {
        master_speed_counts_per_s: 0,
        tick_max_us: 0,
        backoff_level: [0],
    };
    let mut out = std::vec![0u16; n];
    s.read_input(&r.h, &r.dev, &st, &live, start, &mut out)
        .unwrap();
    out
}

const CMD: u16 = 0;
const HEARTBEAT: u16 = 2;
const OWNER: u16 = 3;

fn bits(b: &[CommandBit]) -> u16 {
    b.iter().fold(0, |m, b| m | b.mask())
}

/// A PLC that owns an idle board with table 2 active.
fn plc_owned() -> (Rig, Srv) {
    let mut r = loaded_rig();
    let mut s = Srv::new(0);
    write(&mut r, &mut s, OWNER, &[2], 0).unwrap();
    assert_eq!(r.h.owner(), Side::Plc);
    (r, s)
}

#[test]
fn the_host_owns_a_free_board_by_using_it_and_the_plc_is_refused_with_01() {
    let mut r = loaded_rig();
    // loaded_rig's Activate and Save took the free board for the serial host.
    assert_eq!(r.h.owner(), Side::Host);
    let mut s = Srv::new(0);
    let start = bits(&[CommandBit::Enable, CommandBit::Start]);
    assert_eq!(
        write(&mut r, &mut s, CMD, &[start], 0),
        Err(Exception::IllegalFunction)
    );
    assert!(!r.dev.running, "a refused write changes nothing");
    assert_eq!(holding(&s, CMD, 1), [0], "nor is it stored");
    // Reads and the free registers are allowed.
    assert_eq!(input(&r, &s, 0, 2)[1], 0);
    write(&mut r, &mut s, HEARTBEAT, &[7], 0).unwrap();
    // At rest the PLC may take the machine; then the host is refused (Stop excepted).
    write(&mut r, &mut s, OWNER, &[2], 0).unwrap();
    let st = input(&r, &s, 0, 1)[0];
    assert_ne!(st & (1 << StatusBit::OwnerIsPlc as u8), 0);
    assert_eq!(nak_code(&r.req(&Request::Start)), NakCode::NotOwner);
    assert!(!r.dev.running);
    r.ack(&Request::Stop);
    // The host takes it back at rest with Owner; the PLC cannot while the host runs.
    r.ack(&Request::Owner { side: 1 });
    r.ack(&Request::Start);
    assert!(r.dev.running);
    assert_eq!(
        write(&mut r, &mut s, OWNER, &[2], 0),
        Err(Exception::IllegalFunction)
    );
    assert_eq!(r.h.owner(), Side::Host);
    // Only the owner releases.
    assert_eq!(
        write(&mut r, &mut s, OWNER, &[0], 0),
        Err(Exception::IllegalFunction)
    );
    r.ack(&Request::Owner { side: 0 });
    assert_eq!(r.h.owner(), Side::None);
    assert_eq!(
        nak_code(&r.req(&Request::Owner { side: 2 })),
        NakCode::Malformed,
        "the serial host cannot hand the machine to the PLC"
    );
}

#[test]
fn bad_addresses_are_02_and_bad_values_03_and_nothing_changes() {
    let (mut r, mut s) = plc_owned();
    let e = |r: &mut Rig, s: &mut Srv, a: u16, v: &[u16]| write(r, s, a, v, 0).unwrap_err();
    assert_eq!(e(&mut r, &mut s, 30, &[1]), Exception::IllegalAddress);
    assert_eq!(
        e(&mut r, &mut s, 13, &[1]),
        Exception::IllegalAddress,
        "split f32"
    );
    assert_eq!(
        e(&mut r, &mut s, 120, &[0, 1]),
        Exception::IllegalAddress,
        "axis 1 of 1"
    );
    assert_eq!(e(&mut r, &mut s, OWNER, &[3]), Exception::IllegalValue);
    assert_eq!(
        e(&mut r, &mut s, 11, &[7]),
        Exception::IllegalValue,
        "param.op"
    );
    assert_eq!(
        e(&mut r, &mut s, 1, &[1]),
        Exception::IllegalValue,
        "command_axis 1 of 1"
    );
    assert_eq!(e(&mut r, &mut s, CMD, &[1 << 11]), Exception::IllegalValue);
    let both = bits(&[CommandBit::JogPos, CommandBit::JogNeg]);
    assert_eq!(e(&mut r, &mut s, CMD, &[both]), Exception::IllegalValue);
    let far = (9_000_000i32 as u32).to_be_bytes();
    let far = [
        u16::from_be_bytes([far[0], far[1]]),
        u16::from_be_bytes([far[2], far[3]]),
    ];
    assert_eq!(e(&mut r, &mut s, 100, &far), Exception::IllegalValue);
    assert_eq!(holding(&s, 100, 2), [0, 0]);
    let mut out = [0u16; 1];
    assert_eq!(s.read_holding(30, &mut out), Err(Exception::IllegalAddress));
}

/// Writes `param.id`, `param.op`, `param.value`, `param.axis` in one write.
fn param(r: &mut Rig, s: &mut Srv, id: ParamId, op: u16, v: f32) -> Result<(), Exception> {
    let b = v.to_bits();
    write(r, s, 10, &[id as u16, op, (b >> 16) as u16, b as u16, 0], 0)
}

#[test]
fn the_parameter_channel_is_validated_as_the_serial_link() {
    let (mut r, mut s) = plc_owned();
    param(&mut r, &mut s, ParamId::KpLsbPerUm, 2, 2.5).unwrap();
    assert_eq!(r.dev.kp, 2.5);
    assert_eq!(input(&r, &s, 7, 1), [param_result::DONE]);
    assert_eq!(
        param(&mut r, &mut s, ParamId::KpLsbPerUm, 2, 5000.0),
        Err(Exception::IllegalValue)
    );
    assert_eq!(r.dev.kp, 2.5, "an out-of-range value changes nothing");
    assert_eq!(input(&r, &s, 7, 1), [param_result::RANGE]);
    assert_eq!(
        param(&mut r, &mut s, ParamId::PeriodUs, 2, 500.0),
        Err(Exception::IllegalValue)
    );
    assert_eq!(input(&r, &s, 7, 1), [param_result::READ_ONLY]);
    // A handler-held setting, and a read back.
    param(&mut r, &mut s, ParamId::PlcHeartbeatMs, 2, 250.0).unwrap();
    assert_eq!(r.h.plc_settings().heartbeat_ms(), 250);
    param(&mut r, &mut s, ParamId::KpLsbPerUm, 1, 0.0).unwrap();
    let w = input(&r, &s, 8, 2);
    assert_eq!(
        f32::from_bits((u32::from(w[0]) << 16) | u32::from(w[1])),
        2.5
    );
    // A read needs no ownership; a write does.
    r.h.take_owner(&r.dev, Side::Plc, Side::None).unwrap();
    param(&mut r, &mut s, ParamId::KpLsbPerUm, 1, 0.0).unwrap();
    assert_eq!(
        param(&mut r, &mut s, ParamId::KpLsbPerUm, 2, 1.0),
        Err(Exception::IllegalFunction)
    );
    assert_eq!(r.dev.kp, 2.5);
}

#[test]
fn commands_act_on_edges_need_enable_and_report_their_outcome() {
    let (mut r, mut s) = plc_owned();
    let start = bits(&[CommandBit::Start]);
    assert_eq!(
        write(&mut r, &mut s, CMD, &[start], 0),
        Err(Exception::DeviceFailure)
    );
    assert_eq!(input(&r, &s, 4, 2), [ACK_ENABLE_OFF, 1]);
    assert_eq!(holding(&s, CMD, 1), [0], "a refused command is not stored");
    let go = bits(&[CommandBit::Enable, CommandBit::Start]);
    write(&mut r, &mut s, CMD, &[go], 0).unwrap();
    assert!(r.dev.running, "start approaches the table, then follows");
    assert_eq!(input(&r, &s, 4, 2), [ACK_DONE, 2]);
    // The same bits again are no edge: nothing new.
    write(&mut r, &mut s, CMD, &[go], 0).unwrap();
    assert_eq!(input(&r, &s, 5, 1), [2]);
    // Clearing enable stops.
    write(&mut r, &mut s, CMD, &[0], 0).unwrap();
    assert!(!r.dev.running);
    // A device refusal: the serial Nak's code in command_ack, exception 04.
    let mv = bits(&[CommandBit::Enable, CommandBit::Move]);
    write(&mut r, &mut s, 102, &[0, 100], 0).unwrap();
    assert_eq!(
        write(&mut r, &mut s, CMD, &[mv], 0),
        Err(Exception::DeviceFailure)
    );
    assert_eq!(input(&r, &s, 4, 1), [0x100 | NakCode::BadState as u16]);
}

#[test]
fn a_jog_runs_while_its_bit_is_set_and_is_renewed() {
    let (mut r, mut s) = plc_owned();
    write(&mut r, &mut s, 102, &[0, 2000], 0).unwrap();
    let jog = bits(&[CommandBit::Enable, CommandBit::JogNeg]);
    write(&mut r, &mut s, CMD, &[jog], 0).unwrap();
    assert_eq!((r.dev.jogs, r.dev.jog_speed), (1, -2000 * 256));
    for t in [50, 100, 150, 200] {
        write(&mut r, &mut s, HEARTBEAT, &[t as u16], t).unwrap();
        s.poll(&mut r.h, &mut r.dev, &mut r.flash, t);
    }
    assert_eq!(r.dev.jogs, 3, "renewed every 100 ms");
    write(&mut r, &mut s, CMD, &[bits(&[CommandBit::Enable])], 210).unwrap();
    assert_eq!(
        (r.dev.jogs, r.dev.jog_speed),
        (4, 0),
        "its bit cleared: speed 0"
    );
}

#[test]
fn a_lost_heartbeat_holds_a_run_the_plc_started_and_frees_the_machine() {
    let (mut r, mut s) = plc_owned();
    param(&mut r, &mut s, ParamId::PlcHeartbeatMs, 2, 200.0).unwrap();
    let go = bits(&[CommandBit::Enable, CommandBit::Start]);
    write(&mut r, &mut s, CMD, &[go], 0).unwrap();
    for t in (10..=150).step_by(10) {
        write(&mut r, &mut s, HEARTBEAT, &[t as u16], t).unwrap();
        assert!(!s.poll(&mut r.h, &mut r.dev, &mut r.flash, t));
    }
    assert_eq!(r.dev.holds, 0);
    // Silence: held 200 ms after the last change, once.
    assert!(!s.poll(&mut r.h, &mut r.dev, &mut r.flash, 349));
    assert!(s.poll(&mut r.h, &mut r.dev, &mut r.flash, 350));
    assert_eq!(r.dev.holds, 1);
    assert!(!s.poll(&mut r.h, &mut r.dev, &mut r.flash, 400));
    assert_eq!(r.dev.holds, 1);
    let st = input(&r, &s, 0, 1)[0];
    assert_ne!(st & (1 << StatusBit::HeartbeatLost as u8), 0);
    // The PLC timed out: the host may take the machine although it still runs.
    assert!(r.dev.running);
    r.ack(&Request::Owner { side: 1 });
    assert_eq!(r.h.owner(), Side::Host);
}

#[test]
fn a_plc_start_is_not_watched_by_the_serial_link() {
    let (mut r, mut s) = plc_owned();
    r.h.take_owner(&r.dev, Side::Plc, Side::None).unwrap();
    r.set_param(ParamId::LinkTimeoutMs, 100.0);
    r.ack(&Request::Owner { side: 0 });
    write(&mut r, &mut s, OWNER, &[2], 0).unwrap();
    let go = bits(&[CommandBit::Enable, CommandBit::Start]);
    write(&mut r, &mut s, CMD, &[go], 0).unwrap();
    for ms in [0, 500, 1000] {
        r.h.watch_link(&mut r.dev, ms);
    }
    assert_eq!(r.dev.holds, 0);
    assert!(matches!(r.req(&Request::GetStatus), Response::Status(_)));
}
