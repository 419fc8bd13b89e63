//! Line-buffered text output over semihosting (`core::fmt` into a fixed buffer, one
//! semihosting write per line).

use crate::semihost;
use core::fmt;

/// A line buffer; flushed on `\n` or when full.
pub struct Out {
    buf: [u8; 256],
    len: usize,
}

impl Out {
    /// An empty buffer.
    pub const fn new() -> Self {
        Self {
            buf: [0; 256],
            len: 0,
        }
    }

    fn flush(&mut self) {
        // Up to the last complete UTF-8 character: the bytes of a character a full buffer
        // cut (at most 3) stay for the next write.
        let bytes = self.buf.get(..self.len).unwrap_or(&[]);
        let valid = match core::str::from_utf8(bytes) {
            Ok(t) => t.len(),
            Err(e) => e.valid_up_to(),
        };
        semihost::write(core::str::from_utf8(bytes.get(..valid).unwrap_or(&[])).unwrap_or(""));
        let rest = self.len.saturating_sub(valid);
        if rest <= 3 {
            self.buf.copy_within(valid..self.len, 0);
            self.len = rest;
        } else {
            // Not a cut character: bytes that are no text are dropped.
            self.len = 0;
        }
    }
}

impl fmt::Write for Out {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for &c in s.as_bytes() {
            if self.len >= self.buf.len() {
                self.flush();
            }
            if let Some(b) = self.buf.get_mut(self.len) {
                *b = c;
                self.len += 1;
            }
            if c == b'\n' {
                self.flush();
            }
        }
        Ok(())
    }
}
