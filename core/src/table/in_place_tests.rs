//! Building tables in place, and large tables under the profile the tests run with.
//!
//! `cargo test --release` uses the workspace's `[profile.bench]` (16 codegen units, no
//! LTO). Under it, rustc 1.95's LLVM miscompiled `try_from_nodes` on x86-64 while that
//! function's frame held a whole table and exceeded 32 KiB (stack probes): the probe loop
//! reused the register still holding the master top speed, and every non-flat table of
//! ≥ 409 rows (S = 1) was refused as `TooSteep`. The table is now built in place (no
//! segment array in the frame); these tests build valid tables of the board's and the
//! simulator's sizes through both entry points and would fail on that bug.

use super::*;
use std::boxed::Box;
use std::vec::Vec;

/// A valid, non-flat table of `rows` nodes: 0.5° (500 counts) per node, a sine-like
/// profile between 20 and 480 mm with slopes well inside the limits below.
fn wavy(rows: usize) -> Vec<Node<1>> {
    (0..rows)
        .map(|j| {
            let x = 250_000.0 + 230_000.0 * (j as f64 * 0.05).sin();
            Node {
                master: Master::from_num(j as i64 * 500),
                slave_um: [PosUm::from_num(x)],
            }
        })
        .collect()
}

fn limits() -> TableLimits<1> {
    TableLimits {
        // 10 °/s: the board's master top speed.
        master_speed_per_s: MasterRate::from_num(10_000),
        axes: [AxisLimits {
            min_um: PosUm::from_num(0),
            max_um: PosUm::from_num(500_000),
            max_speed_um_per_s: VelUmPerS::from_num(250_000),
        }],
    }
}

fn check_built<const N: usize>(t: &CamTable<1, N>, nodes: &[Node<1>]) {
    assert_eq!(t.len(), nodes.len());
    for (i, n) in nodes.iter().enumerate() {
        assert_eq!(t.node(i), Some(*n), "node {i}");
    }
}

#[test]
fn a_512_row_table_builds_by_value_and_in_place() {
    let nodes = wavy(512);
    let t = CamTable::<1, 512>::try_from_nodes(&nodes, &limits()).expect("valid 512-row table");
    check_built(&t, &nodes);
    let mut b: Box<CamTable<1, 512>> = Box::new(CamTable::empty());
    b.rebuild_from_nodes(&nodes, &limits())
        .expect("valid 512-row table");
    check_built(&b, &nodes);
    assert_eq!(*b, t);
}

#[test]
fn a_4096_row_table_builds_in_place() {
    // host-sim's capacity (160 KiB): only ever built in place on the heap.
    let nodes = wavy(4096);
    let mut b: Box<CamTable<1, 4096>> = Box::new(CamTable::empty());
    b.rebuild_from_nodes(&nodes, &limits())
        .expect("valid 4096-row table");
    check_built(&b, &nodes);
}

#[test]
fn the_board_capacity_of_two_slaves_builds_in_place() {
    let nodes: Vec<Node<2>> = wavy(256)
        .iter()
        .map(|n| Node {
            master: n.master,
            slave_um: [n.slave_um[0], PosUm::from_num(20_000)],
        })
        .collect();
    let lim = TableLimits {
        master_speed_per_s: limits().master_speed_per_s,
        axes: [limits().axes[0]; 2],
    };
    let mut b: Box<CamTable<2, 256>> = Box::new(CamTable::empty());
    b.rebuild_from_nodes(&nodes, &lim)
        .expect("valid 256-row table");
    assert_eq!(b.len(), 256);
    assert_eq!(b.node(255), nodes.last().copied());
}

#[test]
fn a_refused_rebuild_leaves_the_table_unchanged() {
    let good = wavy(64);
    let mut t: CamTable<1, 64> = CamTable::empty();
    t.rebuild_from_nodes(&good, &limits()).unwrap();
    let before = t.clone();
    // Each kind of refusal, each found only late in the table.
    let mut steep = wavy(64);
    steep[60].slave_um[0] = PosUm::from_num(499_000);
    let mut not_mono = wavy(64);
    not_mono[63].master = not_mono[62].master;
    let mut out = wavy(64);
    out[50].slave_um[0] = PosUm::from_num(-1);
    let too_many = wavy(65);
    for (bad, e) in [
        (&steep[..], TableError::TooSteep { row: 60, axis: 0 }),
        (&not_mono[..], TableError::NotMonotonic { row: 63 }),
        (&out[..], TableError::OutOfRange { row: 50, axis: 0 }),
        (&too_many[..], TableError::TooManyNodes { capacity: 64 }),
        (&good[..1], TableError::TooFewNodes),
    ] {
        let first_error = t.rebuild_from_nodes(bad, &limits()).unwrap_err();
        assert!(
            matches!(
                (first_error, e),
                (TableError::TooSteep { .. }, TableError::TooSteep { .. })
                    | (
                        TableError::NotMonotonic { .. },
                        TableError::NotMonotonic { .. }
                    )
                    | (TableError::OutOfRange { .. }, TableError::OutOfRange { .. })
                    | (
                        TableError::TooManyNodes { .. },
                        TableError::TooManyNodes { .. }
                    )
                    | (TableError::TooFewNodes, TableError::TooFewNodes)
            ),
            "{first_error:?} for {e:?}"
        );
        assert_eq!(t, before, "a refused rebuild ({e:?}) changed the table");
    }
}

#[test]
fn copy_from_and_empty() {
    let e: CamTable<1, 16> = CamTable::empty();
    assert!(e.is_empty());
    assert_eq!(e.len(), 0);
    assert_eq!(e.node(0), None);
    let mut lk_cursor = 3;
    // Lookups on the placeholder never panic.
    let lk = e.locate(&mut lk_cursor, Master::from_num(5));
    let _ = e.value(&lk, 0);
    let _ = e.rise(&lk, 0);
    let t = CamTable::<1, 16>::try_from_nodes(&wavy(10), &limits()).unwrap();
    let mut c: CamTable<1, 16> = CamTable::empty();
    c.copy_from(&t);
    assert_eq!(c, t);
    assert!(!c.is_empty());
}
