//! `board-emu --pty`: host-sim's own board commands (its serial `Link`, `upload`) against
//! the real firmware binary on a pseudo-terminal, exactly as against a board.

mod common;

use common::*;
use hydra_core::protocol::{Request, Response};
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn host_sim_uploads_activates_saves_and_reads_status_over_the_pty() {
    let elf = {
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map_or_else(|| root().join("target"), std::path::PathBuf::from);
        target.join("thumbv7em-none-eabihf/release/firmware")
    };
    let _ = image(); // fails clearly if the ELF is missing
    let mut child = Kill(
        Command::new(env!("CARGO_BIN_EXE_board-emu"))
            .args(["--pty", "--elf"])
            .arg(&elf)
            .stdout(Stdio::piped())
            .spawn()
            .expect("board-emu starts"),
    );
    let mut line = String::new();
    BufReader::new(child.0.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("the PTY path");
    let port = line.trim().to_string();
    assert!(port.starts_with("/dev/"), "{port:?}");
    std::thread::sleep(std::time::Duration::from_millis(300)); // boot

    // A two-column table (the board's two slaves): the tangent column and slave 1 at 20 mm.
    let t = table(&scenario());
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("two.csv");
    let mut text = String::from("master,tangent,side\n");
    for (m, x) in t.master.iter().zip(&t.columns[0]) {
        text.push_str(&format!("{m},{x},20\n"));
    }
    std::fs::write(&csv, text).expect("write csv");
    host_sim::cmd::upload::run(&host_sim::cmd::upload::Args {
        port: port.clone(),
        table: csv,
        activate: true,
        save: true,
        id: Some(77),
        master_counts_per_unit: 1000.0,
    })
    .expect("host-sim upload --activate --save");

    // Reference both slaves (this board's encoders are incremental), then Start and Stop
    // with host-sim's own motion command.
    let motion = |what, axis, mm| {
        host_sim::cmd::motion::run(&host_sim::cmd::motion::Args {
            port: port.clone(),
            what,
            axis,
            mm,
            master_op: None,
            speed_scale: None,
            manual: Default::default(),
            test: Default::default(),
        })
    };
    // A manual motion with its options (`motion move --to-mm`, `start --approach`).
    let manual = |what, axis, m: host_sim::cmd::manual::ManualArgs| {
        host_sim::cmd::motion::run(&host_sim::cmd::motion::Args {
            port: port.clone(),
            what,
            axis,
            mm: None,
            master_op: None,
            speed_scale: None,
            manual: m,
            test: Default::default(),
        })
    };
    use host_sim::cmd::motion::What;
    let e = motion(What::Start, None, None).expect_err("Start before the slaves are referenced");
    assert!(format!("{e}").contains("not referenced"), "{e}");
    // Before referencing, the board's position is its encoder's count since boot: how far
    // the piston drifted from where the emulated machine started it (identification
    // needs the cylinder's frame below).
    let raw0_mm = {
        let mut l = host_sim::cmd::serial::Link::open(&port).expect("Hello");
        match l.request(&Request::GetStatus).expect("GetStatus") {
            Response::Status(s) => f64::from(s.axes[0].pos_um) / 256_000.0,
            r => panic!("{r:?}"),
        }
    };
    motion(What::SetPosition, Some(0), Some(t.columns[0][0])).expect("set-position 0");
    motion(What::SetPosition, Some(1), Some(20.0)).expect("set-position 1");
    if let Err(e) = motion(What::Start, None, None) {
        let mut l = host_sim::cmd::serial::Link::open(&port).expect("Hello");
        panic!("Start: {e}; status {:?}", l.request(&Request::GetStatus));
    }
    let mut link = host_sim::cmd::serial::Link::open(&port).expect("Hello");
    match link.request(&Request::GetStatus).expect("GetStatus") {
        Response::Status(s) => assert_eq!(s.state, 1, "following"),
        r => panic!("{r:?}"),
    }
    drop(link);
    motion(What::Stop, None, None).expect("Stop");
    // By hand: slave 0 2 mm off the table's start by an S-curve (returns when there),
    // then start --approach moves it back and follows.
    let off = host_sim::cmd::manual::ManualArgs {
        to_mm: Some(t.columns[0][0] + 2.0),
        ..Default::default()
    };
    manual(What::Move, Some(0), off).expect("motion move");
    let approach = host_sim::cmd::manual::ManualArgs {
        approach: true,
        ..Default::default()
    };
    manual(What::Start, None, approach).expect("motion start --approach");
    motion(What::Stop, None, None).expect("Stop");
    // The identification test move on the real firmware, recorded by its capture, and the
    // fit of the recording (the nominal machine: within 10 %, the criterion, but
    // the viscous friction: 15 %).
    let rec = dir.path().join("step.csv");
    host_sim::cmd::motion::run(&host_sim::cmd::motion::Args {
        port: port.clone(),
        what: What::Test,
        axis: Some(0),
        mm: None,
        master_op: None,
        speed_scale: None,
        manual: Default::default(),
        test: host_sim::cmd::test_move::TestArgs {
            profile: Some(host_sim::cmd::test_move::Profile::Step),
            csv: Some(rec.clone()),
            ..Default::default()
        },
    })
    .expect("motion test --profile step");
    // The plant started at the table's first value with the encoder at 0, and the slave was
    // declared there when it had drifted `raw0_mm`: the piston is at the board's position
    // plus `raw0_mm`.
    let r = host_sim::cmd::identify::read_capture(&rec, 0, raw0_mm, 0.0).expect("the capture");
    let s0 = scenario();
    let a = &s0.axes[0];
    let known = a.plant(s0.supply(), 0.25);
    let fit = |skew_ms: f64| {
        host_sim::identify::spoolless::identify_spoolless(
            &known,
            std::slice::from_ref(&r),
            skew_ms * 1e-3,
        )
        .expect("fit")
    };
    // The viscous term's sensitivity to the pressures' timing (docs/results.md,
    // "Identification and tuning"): the same recording read as if the pressures were 0.05 ms and 0.119 ms
    // (the mean age of the firmware's averaged ADC scans) older than the position.
    for skew_ms in [-0.05, -0.119] {
        let v = fit(skew_ms)
            .get("viscous_n_s_per_m")
            .map_or(f64::NAN, |p| p.value);
        eprintln!(
            "identified on the real firmware with a pressure skew of {skew_ms} ms: viscous_n_s_per_m {v:.4e} ({:+.2} %)",
            100.0 * (v / a.cylinder.viscous_n_s_per_m - 1.0)
        );
    }
    let id = fit(0.0);
    for (name, truth) in [
        ("mass_kg", a.cylinder.mass_kg),
        ("bulk_modulus_pa", a.cylinder.bulk_modulus_pa),
        ("rated_flow_extend_l_per_min", a.valve.rated_flow_l_per_min),
        ("rated_flow_retract_l_per_min", a.valve.rated_flow_l_per_min),
        ("viscous_n_s_per_m", a.cylinder.viscous_n_s_per_m),
        ("coulomb_n", a.cylinder.coulomb_n),
    ] {
        let p = id.get(name).expect(name);
        eprintln!(
            "identified on the real firmware: {name} {:.4e} ± {:.1e} (true {truth:.4e}, {:+.2} %)",
            p.value,
            p.std,
            100.0 * (p.value / truth - 1.0)
        );
        // The viscous friction is the one sensitive to the sub-tick timing of the
        // emulated ADC scans against the encoder latch: +4 … +10 % in runs here (the PTY
        // session is paced by the host, so runs differ); 50 µs
        // of skew moves it by ≈ 18 % (docs/results.md, "Identification and tuning").
        let tol = if name == "viscous_n_s_per_m" {
            0.15
        } else {
            0.10
        };
        assert!(
            (p.value / truth - 1.0).abs() < tol,
            "{name}: {p:?}, true {truth}"
        );
    }
    motion(What::Stop, None, None).expect("Stop");
    // `table list` and a refused `table activate` (nothing committed under that id).
    let tables = |what, id| {
        host_sim::cmd::table::run(&host_sim::cmd::table::Args {
            port: Some(port.clone()),
            what,
            file: Some(dir.path().join("two.csv")),
            master_counts_per_unit: 1000.0,
            id,
            json: true,
            plot: None,
        })
    };
    use host_sim::cmd::table::What as T;
    // The table passes the rules the emulated firmware reports in Info.
    tables(T::Check, None).expect("table check --port");
    tables(T::List, None).expect("table list");
    let e = tables(T::Activate, Some(78)).expect_err("78 was never committed");
    assert!(format!("{e}").contains("no committed table"), "{e}");
    let mut link = host_sim::cmd::serial::Link::open(&port).expect("Hello");
    assert_eq!(
        (link.info.axes, link.info.capacity_rows, link.info.active_id),
        (2, 256, 77)
    );
    match link.request(&Request::GetStatus).expect("GetStatus") {
        Response::Status(s) => {
            assert_eq!(
                (s.state, s.fault_code, s.active_id, s.saved_id),
                (0, 0, 77, 77)
            );
            assert!(
                s.ticks > 100,
                "{} ticks (the tick pauses during the 1 s erase)",
                s.ticks
            );
        }
        r => panic!("GetStatus answered {r:?}"),
    }
}
