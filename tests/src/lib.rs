//! End-to-end tests live in `tests/tests/*.rs`; this library holds their shared helpers.

/// Path of the workspace root (for scenario and table files).
pub fn workspace_root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default()
}

use host_sim::vboard::{VBoard, AXES, CAPACITY};
use hydra_core::protocol::crc::crc32;
use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::msg::{row_len, write_row};
use hydra_core::protocol::wire::Writer;
use hydra_core::protocol::{Handler, Request, Response};
use hydra_core::table::Node;

/// A host talking frames to a [`VBoard`] in the same process (no PTY): one request, its
/// one answer, the session seq advanced on a positive answer as a real host does.
pub struct VbHost {
    seq: u16,
}

impl VbHost {
    /// A host whose first Hello carries `seq`.
    pub fn new(seq: u16) -> Self {
        Self { seq }
    }

    /// Sends `q`, returns the board's one answer.
    pub fn req(&mut self, b: &mut VBoard, q: &Request<'_>) -> Response {
        let s = if matches!(q, Request::Hello) {
            self.seq
        } else {
            self.seq.wrapping_add(1)
        };
        let mut f = [0u8; MAX_WIRE + 1];
        let n = encode_request(s, q, &mut f).expect("request fits one frame");
        let mut rs = exchange(b, &f[..n]);
        assert_eq!(rs.len(), 1, "one answer to {q:?}");
        let r = rs.remove(0);
        if !matches!(r, Response::Nak { .. }) {
            self.seq = s;
        }
        r
    }

    /// Sends `q`, which must be acknowledged.
    pub fn ack(&mut self, b: &mut VBoard, q: &Request<'_>) {
        let r = self.req(b, q);
        assert!(matches!(r, Response::Ack { .. }), "{q:?}: {r:?}");
    }

    /// Uploads `nodes` (one column per slave of the board) as table `id` (Begin, chunks of the board's size, each Ack'd) and
    /// returns the answer to TableCommit.
    pub fn upload(&mut self, b: &mut VBoard, id: u32, nodes: &[Node<AXES>]) -> Response {
        let rows = u16::try_from(nodes.len()).expect("rows fit u16");
        self.ack(
            b,
            &Request::TableBegin {
                id,
                columns: AXES as u8,
                rows,
            },
        );
        let per = Handler::<AXES, CAPACITY>::MAX_CHUNK_ROWS;
        let mut all = Vec::new();
        for (k, c) in nodes.chunks(per).enumerate() {
            let bytes = rows_bytes(c);
            all.extend_from_slice(&bytes);
            self.ack(
                b,
                &Request::TableChunk {
                    offset: (k * per) as u16,
                    count: c.len() as u8,
                    data: &bytes,
                },
            );
        }
        self.req(b, &Request::TableCommit { crc: crc32(&all) })
    }
}

/// Sends the wire bytes `frame` to `b` and returns every response it sends back
/// (answers and telemetry), in order.
pub fn exchange(b: &mut VBoard, frame: &[u8]) -> Vec<Response> {
    let mut out = Vec::new();
    b.on_bytes(frame, &mut |x| out.extend_from_slice(x));
    let mut d = FrameDecoder::new();
    let mut rs = Vec::new();
    for &x in &out {
        if let Some(fr) = d.push(x) {
            let fr = fr.expect("a valid frame from the board");
            rs.push(Response::decode(fr.ty, fr.payload).expect("a known response"));
        }
    }
    rs
}

/// Rows as on the wire.
pub fn rows_bytes<const S: usize>(ns: &[Node<S>]) -> Vec<u8> {
    let mut b = vec![0u8; ns.len() * row_len(S)];
    let mut w = Writer::new(&mut b);
    for n in ns {
        write_row(&mut w, n).expect("row fits");
    }
    b
}
