//! End-to-end tests live in `tests/tests/*.rs`; this library holds their shared helpers.

/// Path of the workspace root (for scenario and table files).
pub fn workspace_root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default()
}

use host_sim::vboard::{VBoard, AXES, CAPACITY};
use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::upload::TableUpload;
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

    /// Uploads `nodes` (one column per slave of the board) as table `id` — core's
    /// [`TableUpload`] sequence in chunks of the board's size, each request Ack'd — and
    /// returns the answer to TableCommit.
    pub fn upload(&mut self, b: &mut VBoard, id: u32, nodes: &[Node<AXES>]) -> Response {
        let per = Handler::<AXES, CAPACITY>::MAX_CHUNK_ROWS;
        let mut up = TableUpload::new(id, nodes, per).expect("an upload the board can take");
        let mut buf = vec![0u8; up.chunk_bytes()];
        while let Some(q) = up.next_request(&mut buf).expect("a chunk that fits") {
            if matches!(q, Request::TableCommit { .. }) {
                return self.req(b, &q);
            }
            self.ack(b, &q);
        }
        unreachable!("an upload ends with its commit")
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
