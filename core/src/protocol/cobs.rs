//! Consistent Overhead Byte Stuffing (Cheshire & Baker, 1999): removes every 0x00 from a
//! frame so 0x00 can delimit frames on the wire.
//!
//! The encoded frame is a sequence of blocks `code, data[code − 1]`: a block with
//! `code < 0xFF` stands for its data followed by one (implicit) zero; a block with
//! `code = 0xFF` stands for 254 data bytes and no zero. The last block's implicit zero is
//! dropped. Overhead: at most ⌈n/254⌉ bytes (1 for n < 254), plus the 0x00 delimiter the
//! caller appends.

/// Why a COBS block sequence could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CobsError {
    /// A 0x00 inside the encoded data (a code byte of 0).
    ZeroByte,
    /// A block runs past the end of the data.
    ShortBlock,
    /// The output buffer is too small.
    Overflow,
}

/// Largest encoded size of `n` bytes (without the delimiter): `n + ⌈n/254⌉`, at least 1.
pub const fn max_encoded_len(n: usize) -> usize {
    n.saturating_add(n / 254).saturating_add(1)
}

/// Encodes `src` into `dst`; returns the encoded length (no delimiter is written).
pub fn encode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let mut code_at = 0usize; // index of the pending code byte
    let mut out = 1usize; // next write index
    let mut code = 1u8;
    let put = |dst: &mut [u8], i: usize, v: u8| -> Result<(), CobsError> {
        *dst.get_mut(i).ok_or(CobsError::Overflow)? = v;
        Ok(())
    };
    if dst.is_empty() {
        return Err(CobsError::Overflow);
    }
    for &b in src {
        if b == 0 {
            put(dst, code_at, code)?;
            code_at = out;
            out = out.checked_add(1).ok_or(CobsError::Overflow)?;
            code = 1;
        } else {
            put(dst, out, b)?;
            out = out.checked_add(1).ok_or(CobsError::Overflow)?;
            code = code.wrapping_add(1);
            if code == 0xFF {
                put(dst, code_at, code)?;
                code_at = out;
                out = out.checked_add(1).ok_or(CobsError::Overflow)?;
                code = 1;
            }
        }
    }
    put(dst, code_at, code)?;
    Ok(out)
}

/// Decodes one frame (without its delimiter) into `dst`; returns the decoded length.
pub fn decode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let mut i = 0usize;
    let mut out = 0usize;
    while let Some(&code) = src.get(i) {
        if code == 0 {
            return Err(CobsError::ZeroByte);
        }
        let start = i.checked_add(1).ok_or(CobsError::ShortBlock)?;
        let end = i
            .checked_add(usize::from(code))
            .ok_or(CobsError::ShortBlock)?;
        let block = src.get(start..end).ok_or(CobsError::ShortBlock)?;
        for &b in block {
            if b == 0 {
                return Err(CobsError::ZeroByte);
            }
            *dst.get_mut(out).ok_or(CobsError::Overflow)? = b;
            out = out.checked_add(1).ok_or(CobsError::Overflow)?;
        }
        i = end;
        if code != 0xFF && i < src.len() {
            *dst.get_mut(out).ok_or(CobsError::Overflow)? = 0;
            out = out.checked_add(1).ok_or(CobsError::Overflow)?;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn roundtrip(data: &[u8]) -> std::vec::Vec<u8> {
        let mut enc = std::vec![0u8; max_encoded_len(data.len())];
        let n = encode(data, &mut enc).unwrap();
        assert!(!enc[..n].contains(&0), "encoded data contains a zero");
        let mut dec = std::vec![0u8; data.len() + 1];
        let m = decode(&enc[..n], &mut dec).unwrap();
        dec.truncate(m);
        dec
    }

    #[test]
    fn known_vectors() {
        // Wikipedia's examples.
        let mut b = [0u8; 16];
        assert_eq!(encode(&[0x00], &mut b), Ok(2));
        assert_eq!(&b[..2], &[0x01, 0x01]);
        assert_eq!(encode(&[0x11, 0x22, 0x00, 0x33], &mut b), Ok(5));
        assert_eq!(&b[..5], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        assert_eq!(encode(&[], &mut b), Ok(1));
        assert_eq!(&b[..1], &[0x01]);
    }

    #[test]
    fn long_runs() {
        for n in [253usize, 254, 255, 508, 509, 600] {
            let data: std::vec::Vec<u8> = (0..n).map(|i| (i % 255) as u8 + 1).collect();
            assert_eq!(roundtrip(&data), data, "n = {n}");
        }
    }

    #[test]
    fn bad_input_is_typed() {
        let mut b = [0u8; 16];
        assert_eq!(decode(&[0x05, 0x11], &mut b), Err(CobsError::ShortBlock));
        assert_eq!(decode(&[0x02, 0x00], &mut b), Err(CobsError::ZeroByte));
        assert_eq!(
            decode(&[0x03, 1, 2, 0x02, 3], &mut b[..2]),
            Err(CobsError::Overflow)
        );
    }

    proptest! {
        #[test]
        fn roundtrips(data in proptest::collection::vec(any::<u8>(), 0..800)) {
            prop_assert_eq!(roundtrip(&data), data);
        }

        #[test]
        fn decode_never_panics(data in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut b = [0u8; 700];
            let _ = decode(&data, &mut b);
        }
    }
}
