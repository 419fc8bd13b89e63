//! Host-link throughput against the virtual board on a PTY (the board `host-sim serve
//! --pty` runs, here in a thread of this program): requests per second stop-and-wait
//! (one GetStatus, wait for its Status, the next) and frames per second pipelined (64
//! GetStatus frames written back to back, then their 64 Status answers read), each for
//! two seconds. A benchmark, not a test: run it with
//! `cargo run --release -p host-sim --example link_throughput` (prints JSON).

use host_sim::cmd::serve;
use host_sim::scenario::Scenario;
use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::{Request, Response};
use std::io::Write;
use std::time::{Duration, Instant};

const RUN: Duration = Duration::from_secs(2);
const BATCH: u16 = 64;

/// Reads until `want` answers (any response but Telemetry) arrived; returns how many
/// were a Status.
fn answers(
    port: &mut dyn serialport::SerialPort,
    dec: &mut FrameDecoder,
    want: usize,
) -> anyhow::Result<usize> {
    let (mut got, mut status) = (0, 0);
    let mut buf = [0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(5);
    while got < want {
        anyhow::ensure!(Instant::now() < deadline, "{got} of {want} answers");
        let n = match port.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
            Err(e) => return Err(e.into()),
        };
        for &b in &buf[..n] {
            if let Some(Ok(f)) = dec.push(b) {
                match Response::decode(f.ty, f.payload) {
                    Some(Response::Telemetry(_)) | None => {}
                    Some(Response::Status(_)) => {
                        got += 1;
                        status += 1;
                    }
                    Some(_) => got += 1,
                }
            }
        }
    }
    Ok(status)
}

fn main() -> anyhow::Result<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let r = serve::serve(&Scenario::default(), |p| {
            let _ = tx.send(p.to_string());
        });
        eprintln!("the virtual board stopped: {r:?}");
    });
    let path = rx.recv_timeout(Duration::from_secs(10))?;
    let mut port = serialport::new(&path, 921_600)
        .timeout(Duration::from_millis(5))
        .open()?;
    let mut dec = FrameDecoder::new();
    let mut frame = [0u8; MAX_WIRE + 1];
    let mut seq: u16 = 0;
    let n =
        encode_request(seq, &Request::Hello, &mut frame).ok_or_else(|| anyhow::anyhow!("Hello"))?;
    port.write_all(&frame[..n])?;
    answers(port.as_mut(), &mut dec, 1)?;

    // Stop and wait.
    let (t0, mut reqs) = (Instant::now(), 0u64);
    while t0.elapsed() < RUN {
        seq = seq.wrapping_add(1);
        let n = encode_request(seq, &Request::GetStatus, &mut frame)
            .ok_or_else(|| anyhow::anyhow!("frame"))?;
        port.write_all(&frame[..n])?;
        anyhow::ensure!(
            answers(port.as_mut(), &mut dec, 1)? == 1,
            "GetStatus refused"
        );
        reqs += 1;
    }
    let stop_and_wait = reqs as f64 / t0.elapsed().as_secs_f64();

    // Pipelined.
    let (t0, mut frames) = (Instant::now(), 0u64);
    let mut batch = Vec::new();
    while t0.elapsed() < RUN {
        batch.clear();
        for _ in 0..BATCH {
            seq = seq.wrapping_add(1);
            let n = encode_request(seq, &Request::GetStatus, &mut frame)
                .ok_or_else(|| anyhow::anyhow!("frame"))?;
            batch.extend_from_slice(&frame[..n]);
        }
        port.write_all(&batch)?;
        let ok = answers(port.as_mut(), &mut dec, usize::from(BATCH))?;
        anyhow::ensure!(
            ok == usize::from(BATCH),
            "{ok} of {BATCH} answered with a Status"
        );
        frames += u64::from(BATCH);
    }
    let pipelined = frames as f64 / t0.elapsed().as_secs_f64();
    println!(
        "{}",
        serde_json::json!({
            "request": "GetStatus",
            "stop_and_wait_req_per_s": stop_and_wait.round(),
            "pipelined_frames_per_s": pipelined.round(),
            "batch": BATCH,
        })
    );
    Ok(())
}
