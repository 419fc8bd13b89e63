//! CRC-32 (IEEE 802.3 / zlib / PNG): polynomial 0x04C11DB7 reflected (0xEDB88320),
//! initial value 0xFFFFFFFF, input and output reflected, final XOR 0xFFFFFFFF.
//! Check value: `crc32(b"123456789") = 0xCBF43926`.
//!
//! Table-driven, one byte per step: `c = T[(c ^ b) & 0xFF] ^ (c >> 8)`. The 1 KiB table
//! is built at compile time.

/// The 256-entry table of the reflected polynomial.
const TABLE: [u32; 256] = build_table();

// Evaluated by the compiler only (a `const`): i < 256 and k < 8 bound every index and sum.
#[allow(clippy::arithmetic_side_effects, clippy::indexing_slicing)]
const fn build_table() -> [u32; 256] {
    let mut t = [0u32; 256];
    let mut i = 0u32;
    while i < 256 {
        let mut c = i;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i as usize] = c;
        i += 1;
    }
    t
}

/// A running CRC-32: `update` any number of times, then `finish`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc32(u32);

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A fresh CRC (register 0xFFFFFFFF).
    pub const fn new() -> Self {
        Self(0xFFFF_FFFF)
    }

    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut c = self.0;
        for &b in bytes {
            let idx = ((c ^ u32::from(b)) & 0xFF) as usize;
            c = TABLE.get(idx).copied().unwrap_or(0) ^ (c >> 8);
        }
        self.0 = c;
    }

    /// The CRC of everything fed so far.
    pub const fn finish(self) -> u32 {
        self.0 ^ 0xFFFF_FFFF
    }
}

/// CRC-32 of one buffer.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn incremental_equals_one_shot() {
        let data: std::vec::Vec<u8> = (0..=255u8).cycle().take(1000).collect();
        let mut c = Crc32::new();
        for part in data.chunks(7) {
            c.update(part);
        }
        assert_eq!(c.finish(), crc32(&data));
    }
}
