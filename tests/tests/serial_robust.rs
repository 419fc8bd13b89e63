//! Host-side robustness of the virtual board and the host link (found by attack,
//! one-runtime-path issue item 4): a host that sends without reading never stops the
//! board, and a host that died mid-frame does not break the next session.

use host_sim::cmd::serial::Link;
use host_sim::cmd::serve;
use host_sim::scenario::Scenario;
use hydra_core::protocol::frame::MAX_WIRE;
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::{Request, Response};
use std::io::Write;
use std::sync::mpsc;
use std::time::Duration;

fn start_board() -> (String, mpsc::Receiver<String>) {
    let (tx, rx) = mpsc::channel();
    let (done_tx, done_rx) = mpsc::channel();
    std::thread::spawn(move || {
        let scn = Scenario::default();
        let r = serve::serve(&scn, |p| tx.send(p.to_string()).unwrap());
        let _ = done_tx.send(format!("{r:?}"));
    });
    (
        rx.recv_timeout(Duration::from_secs(10)).expect("PTY path"),
        done_rx,
    )
}

fn raw(port: &str) -> Box<dyn serialport::SerialPort> {
    serialport::new(port, 921_600)
        .timeout(Duration::from_millis(20))
        .open()
        .unwrap()
}

fn frame(seq: u16, q: &Request<'_>) -> Vec<u8> {
    let mut b = [0u8; MAX_WIRE + 1];
    let n = encode_request(seq, q, &mut b).unwrap();
    b[..n].to_vec()
}

#[test]
fn a_host_that_never_reads_does_not_stop_the_board() {
    let (port, done) = start_board();
    {
        let mut p = raw(&port);
        // 3000 GetStatus requests (≈ 7× what stopped `serve` before), answers never read.
        for i in 0..3000u16 {
            p.write_all(&frame(i, &Request::GetStatus)).unwrap();
        }
        p.flush().unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }
    assert!(
        done.try_recv().is_err(),
        "the virtual board stopped while the host was not reading"
    );
    // A new session works.
    let mut link = Link::open(&port).unwrap();
    assert!(matches!(
        link.request(&Request::GetStatus).unwrap(),
        Response::Status(_)
    ));
}

#[test]
fn a_host_that_died_mid_frame_does_not_break_the_next_session() {
    let (port, _done) = start_board();
    for cut in [3usize, 7, 11] {
        {
            let mut p = raw(&port);
            let f = frame(77, &Request::SetTelemetry { decimation: 0 });
            p.write_all(&f[..cut.min(f.len() - 1)]).unwrap();
            p.flush().unwrap();
        }
        let mut link = Link::open(&port).unwrap();
        match link.request(&Request::GetStatus).unwrap() {
            Response::Status(_) => {}
            r => panic!("after a half frame of {cut} bytes: {r:?}"),
        }
    }
}
