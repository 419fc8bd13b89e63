//! Modbus TCP for the virtual board (`serve --modbus-tcp ADDR`): the MBAP framing
//! (Modbus Messaging on TCP/IP Implementation Guide v1.0b §3.1.3) and the PDUs of
//! functions 3, 4, 6 and 16 (Modbus Application Protocol v1.1b3 §6) around core's
//! [`hydra_core::plc::Server`], which the board's own transports call the same way.
//!
//! Rules: a frame is answered only when its header is whole and sane (protocol id 0,
//! length 2 … 254); a client that sends a header that is not is disconnected (its
//! stream cannot be resynchronised). A request for another unit id than `plc/unit_id`
//! (or 255, or 0) is not answered. While `plc/enable` is 0, and for a client not on
//! the allow list (`plc/allow/<n>`), connections are closed as soon as they are accepted.
//! At most [`MAX_CLIENTS`] at once; a connection quiet for [`IDLE_S`] is closed.

use crate::vboard::VBoard;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

/// Connections served at once (more are closed on accept).
pub const MAX_CLIENTS: usize = 32;
/// A connection without a request for this long is closed, s.
pub const IDLE_S: u64 = 60;
/// Most registers one read returns (the protocol's 125).
const MAX_READ: u16 = 125;
/// Most registers one write takes (the protocol's 123).
const MAX_WRITE: u16 = 123;

/// An exception response to function `f`.
fn exception(f: u8, code: u8) -> Vec<u8> {
    vec![f | 0x80, code]
}

/// One request PDU (function code and data) → its response PDU, against `board`.
pub fn pdu(board: &mut VBoard, req: &[u8]) -> Vec<u8> {
    let Some((&f, data)) = req.split_first() else {
        return exception(0, 1);
    };
    let be = |i: usize| data.get(i..i + 2).map(|b| u16::from_be_bytes([b[0], b[1]]));
    match f {
        3 | 4 => {
            let (Some(start), Some(n), 4) = (be(0), be(2), data.len()) else {
                return exception(f, 3);
            };
            if n == 0 || n > MAX_READ {
                return exception(f, 3);
            }
            let mut words = vec![0u16; usize::from(n)];
            let r = if f == 3 {
                board.plc_read_holding(start, &mut words)
            } else {
                board.plc_read_input(start, &mut words)
            };
            match r {
                Ok(()) => {
                    let mut out = vec![f, (n * 2) as u8];
                    for w in words {
                        out.extend_from_slice(&w.to_be_bytes());
                    }
                    out
                }
                Err(e) => exception(f, e as u8),
            }
        }
        6 => {
            let (Some(a), Some(v), 4) = (be(0), be(2), data.len()) else {
                return exception(f, 3);
            };
            match board.plc_write(a, &[v]) {
                Ok(()) => req.to_vec(),
                Err(e) => exception(f, e as u8),
            }
        }
        16 => {
            let (Some(a), Some(n)) = (be(0), be(2)) else {
                return exception(f, 3);
            };
            let bytes = data.get(4).copied().map(usize::from);
            let ok = (1..=MAX_WRITE).contains(&n)
                && bytes == Some(usize::from(n) * 2)
                && data.len() == 5 + usize::from(n) * 2;
            if !ok {
                return exception(f, 3);
            }
            let values: Vec<u16> = (0..usize::from(n)).filter_map(|k| be(5 + 2 * k)).collect();
            match board.plc_write(a, &values) {
                Ok(()) => {
                    let mut out = vec![f];
                    out.extend_from_slice(&a.to_be_bytes());
                    out.extend_from_slice(&n.to_be_bytes());
                    out
                }
                Err(e) => exception(f, e as u8),
            }
        }
        _ => exception(f, 1),
    }
}

struct Client {
    stream: TcpStream,
    rx: Vec<u8>,
    last: Instant,
}

/// The listener and its connections, polled from the serve loop.
pub struct TcpServer {
    listener: TcpListener,
    clients: Vec<Client>,
}

impl TcpServer {
    /// Listens on `addr` (e.g. `127.0.0.1:1502`).
    pub fn bind(addr: &str) -> anyhow::Result<Self> {
        let listener = TcpListener::bind(addr)
            .map_err(|e| anyhow::anyhow!("modbus-tcp: cannot listen on {addr}: {e}"))?;
        listener.set_nonblocking(true)?;
        Ok(Self {
            listener,
            clients: Vec::new(),
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> anyhow::Result<std::net::SocketAddr> {
        Ok(self.listener.local_addr()?)
    }

    /// Accepts new connections, answers every whole request, closes idle ones.
    pub fn poll(&mut self, board: &mut VBoard) {
        while let Ok((stream, peer)) = self.listener.accept() {
            let plc = board.handler.plc_settings();
            let ip = match peer.ip() {
                std::net::IpAddr::V4(v4) => v4.octets(),
                std::net::IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or([0; 4], |v| v.octets()),
            };
            if !plc.enable() || !plc.allows(ip) || self.clients.len() >= MAX_CLIENTS {
                drop(stream);
                continue;
            }
            if stream.set_nonblocking(true).is_err() {
                continue;
            }
            let _ = stream.set_nodelay(true);
            self.clients.push(Client {
                stream,
                rx: Vec::new(),
                last: Instant::now(),
            });
        }
        let unit_id = board.handler.plc_settings().unit_id();
        let enabled = board.handler.plc_settings().enable();
        self.clients
            .retain_mut(|c| enabled && serve_client(c, board, unit_id));
    }
}

/// Reads and answers what `c` sent; `false` when it is to be closed.
fn serve_client(c: &mut Client, board: &mut VBoard, unit_id: u8) -> bool {
    let mut buf = [0u8; 512];
    loop {
        match c.stream.read(&mut buf) {
            Ok(0) => return false,
            Ok(n) => {
                c.rx.extend_from_slice(&buf[..n]);
                c.last = Instant::now();
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => return false,
        }
    }
    while c.rx.len() >= 7 {
        let proto = u16::from_be_bytes([c.rx[2], c.rx[3]]);
        let len = usize::from(u16::from_be_bytes([c.rx[4], c.rx[5]]));
        if proto != 0 || !(2..=254).contains(&len) {
            return false;
        }
        if c.rx.len() < 6 + len {
            break;
        }
        let frame: Vec<u8> = c.rx.drain(..6 + len).collect();
        let unit = frame[6];
        if unit != unit_id && unit != 255 && unit != 0 {
            continue;
        }
        let resp = pdu(board, &frame[7..]);
        let mut out = Vec::with_capacity(7 + resp.len());
        out.extend_from_slice(&frame[0..4]);
        out.extend_from_slice(&((resp.len() + 1) as u16).to_be_bytes());
        out.push(unit);
        out.extend_from_slice(&resp);
        let _ = c.stream.set_write_timeout(Some(Duration::from_millis(100)));
        if write_all_nonblocking(&mut c.stream, &out).is_err() {
            return false;
        }
    }
    c.last.elapsed() < Duration::from_secs(IDLE_S)
}

fn write_all_nonblocking(s: &mut TcpStream, mut b: &[u8]) -> std::io::Result<()> {
    let t0 = Instant::now();
    while !b.is_empty() {
        match s.write(b) {
            Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
            Ok(n) => b = &b[n..],
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if t0.elapsed() > Duration::from_millis(100) {
                    return Err(e);
                }
                std::thread::sleep(Duration::from_micros(100));
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
