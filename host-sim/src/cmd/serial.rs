//! The host end of the UART protocol (`PROTOCOL.md`): open a port, send one request,
//! wait for its answer. Shared by `upload`, `status` and `trace`.

use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::msg::{Info, Telemetry, PROTOCOL_VERSION};
use hydra_core::protocol::{Nak, Request, Response};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// Baud rate the board's USART runs at (a PTY ignores it).
pub const BAUD: u32 = 921_600;
/// How long to wait for an answer.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(3);
/// How long to wait for Save's answer: the board erases a 128 KiB flash sector, 1 s
/// typical and 2 s at most at x32 (4 s at most at x8: the margin covers a firmware that
/// erases at x8), then programs ≤ 4 KiB (≤ 0.1 s at 100 µs per word) and reads it back.
pub const SAVE_TIMEOUT: Duration = Duration::from_secs(6);

/// The answer timeout of request `q`.
pub fn timeout_for(q: &Request<'_>) -> Duration {
    match q {
        Request::Save => SAVE_TIMEOUT,
        _ => ANSWER_TIMEOUT,
    }
}

/// A request the board refused.
#[derive(Debug, thiserror::Error)]
#[error("board refused {req}: {} ({:?}, detail {}, {})", explain(nak), nak.code, nak.detail, nak.detail2)]
pub struct Refused {
    /// Request name.
    pub req: String,
    /// The Nak.
    pub nak: Nak,
}

/// A Nak in words a person can act on (PROTOCOL.md's table of codes and details).
pub fn explain(nak: &Nak) -> String {
    use hydra_core::protocol::NakCode as C;
    let (d, d2) = (nak.detail, nak.detail2);
    let state = match d {
        0 => "idle",
        1 => "following",
        2 => "holding",
        3 => "in fault",
        4 => "in manual (moving slaves by hand)",
        _ => "in an unknown state",
    };
    match nak.code {
        C::BadState => {
            let why = match d2 {
                1 => "no table is active: upload one with --activate",
                2 => "the board is in Fault: clear the fault first (motion clear-fault)",
                3 => "the fault's cause is still present (e.g. the E-stop chain is open)",
                4 => "the master moved while holding: stop, then start again",
                5 => "holding at the end of the table: stop, then start again",
                6 => "not possible now (idle or fault only; in manual, wait until every slave is at rest)",
                _ => "not allowed now",
            };
            format!("the board is {state}: {why}")
        }
        C::NotReferenced => {
            format!("slave {d} is not referenced: set its position or home it first")
        }
        C::NoAxis => format!("the board has no slave {d}"),
        C::Motion => {
            use hydra_core::protocol::msg::motion_reason as m;
            let why = match d2 {
                m::LIMITS => "a speed, acceleration or jerk limit is zero or too large",
                m::OUTSIDE_LIMITS => {
                    "the target is outside its limits/min_um … max_um (or the jog points out of \
                     them; a test needs its amplitude plus the following-error limit inside)"
                }
                m::MOVING => "it is moving: wait until it is at rest (or hold)",
                m::PLAN => "the move is too long to plan",
                m::TOO_FAST => "the speed is above its limits/max_speed_um_per_s",
                m::TEST_STEP => {
                    "a step of the test (its amplitude; a PRBS twice it) is not below the \
                     axis' following-error limit"
                }
                m::TEST_SPEC => {
                    "the test's profile, amplitude (1 µm … 100 mm), duration (≤ 60 s), dwell or \
                     frequency (≤ a tenth of the loop rate) is impossible"
                }
                _ => "refused",
            };
            format!("slave {d}: {why}")
        }
        C::NoSession => "no session (say Hello first)".into(),
        C::TooManyRows => format!("more rows than the board holds ({d})"),
        C::Columns => format!("the board has {d} slave column(s)"),
        C::Incomplete => format!("only {d} rows arrived before the commit"),
        C::TableCrc => "the table's CRC does not match the rows received".into(),
        C::TableTooFewNodes => "a table needs at least 2 rows".into(),
        C::TableTooManyNodes => "more rows than the board holds".into(),
        C::TableNotMonotonic => format!("row {d}: the master is not strictly increasing"),
        C::TableSegmentLength => format!("row {d}: the master step is longer than 65 535 counts"),
        C::TableOutOfRange => format!("row {d}, slave {d2}: outside the slave's position limits"),
        C::TableTooSteep => format!(
            "row {d}, slave {d2}: steeper than the slave can follow at the master's top speed"
        ),
        C::TableMasterSpeed => "the board's master top speed is not positive".into(),
        C::UnknownTable => "no committed table with this id".into(),
        C::NotIdle => "only possible while every axis is idle".into(),
        C::UnknownParam => format!("{}: not a parameter of this board", param_path(d, d2)),
        C::ParamRange => format!(
            "{}: outside its range, or invalid with the other settings and the active table \
             (see `param list`)",
            param_path(d, d2)
        ),
        C::ReadOnly => format!(
            "{}: read-only (the board sets it itself)",
            param_path(d, d2)
        ),
        C::NothingToSave if d == 1 => {
            "the saved table is not running (its install was refused at boot): saving the \
             settings alone would stop it booting; activate a table first"
                .into()
        }
        C::NothingToSave => "no active table and no changed setting to save".into(),
        C::Flash => "the flash erase, write or verify failed".into(),
        C::Refused if d == 0 => {
            "the table's law cannot be built with the present parameters".into()
        }
        C::Refused => "the board was not at a safe point".into(),
        C::CaptureTooLong => format!(
            "the capture is longer than the board's ring ({d} ticks: pre + post + 1 must fit)"
        ),
        C::CaptureTrigger if d == 0 && d2 == 0 => {
            "the board keeps no capture ring, or the trigger is not one it knows".into()
        }
        C::NoVirtualMaster if d2 == 1 => "the master's speed scale must be 0.01 … 100".into(),
        C::NoVirtualMaster if d2 == 2 => format!("operation {d}: not a master operation"),
        C::NoVirtualMaster => format!(
            "operation {d}: this board's master is a real encoder (only a virtual board's \
             master can be started, stopped or rewound from the host)"
        ),
        C::CaptureTrigger => {
            format!("trigger kind {d}, channel {d2}: not a trigger this board knows")
        }
        c => format!("{c:?}"),
    }
}

/// The settings path a Nak's (axis, parameter id) details name.
fn param_path(axis: u16, id: u8) -> String {
    use hydra_core::protocol::settings::{ParamId, ParamPath};
    match (ParamId::from_u8(id), u8::try_from(axis)) {
        (Some(id), Ok(axis)) => ParamPath { id, axis }.to_string(),
        _ => format!("axis {axis}, parameter id {id}"),
    }
}

/// An open session with a board.
pub struct Link {
    port: Box<dyn serialport::SerialPort>,
    dec: FrameDecoder,
    seq: u16,
    /// Telemetry frames received while waiting for answers, oldest first.
    pub telemetry: Vec<Telemetry>,
    /// The board's Info from Hello.
    pub info: Info,
}

impl Link {
    /// Opens `path` and says Hello.
    ///
    /// A port that cannot be opened is an error with [`open_hint`]'s advice.
    pub fn open(path: &str) -> anyhow::Result<Self> {
        let port = serialport::new(path, BAUD)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|e| anyhow::anyhow!("cannot open {path}: {e}\n{}", open_hint()))?;
        let mut l = Self {
            port,
            dec: FrameDecoder::new(),
            seq: (std::process::id() & 0x7FFF) as u16,
            telemetry: Vec::new(),
            info: Info::default(),
        };
        // Resynchronise: a delimiter ends whatever partial frame a host that died mid-frame
        // left in the board's decoder; the board answers that garbage with a seq-0xFFFF
        // Nak, which (with anything else still in flight) is drained here, so it is never
        // taken for the answer to Hello.
        l.port.write_all(&[0])?;
        l.port.flush()?;
        l.drain(Duration::from_millis(40), Duration::from_millis(400))?;
        match l.request(&Request::Hello)? {
            Response::Info(i) if i.protocol == PROTOCOL_VERSION => l.info = i,
            Response::Info(i) => anyhow::bail!(
                "{path}: the board speaks protocol version {}, this host {PROTOCOL_VERSION}",
                i.protocol
            ),
            Response::Nak { nak, .. } if nak.code == hydra_core::protocol::NakCode::Version => {
                anyhow::bail!(
                    "{path}: the board speaks protocol version {}, this host {PROTOCOL_VERSION}",
                    nak.detail
                )
            }
            // A board of version 2 refuses this version's Hello (it carries the version).
            Response::Nak { nak, .. } => anyhow::bail!(
                "{path}: the board refused Hello ({:?}): it speaks a protocol version older \
                 than this host's {PROTOCOL_VERSION}",
                nak.code
            ),
            r => anyhow::bail!("Hello answered {r:?}"),
        }
        Ok(l)
    }

    /// Reads and discards frames until `quiet` passes without a byte (at most `limit`).
    fn drain(&mut self, quiet: Duration, limit: Duration) -> anyhow::Result<()> {
        let t0 = Instant::now();
        let mut last = Instant::now();
        while t0.elapsed() < limit && last.elapsed() < quiet {
            let mut b = [0u8; 4096];
            match self.port.read(&mut b) {
                Ok(0) => {}
                Ok(_) => last = Instant::now(),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(e.into()),
            }
        }
        self.dec = FrameDecoder::new();
        Ok(())
    }

    /// Sends one request and returns its answer (a Nak is returned, not an error).
    pub fn request(&mut self, q: &Request<'_>) -> anyhow::Result<Response> {
        let seq = if matches!(q, Request::Hello) {
            self.seq
        } else {
            self.seq.wrapping_add(1)
        };
        let mut buf = [0u8; MAX_WIRE + 1];
        let n = encode_request(seq, q, &mut buf)
            .ok_or_else(|| anyhow::anyhow!("request too large for one frame"))?;
        self.port.write_all(&buf[..n])?;
        self.port.flush()?;
        let timeout = timeout_for(q);
        let deadline = Instant::now() + timeout;
        // A seq-0xFFFF Nak names no request: it may be this frame, corrupted on the way,
        // or other bytes (noise, a dead host's half frame). It is not taken as the answer
        // at once: the real answer may follow. After 100 ms without one the frame is sent
        // again (a Nak changed nothing on the board, so a resend is safe), twice at most.
        let mut framing: Option<(Response, Instant)> = None;
        let mut resends = 0;
        loop {
            for (s, r) in self.read_frames()? {
                match r {
                    Response::Telemetry(t) => self.telemetry.push(t),
                    Response::Nak { .. } if s == 0xFFFF => {
                        framing.get_or_insert((r, Instant::now()));
                    }
                    Response::Nak { .. } if s == seq => return Ok(r),
                    r if s == seq => {
                        self.seq = seq;
                        return Ok(r);
                    }
                    _ => {}
                }
            }
            if let Some((nak, at)) = &framing {
                if at.elapsed() > Duration::from_millis(100) {
                    if resends >= 2 {
                        return Ok(nak.clone());
                    }
                    resends += 1;
                    framing = None;
                    self.port.write_all(&buf[..n])?;
                    self.port.flush()?;
                }
            }
            if Instant::now() > deadline {
                anyhow::bail!("no answer to {q:?} within {timeout:?}");
            }
        }
    }

    /// Sends a request that must be acknowledged; a Nak becomes [`Refused`].
    pub fn expect_ack(&mut self, q: &Request<'_>) -> anyhow::Result<u8> {
        match self.request(q)? {
            Response::Ack { flags, .. } => Ok(flags),
            Response::Nak { nak, .. } => Err(Refused {
                req: format!("{q:?}")
                    .split([' ', '{'])
                    .next()
                    .unwrap_or("?")
                    .to_string(),
                nak,
            }
            .into()),
            r => anyhow::bail!("{q:?} answered {r:?}"),
        }
    }

    /// Reads what is available (up to the port timeout) and decodes whole frames.
    pub fn read_frames(&mut self) -> anyhow::Result<Vec<(u16, Response)>> {
        let mut b = [0u8; 4096];
        let n = match self.port.read(&mut b) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
            Err(e) => return Err(e.into()),
        };
        let mut out = Vec::new();
        for &x in &b[..n] {
            if let Some(Ok(f)) = self.dec.push(x) {
                if let Some(r) = Response::decode(f.ty, f.payload) {
                    out.push((f.seq, r));
                }
            }
        }
        Ok(out)
    }
}

/// What to try when a serial port does not open: the ports this machine has (USB-serial
/// adapters and boards with a USB UART), the `dialout` group, and the virtual boards.
pub fn open_hint() -> String {
    let mut ports: Vec<String> = std::fs::read_dir("/dev")
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with("ttyUSB") || n.starts_with("ttyACM"))
                .map(|n| format!("/dev/{n}"))
                .collect()
        })
        .unwrap_or_default();
    ports.sort();
    let found = if ports.is_empty() {
        "no /dev/ttyUSB* or /dev/ttyACM* here (is the adapter plugged in?)".to_string()
    } else {
        format!("serial ports here: {}", ports.join(", "))
    };
    format!(
        "  {found};\n  \"permission denied\": add yourself to the dialout group \
         (`sudo usermod -aG dialout $USER`, then log in again);\n  \
         without a board: `host-sim serve --pty` (the virtual board) or `cargo run --release \
         -p board-emu -- --pty` (the firmware, emulated) prints a port to use"
    )
}

#[cfg(test)]
mod explain_tests {
    use super::{explain, Link};
    use hydra_core::protocol::{Nak, NakCode};

    #[test]
    fn a_port_that_does_not_open_says_what_to_try() {
        let Err(e) = Link::open("/dev/hydra-no-such-port") else {
            panic!("opened a port that does not exist");
        };
        let e = format!("{e:#}");
        for p in [
            "cannot open /dev/hydra-no-such-port",
            "dialout",
            "serve --pty",
        ] {
            assert!(e.contains(p), "{p} missing: {e}");
        }
    }

    #[test]
    fn naks_are_explained_with_their_details() {
        let e = explain(&Nak::with(NakCode::BadState, 0, 1));
        assert!(
            e.contains("idle") && e.contains("no table is active"),
            "{e}"
        );
        let e = explain(&Nak::with(NakCode::TableTooSteep, 17, 1));
        assert!(
            e.contains("row 17, slave 1") && e.contains("steeper"),
            "{e}"
        );
        let e = explain(&Nak::with(NakCode::NotReferenced, 1, 0));
        assert!(e.contains("slave 1 is not referenced"), "{e}");
    }
}
