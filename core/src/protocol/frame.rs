//! Frames on the wire: `COBS(seq · type · payload · crc32) 0x00`.
//!
//! | offset (decoded) | size | field |
//! |---|---|---|
//! | 0 | 2 | `seq`, u16 little-endian |
//! | 2 | 1 | `type`, message type (see [`super::msg`]) |
//! | 3 | n | payload, 0 ≤ n ≤ [`MAX_PAYLOAD`] |
//! | 3 + n | 4 | CRC-32 ([`CRC32`]) of bytes 0 … 3 + n − 1, little-endian |
//!
//! The decoded frame is 7 … [`MAX_FRAME`] bytes; COBS-encoded it is at most
//! [`MAX_WIRE`] bytes, then one 0x00 delimiter. An empty frame (two delimiters in a row)
//! is ignored, so a sender may start with 0x00 to resynchronise the receiver.
//!
//! COBS is the `cobs` crate's, the CRC the `crc` crate's CRC-32/ISO-HDLC (IEEE 802.3:
//! polynomial 0x04C11DB7 reflected, init and final XOR 0xFFFFFFFF; check value of
//! `"123456789"`: 0xCBF43926) — also the CRC of a table upload and of a flash slot.

/// The CRC-32 of every frame, table and flash slot. A `static`: its 1 KiB table is never
/// copied onto a stack.
pub static CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// A CRC-32 being computed over several pieces ([`CRC32`]`.digest()`, `update`,
/// `finalize`).
pub type Crc32 = crc::Digest<'static, u32>;

/// The CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// Largest decoded frame: header (3) + payload + CRC (4), bytes.
pub const MAX_FRAME: usize = 512;
/// Header (seq, type) + CRC, bytes.
pub const OVERHEAD: usize = 7;
/// Largest payload, bytes.
pub const MAX_PAYLOAD: usize = MAX_FRAME - OVERHEAD;
/// Largest COBS-encoded frame without its delimiter, bytes.
pub const MAX_WIRE: usize = cobs::max_encoding_length(MAX_FRAME);

/// Why received bytes are not a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The bytes between two delimiters are not valid COBS.
    Cobs,
    /// Shorter than the 7 bytes of header and CRC.
    Truncated,
    /// More than [`MAX_WIRE`] bytes before the delimiter (the rest was discarded).
    Oversized,
    /// The CRC does not match.
    Crc,
}

/// A received, CRC-checked frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Sequence number.
    pub seq: u16,
    /// Message type.
    pub ty: u8,
    /// Payload.
    pub payload: &'a [u8],
}

/// Checks and splits one decoded frame.
pub fn parse(decoded: &[u8]) -> Result<Frame<'_>, FrameError> {
    if decoded.len() < OVERHEAD {
        return Err(FrameError::Truncated);
    }
    if decoded.len() > MAX_FRAME {
        return Err(FrameError::Oversized);
    }
    let body_len = decoded.len().saturating_sub(4);
    let (body, crc) = decoded.split_at(body_len);
    let crc = u32::from_le_bytes(crc.try_into().map_err(|_| FrameError::Truncated)?);
    if crc32(body) != crc {
        return Err(FrameError::Crc);
    }
    let (hdr, payload) = body.split_at(3);
    let (&s0, &s1, &ty) = match hdr {
        [a, b, c] => (a, b, c),
        _ => return Err(FrameError::Truncated),
    };
    Ok(Frame {
        seq: u16::from_le_bytes([s0, s1]),
        ty,
        payload,
    })
}

/// Builds a frame (COBS-encoded, delimiter included) into `out`; returns its length.
/// `None` when the payload exceeds [`MAX_PAYLOAD`] or `out` is too small (it needs
/// [`MAX_WIRE`] + 1 bytes for any payload).
pub fn encode(seq: u16, ty: u8, payload: &[u8], out: &mut [u8]) -> Option<usize> {
    if payload.len() > MAX_PAYLOAD {
        return None;
    }
    let mut raw = [0u8; MAX_FRAME];
    let [s0, s1] = seq.to_le_bytes();
    let body_len = payload.len().checked_add(3)?;
    raw.get_mut(..3)?.copy_from_slice(&[s0, s1, ty]);
    raw.get_mut(3..body_len)?.copy_from_slice(payload);
    let crc = crc32(raw.get(..body_len)?);
    let total = body_len.checked_add(4)?;
    raw.get_mut(body_len..total)?
        .copy_from_slice(&crc.to_le_bytes());
    let n = cobs::try_encode(raw.get(..total)?, out).ok()?;
    *out.get_mut(n)? = 0;
    n.checked_add(1)
}

/// Splits a byte stream into frames.
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    wire: [u8; MAX_WIRE],
    len: usize,
    overflow: bool,
    decoded: [u8; MAX_FRAME],
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            wire: [0; MAX_WIRE],
            len: 0,
            overflow: false,
            decoded: [0; MAX_FRAME],
        }
    }

    /// Takes one byte. At a delimiter returns the frame it ends (or why it is not one);
    /// `None` otherwise and for empty frames.
    pub fn push(&mut self, b: u8) -> Option<Result<Frame<'_>, FrameError>> {
        if b != 0 {
            match self.wire.get_mut(self.len) {
                Some(slot) if !self.overflow => {
                    *slot = b;
                    self.len = self.len.saturating_add(1);
                }
                _ => self.overflow = true,
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflow) {
            return Some(Err(FrameError::Oversized));
        }
        if len == 0 {
            return None;
        }
        let wire = self.wire.get(..len).unwrap_or(&[]);
        let n = match cobs::decode(wire, &mut self.decoded) {
            Ok(n) => n,
            Err(cobs::DecodeError::TargetBufTooSmall) => return Some(Err(FrameError::Oversized)),
            Err(_) => return Some(Err(FrameError::Cobs)),
        };
        Some(parse(self.decoded.get(..n).unwrap_or(&[])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Got = std::vec::Vec<Result<(u16, u8, std::vec::Vec<u8>), FrameError>>;

    fn feed(d: &mut FrameDecoder, bytes: &[u8]) -> Got {
        let mut v = std::vec::Vec::new();
        for &b in bytes {
            if let Some(r) = d.push(b) {
                v.push(r.map(|f| (f.seq, f.ty, f.payload.to_vec())));
            }
        }
        v
    }

    #[test]
    fn roundtrip_and_errors() {
        let mut out = [0u8; MAX_WIRE + 1];
        let n = encode(0x1234, 0x11, &[0, 1, 2, 0, 0], &mut out).unwrap();
        let mut d = FrameDecoder::new();
        let got = feed(&mut d, &out[..n]);
        assert_eq!(got, [Ok((0x1234, 0x11, std::vec![0, 1, 2, 0, 0]))]);
        // Flip one bit of the CRC region: CRC error.
        let mut bad = out[..n].to_vec();
        bad[n - 3] ^= 0x01;
        if bad[n - 3] == 0 {
            bad[n - 3] = 0x80;
        }
        assert_eq!(feed(&mut d, &bad), [Err(FrameError::Crc)]);
        // Too short.
        let mut short = [0u8; 8];
        let m = cobs::encode(&[1, 2, 3], &mut short);
        short[m] = 0;
        assert_eq!(feed(&mut d, &short[..=m]), [Err(FrameError::Truncated)]);
        // Oversized: then the decoder recovers.
        let mut big = std::vec![0x55u8; MAX_WIRE + 10];
        big.push(0);
        big.extend_from_slice(&out[..n]);
        let got = feed(&mut d, &big);
        assert_eq!(got.len(), 2);
        assert_eq!(got[0], Err(FrameError::Oversized));
        assert!(got[1].is_ok());
        // Empty frames are ignored.
        assert!(feed(&mut d, &[0, 0, 0]).is_empty());
    }

    /// The crates give the bytes the hand-written codecs gave (protocol version 2's
    /// frames): the CRC's check value, and COBS of zeros, of a 254-byte run and of data.
    #[test]
    fn crc_and_cobs_are_the_standard_ones() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        let mut d = CRC32.digest();
        d.update(b"1234");
        d.update(b"56789");
        assert_eq!(d.finalize(), 0xCBF4_3926);
        let mut out = [0u8; 300];
        let n = cobs::encode(&[0x11, 0x00, 0x00, 0x22], &mut out);
        assert_eq!(&out[..n], &[0x02, 0x11, 0x01, 0x02, 0x22]);
        let n = cobs::encode(&[0x00], &mut out);
        assert_eq!(&out[..n], &[0x01, 0x01]);
        // A 254-byte run without a zero: one 0xFF block. (The hand-written encoder added
        // an empty final block, 0x01; both forms decode to the same bytes.)
        let run: std::vec::Vec<u8> = (1..=254).collect();
        let n = cobs::encode(&run, &mut out);
        assert_eq!((n, out[0]), (255, 0xFF));
        let mut back = [0u8; 300];
        assert_eq!(cobs::decode(&out[..n], &mut back).unwrap(), 254);
        out[255] = 0x01;
        assert_eq!(cobs::decode(&out[..256], &mut back).unwrap(), 254);
        assert_eq!(&back[..254], &run[..]);
    }

    #[test]
    fn largest_payload_fits() {
        let p = [0xA5u8; MAX_PAYLOAD];
        let mut out = [0u8; MAX_WIRE + 1];
        let n = encode(1, 2, &p, &mut out).unwrap();
        let mut d = FrameDecoder::new();
        let got = feed(&mut d, &out[..n]);
        assert_eq!(got.len(), 1);
        assert!(got[0].is_ok());
        assert!(encode(1, 2, &[0; MAX_PAYLOAD + 1], &mut out).is_none());
    }
}
