//! Golden frames: `PROTOCOL.md`'s section "Golden frames" pinned byte for byte. Every
//! message there is built here, encoded (COBS frame, delimiter included) and compared
//! with the hex the document shows, and the document's bytes decode back to the same
//! message. A change to the wire format fails here until the document shows it.

use super::diag::{
    put_capture_row, CaptureArmMsg, CaptureMsg, FaultEventMsg, FaultsMsg, LinkStats, MasterStateMsg,
};
use super::frame::{self, FrameDecoder, MAX_WIRE};
use super::handler::encode_request;
use super::msg::{
    AxisLimitsMsg, AxisSample, AxisStatus, Info, InfoLimits, MotionLimitsMsg, Nak, NakCode,
    Request, Response, StatusMsg, Telemetry, MAX_AXES, NO_TABLE, PROTOCOL_VERSION,
};
use super::wire::Writer;
use crate::runtime::CaptureRow;
use std::string::{String, ToString};
use std::vec::Vec;

const DOC: &str = include_str!("../../../PROTOCOL.md");

/// One table row of the golden TableChunk: master 1000 counts (1°), slaves 250 mm and
/// 10 mm (I48F16 / I24F8 raw, little-endian).
fn row() -> Vec<u8> {
    let mut r = (1000i64 << 16).to_le_bytes().to_vec();
    r.extend_from_slice(&(250_000i32 << 8).to_le_bytes());
    r.extend_from_slice(&(10_000i32 << 8).to_le_bytes());
    r
}

fn status() -> StatusMsg {
    let mut s = StatusMsg {
        state: 1,
        flags: 0x10,
        owner: 1,
        fault_code: 0,
        fault_axis: 0xFF,
        inputs: 2,
        active_id: 7,
        active_rows: 181,
        active_crc: 0x1234_5678,
        committed_id: NO_TABLE,
        saved_id: 7,
        boot_slot: 0,
        boot_reason: 1,
        upload_rows: 0,
        ticks: 123_456,
        tick_max_ns: 18_000,
        tick_mean_ns: 9_400,
        overruns: 0,
        master: 45_000 << 16,
        ..StatusMsg::default()
    };
    let _ = s.axes.push(AxisStatus {
        pos_um: 250_000 << 8,
        target_um: (250_000 << 8) + 2,
        error_um: 2,
        dac: -35,
        reference: 2,
        manual: 0,
        backoff: 1,
        ff_trim: [-2_150, 300],
    });
    s
}

fn limits() -> MotionLimitsMsg {
    MotionLimitsMsg {
        vel_um_per_s: 20_000,
        acc_um_per_s2: 200_000,
        jerk_um_per_s3: 4_000_000,
    }
}

fn info() -> Info {
    let mut axes = [AxisLimitsMsg::default(); MAX_AXES];
    axes[0] = AxisLimitsMsg {
        min_um: 0,
        max_um: 500_000 << 8,
        max_speed_um_per_s: 200_000 << 8,
    };
    Info {
        protocol: PROTOCOL_VERSION,
        firmware: [0, 1, 0],
        axes: 1,
        capacity_rows: 256,
        max_chunk_rows: 28,
        period_us: 1000,
        active_id: NO_TABLE,
        law_buffers: 2,
        period_min_us: 100,
        period_max_us: 100_000,
        max_segment_counts: 65_535,
        limits: InfoLimits {
            master_speed_per_s: 10_000 << 16,
            axes,
        },
    }
}

fn telemetry() -> Telemetry {
    let mut t = Telemetry {
        tick: 1000,
        master: -(1 << 16),
        ..Telemetry::default()
    };
    let _ = t.axes.push(AxisSample {
        target_um: 256,
        actual_um: 255,
        dac: 12,
    });
    t
}

/// One following error of slave 0 (2 500 µm against 2 000 µm at tick 70 000), 300
/// frames received, 1 bad, 2 Naks.
fn faults() -> FaultsMsg {
    let mut f = FaultsMsg {
        link: LinkStats {
            frames: 300,
            bad_frames: 1,
            naks: 2,
        },
        ..FaultsMsg::default()
    };
    let _ = f.events.push(FaultEventMsg {
        code: 0x0600,
        tick: 70_000,
        value: 2500 << 8,
        limit: 2000 << 8,
    });
    f
}

/// A finished one-slave capture (500 + 1 + 1500 rows of 2 048), its first row: master
/// 45 000 counts, Following with valve power, target 250 mm, actual 249.95 mm, DAC −35,
/// 120.00 / 80.50 bar.
fn capture() -> CaptureMsg {
    let row = CaptureRow::<1> {
        master: 45_000,
        target_um: [250_000 << 8],
        actual_um: [249_950 << 8],
        dac: [-35],
        pressure_cbar: [[12_000, 8_050]],
    };
    let mut buf = [0u8; 19];
    let _ = put_capture_row(&mut Writer::new(&mut buf), &row, 0x09);
    CaptureMsg {
        phase: 3,
        pre: 500,
        rows: 2001,
        trigger_tick: 70_000,
        capacity: 2048,
        offset: 0,
        data: heapless::Vec::from_slice(&buf).unwrap(),
    }
}

/// Every golden frame by its name in the document: the request or response and its seq.
// A test's list of messages: the size of a Response (a Capture's 256 data bytes) is fine.
#[allow(clippy::large_enum_variant)]
enum Msg {
    Req(u16, Request<'static>),
    Resp(u16, Response),
}

fn messages(chunk: &'static [u8]) -> Vec<(&'static str, Msg)> {
    use Msg::{Req, Resp};
    std::vec![
        ("hello", Req(0, Request::Hello)),
        ("get_status", Req(1, Request::GetStatus)),
        (
            "table_begin",
            Req(
                2,
                Request::TableBegin {
                    id: 7,
                    columns: 2,
                    rows: 300
                }
            )
        ),
        (
            "table_chunk",
            Req(
                3,
                Request::TableChunk {
                    offset: 0,
                    count: 1,
                    data: chunk
                }
            )
        ),
        (
            "table_commit",
            Req(4, Request::TableCommit { crc: 0xCBF4_3926 })
        ),
        ("activate", Req(5, Request::Activate { id: 7 })),
        (
            "set_position",
            Req(
                6,
                Request::SetPosition {
                    axis: 1,
                    pos_um: -(20_500 << 8)
                }
            )
        ),
        (
            "set_param",
            Req(
                7,
                Request::SetParam {
                    axis: 0,
                    param: 1,
                    value: 1.5
                }
            )
        ),
        (
            "get_param",
            Req(8, Request::GetParam { axis: 0, param: 14 })
        ),
        ("save", Req(9, Request::Save)),
        ("get_faults", Req(10, Request::GetFaults)),
        (
            "capture_arm",
            Req(
                11,
                Request::CaptureArm(CaptureArmMsg {
                    trigger: 4,
                    channel: 3,
                    axis: 0,
                    value: 50 << 8,
                    pre: 500,
                    post: 1500
                })
            )
        ),
        (
            "jog",
            Req(
                14,
                Request::Jog {
                    axis: 0,
                    speed: -5000 << 8,
                    limits: limits(),
                }
            )
        ),
        (
            "move_to",
            Req(
                15,
                Request::MoveTo {
                    axis: 0,
                    to_um: 120_000 << 8,
                    limits: limits(),
                }
            )
        ),
        ("approach", Req(16, Request::Approach { limits: limits() })),
        ("owner", Req(17, Request::Owner { side: 1 })),
        (
            "virtual_master",
            Req(
                13,
                Request::VirtualMaster {
                    op: 3,
                    speed_scale: 0.5
                }
            )
        ),
        (
            "get_capture",
            Req(
                12,
                Request::GetCapture {
                    offset: 0,
                    count: 7
                }
            )
        ),
        (
            "ack",
            Resp(
                5,
                Response::Ack {
                    req: 0x14,
                    flags: 1
                }
            )
        ),
        (
            "nak",
            Resp(
                4,
                Response::Nak {
                    req: 0x12,
                    nak: Nak::with(NakCode::TableTooSteep, 4, 1),
                }
            )
        ),
        (
            "nak_version",
            Resp(
                0,
                Response::Nak {
                    req: 0x01,
                    nak: Nak::with(NakCode::Version, u16::from(PROTOCOL_VERSION), 0),
                }
            )
        ),
        (
            "param",
            Resp(
                8,
                Response::Param {
                    axis: 0,
                    param: 14,
                    value: 0.015
                }
            )
        ),
        ("info", Resp(0, Response::Info(info()))),
        ("status", Resp(1, Response::Status(status()))),
        ("telemetry", Resp(42, Response::Telemetry(telemetry()))),
        ("faults", Resp(10, Response::Faults(faults()))),
        ("capture", Resp(12, Response::Capture(capture()))),
        (
            "master_state",
            Resp(
                13,
                Response::MasterState(MasterStateMsg {
                    running: false,
                    time_s: 0.0,
                    position: 0.0,
                    end_s: 31.5,
                    at_end: false,
                    speed_scale: 0.5
                })
            )
        ),
    ]
}

fn wire(m: &Msg) -> Vec<u8> {
    let mut out = [0u8; MAX_WIRE + 1];
    let n = match m {
        Msg::Req(seq, q) => encode_request(*seq, q, &mut out),
        Msg::Resp(seq, r) => {
            let mut p = [0u8; frame::MAX_PAYLOAD];
            let k = r.encode(&mut p).unwrap();
            frame::encode(*seq, r.ty(), &p[..k], &mut out)
        }
    };
    out[..n.unwrap()].to_vec()
}

fn hex(b: &[u8]) -> String {
    b.iter()
        .map(|x| std::format!("{x:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The document's golden block: `name: hex bytes` lines (a line may continue on the
/// next one, indented).
fn doc_frames() -> Vec<(String, Vec<u8>)> {
    let start = DOC
        .find("```golden\n")
        .expect("PROTOCOL.md has a ```golden block");
    let body = &DOC[start + 10..];
    let body = &body[..body.find("```").expect("the golden block ends")];
    let mut out: Vec<(String, Vec<u8>)> = Vec::new();
    for line in body.lines().filter(|l| !l.trim().is_empty()) {
        let (name, bytes) = match line.split_once(':') {
            Some((n, b)) if !line.starts_with(' ') => (Some(n.trim().to_string()), b),
            _ => (None, line),
        };
        let bytes: Vec<u8> = bytes
            .split_whitespace()
            .map(|h| u8::from_str_radix(h, 16).expect("hex byte"))
            .collect();
        match name {
            Some(n) => out.push((n, bytes)),
            None => out.last_mut().expect("a name first").1.extend(bytes),
        }
    }
    out
}

#[test]
fn the_document_shows_every_frame_byte_for_byte() {
    let chunk: &'static [u8] = std::boxed::Box::leak(row().into_boxed_slice());
    let doc = doc_frames();
    let msgs = messages(chunk);
    let names: Vec<_> = msgs.iter().map(|(n, _)| *n).collect();
    let doc_names: Vec<_> = doc.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        doc_names, names,
        "PROTOCOL.md's golden frames and this test's list"
    );
    let mut wrong = String::new();
    for ((name, m), (_, bytes)) in msgs.iter().zip(&doc) {
        let w = wire(m);
        if &w != bytes {
            wrong.push_str(&std::format!("{name}: {}\n", hex(&w)));
            continue;
        }
        // And back: the document's bytes decode to the message.
        let mut d = FrameDecoder::new();
        let mut got = None;
        for &b in bytes {
            if let Some(f) = d.push(b) {
                let f = f.expect("a valid frame");
                got = Some(match m {
                    Msg::Req(seq, q) => {
                        assert_eq!(Request::decode(f.ty, f.payload), Ok(*q), "{name}");
                        f.seq == *seq
                    }
                    Msg::Resp(seq, r) => {
                        assert_eq!(
                            Response::decode(f.ty, f.payload).as_ref(),
                            Some(r),
                            "{name}"
                        );
                        f.seq == *seq
                    }
                });
            }
        }
        assert_eq!(got, Some(true), "{name}: one frame with its seq");
    }
    assert!(
        wrong.is_empty(),
        "PROTOCOL.md shows other bytes; these are the encoder's:\n{wrong}"
    );
}
