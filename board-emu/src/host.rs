//! A host on the emulated USART6, in emulated time: the framed protocol of PROTOCOL.md
//! exactly as `host-sim`'s serial link speaks it (one request, its answer by sequence
//! number; telemetry kept aside).

use crate::machine::Machine;
use anyhow::{anyhow, bail, Result};
use hydra_core::protocol::frame::{FrameDecoder, MAX_WIRE};
use hydra_core::protocol::handler::encode_request;
use hydra_core::protocol::msg::Telemetry;
use hydra_core::protocol::upload::TableUpload;
use hydra_core::protocol::{Request, Response};
use hydra_core::table::Node;

/// The host's side of the link.
pub struct Host {
    seq: u16,
    dec: FrameDecoder,
    /// Telemetry frames received while waiting for answers.
    pub telemetry: Vec<Telemetry>,
    /// Emulated seconds a request may wait for its answer (Save: 6 s, as host-sim).
    pub timeout_s: f64,
}

impl Default for Host {
    fn default() -> Self {
        Self::new()
    }
}

impl Host {
    /// A host that has not said Hello.
    pub fn new() -> Self {
        Self {
            seq: 0x1234,
            dec: FrameDecoder::new(),
            telemetry: Vec::new(),
            timeout_s: 0.5,
        }
    }

    /// The frames the board sent since the last call.
    pub fn frames(&mut self, m: &mut Machine) -> Vec<(u16, Response)> {
        let bytes = std::mem::take(&mut m.state_mut().bus.usart6.to_host);
        let mut out = Vec::new();
        for b in bytes {
            if let Some(Ok(f)) = self.dec.push(b) {
                if let Some(r) = Response::decode(f.ty, f.payload) {
                    out.push((f.seq, r));
                }
            }
        }
        out
    }

    /// Sends `q` and runs the board until its answer (a Nak is an answer).
    pub fn request(&mut self, m: &mut Machine, q: &Request<'_>) -> Result<Response> {
        let seq = if matches!(q, Request::Hello) {
            self.seq
        } else {
            self.seq.wrapping_add(1)
        };
        let mut buf = [0u8; MAX_WIRE + 1];
        let Some(n) = encode_request(seq, q, &mut buf) else {
            bail!("request too large for one frame");
        };
        let now = m.cycles();
        m.state_mut().bus.usart6.host_send(&buf[..n], now);
        let timeout = if matches!(q, Request::Save) {
            6.0
        } else {
            self.timeout_s
        };
        let deadline = m.seconds() + timeout;
        while m.seconds() < deadline {
            m.run_for(0.000_5)?;
            for (s, r) in self.frames(m) {
                match r {
                    Response::Telemetry(t) => self.telemetry.push(t),
                    r if s == seq => {
                        if !matches!(r, Response::Nak { .. }) {
                            self.seq = seq;
                        }
                        return Ok(r);
                    }
                    _ => {}
                }
            }
        }
        bail!("no answer to {q:?} within {timeout} s emulated")
    }

    /// A request that must be acknowledged.
    pub fn ack(&mut self, m: &mut Machine, q: &Request<'_>) -> Result<()> {
        match self.request(m, q)? {
            Response::Ack { .. } => Ok(()),
            r => bail!("{q:?} answered {r:?}"),
        }
    }

    /// Uploads `nodes` as table `id` in chunks of `per` rows (core's
    /// [`TableUpload`] sequence, each request acknowledged) and returns the answer to
    /// the commit.
    pub fn upload<const N: usize>(
        &mut self,
        m: &mut Machine,
        id: u32,
        nodes: &[Node<N>],
        per: usize,
    ) -> Result<Response> {
        let mut up = TableUpload::new(id, nodes, per).map_err(|e| anyhow!("upload: {e:?}"))?;
        let mut buf = vec![0u8; up.chunk_bytes()];
        while let Some(q) = up
            .next_request(&mut buf)
            .map_err(|e| anyhow!("upload: {e:?}"))?
        {
            if matches!(q, Request::TableCommit { .. }) {
                return self.request(m, &q);
            }
            self.ack(m, &q)?;
        }
        bail!("upload ended without a commit")
    }
}
