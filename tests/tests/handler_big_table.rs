//! A valid, non-flat 512-row table uploaded through `Handler<1, 512>` must commit
//! (and activate) — the protocol path of the `TableTooSteep` report. Tables are built in
//! place: a table built by value puts a frame of two tables (> 32 KiB) on the stack, and
//! x86-64's stack-probe loop for such a frame can clobber the register holding the
//! master top speed in builds with 16 codegen units and no LTO — the `bench` profile
//! `ci.sh` runs the host tests with —, so that every non-flat table of ≥ 409 rows is
//! refused ("TableCommit of a valid 512-row table: Nak { code: TableTooSteep,
//! detail: 1 }"). These tests run under `cargo test --profile bench` to catch that.

use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::msg::StatusMsg;
use hydra_core::protocol::ramflash::RamFlash;
use hydra_core::protocol::upload::TableUpload;
use hydra_core::protocol::{Device, Handler, Motion, Nak, ParamId, Request, Response, Store};
use hydra_core::table::{AxisLimits, CamTable, Node, TableLimits};
use hydra_core::units::{Master, MasterRate, PosUm, VelUmPerS};

const S: usize = 1;
const N: usize = 512;
const SLOT: u32 = 8 * 1024;

fn limits() -> TableLimits<S> {
    TableLimits {
        master_speed_per_s: MasterRate::from_num(10_000),
        axes: [AxisLimits {
            min_um: PosUm::from_num(0),
            max_um: PosUm::from_num(500_000),
            max_speed_um_per_s: VelUmPerS::from_num(250_000),
        }],
    }
}

/// 500 counts per row, a sine between 20 and 480 mm: steepest segment 5 750 µm per
/// 500 counts = 115 000 µm/s at 10 000 counts/s, well inside 250 000 µm/s.
fn wavy(rows: usize) -> Vec<Node<S>> {
    (0..rows)
        .map(|j| Node {
            master: Master::from_num(j as i64 * 500),
            slave_um: [PosUm::from_num(
                250_000.0 + 230_000.0 * (j as f64 * 0.05).sin(),
            )],
        })
        .collect()
}

#[derive(Default)]
struct Dev {
    table: Option<CamTable<S, N>>,
}

impl Device<S, N> for Dev {
    fn firmware(&self) -> [u8; 3] {
        [0, 1, 0]
    }
    fn period_us(&self) -> u32 {
        1000
    }
    fn table_limits(&self) -> TableLimits<S> {
        limits()
    }
    fn active_table(&self) -> Option<&CamTable<S, N>> {
        self.table.as_ref()
    }
    fn at_safe_point(&self) -> bool {
        true
    }
    fn all_idle(&self) -> bool {
        true
    }
    fn install_table(&mut self, t: &CamTable<S, N>) -> Result<(), Nak> {
        self.table = Some(t.clone());
        Ok(())
    }
    fn command(&mut self, _: Motion) -> Result<(), Nak> {
        Ok(())
    }
    fn set_param(&mut self, _: u8, _: ParamId, _: f32) -> Result<(), Nak> {
        Ok(())
    }
    fn get_param(&self, _: u8, _: ParamId) -> Result<f32, Nak> {
        Ok(0.0)
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        Ok(())
    }
    fn status(&self, _: &mut StatusMsg) {}
}

struct Rig {
    h: Box<Handler<S, N>>,
    dev: Box<Dev>,
    flash: RamFlash,
    seq: u16,
}

impl Rig {
    fn new() -> Self {
        let flash = RamFlash::new(2 * SLOT as usize);
        let store = Store::new::<_, S, N>(&flash, 0, SLOT).unwrap();
        Self {
            h: Box::new(Handler::new(store)),
            dev: Box::default(),
            flash,
            seq: 0,
        }
    }

    fn req(&mut self, q: &Request<'_>) -> Response {
        let s = if matches!(q, Request::Hello) {
            self.seq
        } else {
            self.seq.wrapping_add(1)
        };
        let mut b = [0u8; MAX_WIRE + 1];
        let n = encode_request(s, q, &mut b).unwrap();
        let mut out = Vec::new();
        self.h
            .on_bytes(&mut *self.dev, &mut self.flash, &b[..n], &mut |f| {
                out.extend_from_slice(f)
            });
        let mut d = FrameDecoder::new();
        let mut rs = Vec::new();
        for &x in &out {
            if let Some(f) = d.push(x) {
                let f = f.unwrap();
                rs.push((f.seq, Response::decode(f.ty, f.payload).unwrap()));
            }
        }
        assert_eq!(rs.len(), 1, "one answer per request");
        if !matches!(rs[0].1, Response::Nak { .. }) {
            self.seq = s;
        }
        rs.remove(0).1
    }
}

#[test]
fn a_valid_512_row_table_commits_through_the_handler() {
    let nodes = wavy(N);
    let mut r = Rig::new();
    assert!(matches!(r.req(&Request::Hello), Response::Info(_)));
    let per = Handler::<S, N>::MAX_CHUNK_ROWS;
    let mut up = TableUpload::new(5, &nodes, per).expect("a sendable table");
    let mut buf = vec![0u8; up.chunk_bytes()];
    while let Some(q) = up.next_request(&mut buf).expect("a chunk that fits") {
        let a = r.req(&q);
        assert!(
            matches!(a, Response::Ack { .. }),
            "{q:?} of a valid 512-row table: {a:?}"
        );
    }
    let act = r.req(&Request::Activate { id: 5 });
    assert!(matches!(act, Response::Ack { .. }), "Activate: {act:?}");
    let t = r.dev.table.as_ref().expect("installed");
    assert_eq!(t.len(), N);
    for (i, n) in nodes.iter().enumerate() {
        assert_eq!(t.node(i), Some(*n), "node {i}");
    }
}

/// The same table, built directly (no handler): the shortest form of the failure.
#[test]
fn a_valid_512_row_table_builds_directly() {
    let nodes = wavy(N);
    let t = CamTable::<S, N>::try_from_nodes(&nodes, &limits());
    assert!(
        t.is_ok(),
        "try_from_nodes of a valid 512-row table: {:?}",
        t.err()
    );
}

/// The virtual board (core's `BoardDevice` over host-sim's `Machine`, `Handler<2, CAPACITY>`):
/// a gentle, non-flat table of `CAPACITY` rows inside the board's limits (10 000 counts/s,
/// 0 … 500 mm at ≤ 200 mm/s): at most 1 mm per 500-count segment = 20 mm/s.
#[test]
fn a_valid_full_table_commits_on_the_virtual_board() {
    use host_sim::scenario::Scenario;
    use host_sim::vboard::{VBoard, CAPACITY};
    // Slave 0 (the tangent axis) moves, slave 1 (the side press) holds 20 mm.
    let nodes: Vec<Node<2>> = (0..CAPACITY)
        .map(|j| Node {
            master: Master::from_num(j as i64 * 500),
            slave_um: [
                PosUm::from_num(250_000.0 + 20_000.0 * (j as f64 * 0.05).sin()),
                PosUm::from_num(20_000),
            ],
        })
        .collect();
    let mut b = VBoard::new(&Scenario::default()).unwrap();
    let mut h = hydra_tests::VbHost::new(0);
    assert!(matches!(h.req(&mut b, &Request::Hello), Response::Info(_)));
    let commit = h.upload(&mut b, 9, &nodes);
    assert!(
        matches!(commit, Response::Ack { .. }),
        "TableCommit of a valid {CAPACITY}-row table on the virtual board: {commit:?}"
    );
    let a = h.req(&mut b, &Request::Activate { id: 9 });
    assert!(matches!(a, Response::Ack { .. }), "Activate: {a:?}");
    assert_eq!(b.handler.active_id(), 9);
}
