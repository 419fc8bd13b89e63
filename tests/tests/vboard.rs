//! The virtual board runs the firmware's tick path: core's `TickLoop` over the plant with
//! the board profile's two slaves. A command is applied by the next tick of the timeline
//! (exactly one tick, no extra plant step), the watchdog is fed once per tick, and the
//! slaves must be referenced before Start, as on the board.

use host_sim::scenario::Scenario;
use host_sim::vboard::VBoard;
use hydra_core::protocol::{NakCode, Request, Response};
use hydra_core::runtime::State;
use hydra_core::table::Node;
use hydra_core::units::{Master, PosUm};
use hydra_tests::VbHost;

/// Slave 0 at 250 mm, slave 1 (the side press) at its 10 mm start, held: a flat table.
fn flat_table() -> Vec<Node<2>> {
    (0..3)
        .map(|j| Node {
            master: Master::from_num(j * 1000),
            slave_um: [PosUm::from_num(250_000), PosUm::from_num(10_000)],
        })
        .collect()
}

/// Set-position of both slaves at the flat table's positions (they stand there).
fn reference_at_the_flat_table(h: &mut VbHost, b: &mut VBoard) {
    for (axis, um) in [(0u8, 250_000), (1, 10_000)] {
        h.ack(
            b,
            &Request::SetPosition {
                axis,
                pos_um: um << 8,
            },
        );
    }
}

#[test]
fn a_command_is_one_tick_of_the_timeline_and_start_needs_references() {
    let mut b = VBoard::new(&Scenario::default()).unwrap();
    let mut h = VbHost::new(3);
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    for _ in 0..20 {
        b.tick(&mut |_| ());
    }
    assert_eq!(b.ticks(), 20);
    let nodes = flat_table();
    assert!(matches!(h.upload(&mut b, 4, &nodes), Response::Ack { .. }));
    h.ack(&mut b, &Request::Activate { id: 4 });
    let t0 = b.ticks();
    // Unreferenced (incremental slaves, as the board's): Start refused naming slave 0.
    match h.req(&mut b, &Request::Start) {
        Response::Nak { nak, .. } => {
            assert_eq!((nak.code, nak.detail), (NakCode::NotReferenced, 0))
        }
        r => panic!("{r:?}"),
    }
    assert_eq!(
        b.ticks(),
        t0 + 1,
        "the command's tick is one tick of the timeline"
    );
    // A pause of the host longer than a period changes nothing: the next command applies.
    std::thread::sleep(std::time::Duration::from_millis(3));
    reference_at_the_flat_table(&mut h, &mut b);
    h.ack(&mut b, &Request::Start);
    assert_eq!(b.ticks(), t0 + 4);
    // The master's edges are timestamped as on the board (1 MHz): once it moves, the
    // runtime's master is below one count on most ticks (the count alone has no fraction).
    let mut fractional = 0;
    for _ in 0..600 {
        b.tick(&mut |_| ());
        let m = b.runtime().expect("booted").status().master;
        fractional += usize::from(m.get().frac() != 0);
    }
    assert!(
        fractional > 300,
        "{fractional} of 600 ticks below one count"
    );
    let rt = b.runtime().expect("booted");
    assert!(
        matches!(rt.state(), State::Following | State::Holding(_)),
        "{:?}",
        rt.state()
    );
    assert_eq!(rt.fault(), None);
    assert_eq!(b.machine.watchdog_feeds(), b.ticks(), "one feed per tick");
    assert!(b.machine.io.enabled(), "valves powered while following");
    // Both slaves hold their table positions within 0.1 mm.
    for (k, want) in [(0usize, 250_000.0), (1, 10_000.0)] {
        let x = rt.status().pos_um[k].to_num::<f64>();
        assert!((x - want).abs() < 100.0, "slave {k} at {x} µm");
    }
}

/// The tick that answers a command sends its telemetry too (the firmware's link task
/// takes every queued sample): no gap in the telemetry's tick numbers at a command.
#[test]
fn a_commands_tick_has_its_telemetry() {
    use hydra_core::protocol::frame::MAX_WIRE;
    use hydra_core::protocol::handler::encode_request;
    let mut b = VBoard::new(&Scenario::default()).unwrap();
    let frames = |b: &mut VBoard, seq: u16, q: &Request<'_>| {
        let mut f = [0u8; MAX_WIRE + 1];
        let n = encode_request(seq, q, &mut f).unwrap();
        hydra_tests::exchange(b, &f[..n])
    };
    assert!(matches!(
        frames(&mut b, 7, &Request::Hello)[0],
        Response::Info(_)
    ));
    let r = frames(&mut b, 8, &Request::SetTelemetry { decimation: 1 });
    assert!(matches!(r[0], Response::Ack { .. }), "{r:?}");
    let mut ticks = Vec::new();
    let mut tx = |x: &[u8]| ticks.extend_from_slice(x);
    b.tick(&mut tx);
    let r = frames(
        &mut b,
        9,
        &Request::SetPosition {
            axis: 0,
            pos_um: 250_000 << 8,
        },
    );
    assert!(matches!(r[0], Response::Ack { .. }), "{r:?}");
    let tel: Vec<u32> = r
        .iter()
        .filter_map(|x| match x {
            Response::Telemetry(t) => Some(t.tick),
            _ => None,
        })
        .collect();
    assert_eq!(tel, vec![b.runtime().unwrap().status().tick], "{r:?}");
}

/// The capture and the fault history against an adversarial host: impossible triggers
/// and lengths are refused with their codes, reads beyond the rows are empty, a damaged
/// frame is counted, and a capture around Start holds exactly the ticks asked for.
#[test]
fn the_capture_and_the_fault_history_refuse_nonsense_and_count_damage() {
    use hydra_core::protocol::diag::{capture_row_len, take_capture_row};
    use hydra_core::protocol::wire::Reader;
    let mut b = VBoard::new(&Scenario::default()).unwrap();
    let mut h = VbHost::new(9);
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    let arm = |trigger, channel, axis, pre, post| {
        Request::CaptureArm(hydra_core::protocol::diag::CaptureArmMsg {
            trigger,
            channel,
            axis,
            value: 0,
            pre,
            post,
        })
    };
    let nak = |r: Response| match r {
        Response::Nak { nak, .. } => (nak.code, nak.detail),
        r => panic!("{r:?}"),
    };
    assert_eq!(
        nak(h.req(&mut b, &arm(9, 0, 0, 1, 1))),
        (NakCode::CaptureTrigger, 9)
    );
    assert_eq!(
        nak(h.req(&mut b, &arm(4, 9, 0, 1, 1))).0,
        NakCode::CaptureTrigger
    );
    assert_eq!(
        nak(h.req(&mut b, &arm(4, 3, 5, 1, 1))),
        (NakCode::NoAxis, 5)
    );
    assert_eq!(
        nak(h.req(&mut b, &arm(0, 0, 0, u32::MAX, u32::MAX))),
        (NakCode::CaptureTooLong, 2048)
    );
    assert_eq!(
        nak(h.req(&mut b, &arm(0, 0, 0, 1024, 1024))),
        (NakCode::CaptureTooLong, 2048)
    );
    // Nothing armed yet: phase 0, no rows, whatever the offset.
    for offset in [0, 1999, u32::MAX] {
        match h.req(&mut b, &Request::GetCapture { offset, count: 255 }) {
            Response::Capture(c) => assert!(c.phase == 0 && c.data.is_empty(), "{c:?}"),
            r => panic!("{r:?}"),
        }
    }
    // A damaged frame (its CRC flipped) is a Nak and counted.
    let mut f = [0u8; 64];
    let n = hydra_core::protocol::handler::encode_request(0, &Request::GetStatus, &mut f).unwrap();
    f[n - 3] ^= 0x55; // a CRC byte (the delimiter is last)
    let answers = hydra_tests::exchange(&mut b, &f[..n]);
    assert!(
        matches!(answers.as_slice(), [Response::Nak { .. }]),
        "{answers:?}"
    );
    let link = match h.req(&mut b, &Request::GetFaults) {
        Response::Faults(fm) => fm.link,
        r => panic!("{r:?}"),
    };
    // Five refused arms; the damaged frame counts as damaged only.
    assert_eq!((link.bad_frames, link.naks), (1, 5), "{link:?}");
    // A capture of 10 + 1 + 20 ticks around the Start command.
    let nodes = flat_table();
    assert!(matches!(h.upload(&mut b, 4, &nodes), Response::Ack { .. }));
    h.ack(&mut b, &Request::Activate { id: 4 });
    reference_at_the_flat_table(&mut h, &mut b);
    h.ack(&mut b, &arm(3, 0, 0, 10, 20));
    for _ in 0..30 {
        b.tick(&mut |_| ());
    }
    h.ack(&mut b, &Request::Start);
    for _ in 0..30 {
        b.tick(&mut |_| ());
    }
    let mut rows = Vec::new();
    loop {
        let q = Request::GetCapture {
            offset: rows.len() as u32,
            count: 255,
        };
        let Response::Capture(c) = h.req(&mut b, &q) else {
            panic!("GetCapture")
        };
        assert_eq!((c.phase, c.pre, c.rows), (3, 10, 31));
        assert_eq!(c.data.len() % capture_row_len(2), 0);
        if c.data.is_empty() {
            break;
        }
        let mut r = Reader::new(&c.data);
        while r.remaining() > 0 {
            rows.push(take_capture_row(&mut r, 2).unwrap());
        }
    }
    assert_eq!(rows.len(), 31);
    assert_eq!(rows[10].flags & 0b111, 1, "the Start tick is following");
    assert_ne!(rows[10].flags & hydra_core::runtime::FLAG_COMMAND, 0);
    assert!(
        rows[..10].iter().all(|r| r.flags & 0b111 == 0),
        "idle before"
    );
    // Reads past the end are empty, and the count of 0 reads only the state.
    for (offset, count) in [(31, 255), (u32::MAX, 255), (0, 0)] {
        match h.req(&mut b, &Request::GetCapture { offset, count }) {
            Response::Capture(c) => assert!(c.data.is_empty() && c.rows == 31),
            r => panic!("{r:?}"),
        }
    }
}
