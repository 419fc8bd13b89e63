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

#[test]
fn a_command_is_one_tick_of_the_timeline_and_start_needs_references() {
    let mut b = VBoard::new(&Scenario::default()).unwrap();
    let mut h = VbHost::new(3);
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    for _ in 0..20 {
        b.tick(&mut |_| ());
    }
    assert_eq!(b.ticks(), 20);
    // Slave 0 at 250 mm, slave 1 (the side press) at its 10 mm start, held: a flat table.
    let nodes: Vec<Node<2>> = (0..3)
        .map(|j| Node {
            master: Master::from_num(j * 1000),
            slave_um: [PosUm::from_num(250_000), PosUm::from_num(10_000)],
        })
        .collect();
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
    for (axis, um) in [(0u8, 250_000), (1, 10_000)] {
        h.ack(
            &mut b,
            &Request::SetPosition {
                axis,
                pos_um: um << 8,
            },
        );
    }
    h.ack(&mut b, &Request::Start);
    assert_eq!(b.ticks(), t0 + 4);
    for _ in 0..200 {
        b.tick(&mut |_| ());
    }
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
