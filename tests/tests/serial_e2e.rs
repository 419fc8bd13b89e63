//! End to end over a real pseudo-terminal: the virtual board (`serve --pty`) runs in a
//! thread; the host commands upload the tangent table, activate and save it, start,
//! trace and read the status exactly as against a board.

use host_sim::cmd::serial::Link;
use host_sim::cmd::{motion, serve, status, trace, upload};
use host_sim::scenario::Scenario;
use hydra_core::protocol::{NakCode, Request, Response};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

/// The board's table: the tangent column and the side press holding at its 10 mm start.
fn table_csv() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/tangent_board.csv")
}

/// Set-position of every slave where the board measures it (the board's encoders are
/// incremental: Start is refused until each slave is referenced).
fn reference_all(port: &str) {
    let st = status::fetch(port).unwrap();
    assert_eq!(st.axes.len(), 2);
    for (k, a) in st.axes.iter().enumerate() {
        motion::run(&motion::Args {
            port: port.to_string(),
            what: motion::What::SetPosition,
            axis: Some(k as u8),
            mm: Some(a.pos_mm),
            master_op: None,
            speed_scale: None,
            manual: Default::default(),
            test: Default::default(),
        })
        .unwrap();
    }
}

fn start_board() -> String {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let scn = Scenario::default();
        let r = serve::serve(&scn, |p| tx.send(p.to_string()).unwrap());
        panic!("the virtual board stopped: {r:?}");
    });
    rx.recv_timeout(Duration::from_secs(10)).expect("PTY path")
}

#[test]
fn upload_activate_start_trace_status() {
    let port = start_board();
    let dir = tempfile::tempdir().unwrap();
    // Before any table: Start is refused with a typed reason.
    let mut link = Link::open(&port).unwrap();
    // The board's profile: two slaves, 256-row tables, 1 ms.
    assert_eq!(link.info.axes, 2);
    assert_eq!(link.info.capacity_rows, 256);
    assert_eq!(link.info.period_us, 1000);
    match link.request(&Request::Start).unwrap() {
        Response::Nak { nak, .. } => assert_eq!(nak.code, NakCode::BadState),
        r => panic!("{r:?}"),
    }
    drop(link); // a port is opened exclusively
    upload::run(&upload::Args {
        port: port.clone(),
        table: table_csv(),
        activate: true,
        save: true,
        id: Some(42),
        master_counts_per_unit: 1000.0,
    })
    .unwrap();
    let st = status::fetch(&port).unwrap();
    assert_eq!(st.state, "idle");
    assert_eq!(st.active_id, Some(42));
    assert_eq!(st.saved_id, Some(42));
    // Unreferenced: Start is refused naming the slave.
    let mut link = Link::open(&port).unwrap();
    match link.request(&Request::Start).unwrap() {
        Response::Nak { nak, .. } => assert_eq!(nak.code, NakCode::NotReferenced),
        r => panic!("{r:?}"),
    }
    drop(link);
    reference_all(&port);
    // Start, then trace 3 s of the master's ramp into 3 °/s.
    let mut link = Link::open(&port).unwrap();
    link.expect_ack(&Request::Start).unwrap();
    drop(link);
    let csv = dir.path().join("trace.csv");
    let svg = dir.path().join("trace.svg");
    trace::run(&trace::Args {
        port: port.clone(),
        seconds: 3.0,
        csv: csv.clone(),
        plot: Some(svg.clone()),
        every: 10,
    })
    .unwrap();
    let plot = std::fs::read_to_string(&svg).unwrap();
    for legend in [
        "target 0",
        "actual 1",
        "error 0",
        "dac 1",
        "following error",
    ] {
        assert!(plot.contains(legend), "the trace plot's legend {legend:?}");
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    // 3 s at one sample per 10 ms: about 300 samples (the PTY scheduling may drop a few ticks' worth).
    assert!(rows.len() > 200, "{} samples", rows.len());
    let master_end = rows.last().unwrap()[1];
    assert!(master_end > 1.0, "the master moved: {master_end}°");
    let worst = rows.iter().map(|r| r[4].abs()).fold(0.0, f64::max);
    eprintln!(
        "e2e: {} samples, master {master_end:.2} deg, worst following error {worst:.3} mm",
        rows.len()
    );
    assert!(worst < 2.0, "worst following error {worst} mm");
    assert!(std::fs::metadata(&svg).unwrap().len() > 1000);
    let st = status::fetch(&port).unwrap();
    assert_eq!(st.state, "following", "{st:?}");
    assert_eq!(st.fault_code, 0);
    assert!(st.axes[0].error_mm.abs() < 2.0, "{st:?}");
    // A new upload while following goes to the inactive bank: activation is deferred.
    upload::run(&upload::Args {
        port: port.clone(),
        table: table_csv(),
        activate: true,
        save: false,
        id: Some(43),
        master_counts_per_unit: 1000.0,
    })
    .unwrap();
    let st = status::fetch(&port).unwrap();
    assert_eq!(st.active_id, Some(42));
    assert!(st.activation_pending);
    let mut link = Link::open(&port).unwrap();
    match link.request(&Request::Save).unwrap() {
        Response::Nak { nak, .. } => assert_eq!(nak.code, NakCode::NotIdle),
        r => panic!("{r:?}"),
    }
}

/// The host refuses, before sending anything, what the board would refuse at commit —
/// with the board's own limits from Info, naming the CSV line — and the board is untouched.
#[test]
fn upload_refuses_what_the_board_would_refuse_naming_the_line() {
    let port = start_board();
    let dir = tempfile::tempdir().unwrap();
    let up = |table: PathBuf| {
        upload::run(&upload::Args {
            port: port.clone(),
            table,
            activate: true,
            save: false,
            id: Some(5),
            master_counts_per_unit: 1000.0,
        })
    };
    // One column for a two-slave board: the header line.
    let one =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/tangent_table.csv");
    let e = up(one).unwrap_err().to_string();
    assert!(
        e.contains("tangent_table.csv:1:") && e.contains("the board has 2 slaves"),
        "{e}"
    );
    // Slave 0 jumps 40 mm in 0.1°: 4 000 mm/s at the board's 10 °/s, 200 mm/s allowed.
    let steep = dir.path().join("steep.csv");
    std::fs::write(
        &steep,
        "master,tangent,side_press\n0,100,10\n1,110,10\n1.1,150,10\n",
    )
    .unwrap();
    let e = up(steep).unwrap_err().to_string();
    assert!(
        e.contains("steep.csv:4:") && e.contains("4000.0 mm/s") && e.contains("200 mm/s"),
        "{e}"
    );
    // Nothing reached the board.
    let st = status::fetch(&port).unwrap();
    assert_eq!((st.active_id, st.committed_id), (None, None), "{st:?}");
}
