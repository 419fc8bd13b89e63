//! Settings come back as they were saved, on the virtual board: a
//! saved set is applied at boot as one validated set, never replayed one by one.

use host_sim::scenario::Scenario;
use host_sim::vboard::VBoard;
use hydra_core::protocol::{NakCode, ParamId, Request, Response};
use hydra_core::table::Node;
use hydra_core::units::{Master, PosUm};
use hydra_tests::VbHost;

/// A host of the virtual board with the two things these tests do.
struct Host(VbHost);

impl Host {
    fn req(&mut self, b: &mut VBoard, q: &Request<'_>) -> Response {
        self.0.req(b, q)
    }

    fn ack(&mut self, b: &mut VBoard, q: &Request<'_>) {
        self.0.ack(b, q)
    }

    fn param(&mut self, b: &mut VBoard, param: ParamId, value: f32) {
        self.0.ack(
            b,
            &Request::SetParam {
                axis: 0,
                param: param as u8,
                value,
            },
        );
    }

    /// Uploads a flat table, slave 0 at `x_mm` (three nodes, 1 000 counts apart) and commits it.
    fn commit(&mut self, b: &mut VBoard, id: u32, x_mm: f64) -> Response {
        // Slave 0 at `x_mm`, slave 1 (the side press) at 20 mm.
        let nodes: Vec<Node<2>> = (0..3)
            .map(|j| Node {
                master: Master::from_num(j * 1000),
                slave_um: [PosUm::from_num(x_mm * 1000.0), PosUm::from_num(20_000)],
            })
            .collect();
        self.0.upload(b, id, &nodes)
    }
}

#[test]
fn limits_set_in_any_order_come_back_exactly_after_a_power_cycle() {
    let scn = Scenario::default();
    let mut b = VBoard::new(&scn).unwrap();
    let mut h = Host(VbHost::new(1));
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    // min 100 mm, max 700 mm, then min 550 mm (the first record replaced in place).
    h.param(&mut b, ParamId::MinUm, 100_000.0);
    h.param(&mut b, ParamId::MaxUm, 700_000.0);
    h.param(&mut b, ParamId::MinUm, 550_000.0);
    assert!(matches!(h.commit(&mut b, 1, 560.0), Response::Ack { .. }));
    h.ack(&mut b, &Request::Activate { id: 1 });
    h.ack(&mut b, &Request::Save);
    // Power cycle: a new board on the same flash.
    let mut b2 = VBoard::with_flash(&scn, b.flash.clone()).unwrap();
    let mut h2 = Host(VbHost::new(9));
    match h2.req(&mut b2, &Request::Hello) {
        Response::Info(i) => {
            assert_eq!(i.active_id, 1, "the saved table boots");
            // Info reports the limits in force: the saved ones, I24F8 raw µm.
            assert_eq!(
                (i.limits.axes[0].min_um, i.limits.axes[0].max_um),
                (550_000 << 8, 700_000 << 8)
            );
            assert_eq!((i.axes, i.capacity_rows, i.law_buffers), (2, 256, 2));
        }
        r => panic!("{r:?}"),
    }
    // The limits are [550, 700] mm again: a table at 100 mm is refused, as before the
    // power cycle (replayed one by one, min 550 failed against the boot max and the
    // limits came back as [0, 700] mm, accepting it).
    match h2.commit(&mut b2, 2, 100.0) {
        Response::Nak { nak, .. } => assert_eq!(nak.code, NakCode::TableOutOfRange),
        r => panic!("a 100 mm table must be refused by the saved limits: {r:?}"),
    }
    assert!(matches!(h2.commit(&mut b2, 3, 600.0), Response::Ack { .. }));
}

/// `serve --flash FILE`: the flash image survives the board's process — a restart on the
/// same file boots the saved table with its settings; a file of the wrong size is refused
/// with a message naming it.
#[test]
fn a_flash_file_makes_a_restart_a_power_cycle() {
    let scn = Scenario::default();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("board.flash");
    let mut b = VBoard::with_flash_file(&scn, &path).unwrap();
    let mut seen = b.flash.ops;
    let mut h = Host(VbHost::new(3));
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    h.param(&mut b, ParamId::MaxUm, 450_000.0);
    assert!(matches!(h.commit(&mut b, 7, 300.0), Response::Ack { .. }));
    h.ack(&mut b, &Request::Activate { id: 7 });
    h.ack(&mut b, &Request::Save);
    b.persist(&path, &mut seen).unwrap();
    drop(b);
    let mut b2 = VBoard::with_flash_file(&scn, &path).unwrap();
    let mut h2 = Host(VbHost::new(40));
    match h2.req(&mut b2, &Request::Hello) {
        Response::Info(i) => assert_eq!(i.active_id, 7),
        r => panic!("{r:?}"),
    }
    // The saved max (450 mm) is back: a table at 460 mm is refused.
    match h2.commit(&mut b2, 8, 460.0) {
        Response::Nak { nak, .. } => assert_eq!(nak.code, NakCode::TableOutOfRange),
        r => panic!("{r:?}"),
    }
    std::fs::write(&path, [0u8; 10]).unwrap();
    let e = VBoard::with_flash_file(&scn, &path)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("board.flash") && e.contains("10 bytes"), "{e}");
}

/// The both-direction Kv (id 4) is saved as the two it set: Kv 0.02, Kv− 0.03, Kv 0.05
/// leave both at 0.05, and after a power cycle both are 0.05 again (replaying an id-4
/// record after Kv− would give Kv− 0.03). A board-wide parameter set with a non-zero axis
/// byte is one setting (the last value), not one per axis byte.
#[test]
fn both_kv_and_board_wide_settings_come_back_as_they_were_set() {
    let scn = Scenario::default();
    let mut b = VBoard::new(&scn).unwrap();
    let mut h = Host(VbHost::new(5));
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    h.param(&mut b, ParamId::KvLsbPerUmS, 0.02);
    h.param(&mut b, ParamId::KvNegLsbPerUmS, 0.03);
    h.param(&mut b, ParamId::KvLsbPerUmS, 0.05);
    for (axis, hz) in [(1u8, 12.0f32), (0, 9.0)] {
        h.ack(
            &mut b,
            &Request::SetParam {
                axis,
                param: ParamId::MasterFilterHz as u8,
                value: hz,
            },
        );
    }
    h.ack(&mut b, &Request::Save);
    let mut b2 = VBoard::with_flash(&scn, b.flash.clone()).unwrap();
    let mut h2 = Host(VbHost::new(60));
    assert!(matches!(
        h2.req(&mut b2, &Request::Hello),
        Response::Info(_)
    ));
    let mut get = |p: ParamId| match h2.req(
        &mut b2,
        &Request::GetParam {
            axis: 0,
            param: p as u8,
        },
    ) {
        Response::Param { value, .. } => value,
        r => panic!("{p:?}: {r:?}"),
    };
    assert_eq!(get(ParamId::KvPosLsbPerUmS), 0.05);
    assert_eq!(get(ParamId::KvNegLsbPerUmS), 0.05);
    assert_eq!(get(ParamId::MasterFilterHz), 9.0);
}
