//! Line-buffered text output over semihosting (`core::fmt` into a fixed buffer, one
//! SYS_WRITE0 per line).

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
        if let Some(b) = self.buf.get_mut(self.len) {
            *b = 0;
        }
        semihost::write0(self.buf.get(..=self.len).unwrap_or(&[]));
        self.len = 0;
    }
}

impl fmt::Write for Out {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for &c in s.as_bytes() {
            // Keep one byte for the NUL terminator.
            if self.len + 1 >= self.buf.len() {
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
