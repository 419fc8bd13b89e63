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
        // Whole UTF-8 characters only reach the buffer when a line is shorter than it;
        // a longer one is cut at the last complete character.
        let bytes = self.buf.get(..self.len).unwrap_or(&[]);
        let text = match core::str::from_utf8(bytes) {
            Ok(t) => t,
            Err(e) => {
                core::str::from_utf8(bytes.get(..e.valid_up_to()).unwrap_or(&[])).unwrap_or("")
            }
        };
        semihost::write(text);
        self.len = 0;
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
