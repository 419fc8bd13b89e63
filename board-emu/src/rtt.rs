//! The firmware's defmt log: the bytes of RTT up-buffer 0 (read from the emulated RAM by
//! [`crate::machine::Machine::poll_rtt`]) decoded with the ELF's defmt table by
//! `defmt-decoder`.

use anyhow::{anyhow, Result};
use defmt_decoder::{DecodeError, Table};

/// One decoded log line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Line {
    /// Level (`INFO`, `WARN`, …), empty if none.
    pub level: String,
    /// The message.
    pub message: String,
}

/// Decodes every complete frame in `bytes` with the defmt table of `elf`.
pub fn decode(elf: &[u8], bytes: &[u8]) -> Result<Vec<Line>> {
    let table = Table::parse(elf)?.ok_or_else(|| anyhow!("the ELF has no defmt table"))?;
    let mut dec = table.new_stream_decoder();
    dec.received(bytes);
    let mut out = Vec::new();
    loop {
        match dec.decode() {
            Ok(f) => out.push(Line {
                level: f
                    .level()
                    .map(|l| l.as_str().to_uppercase())
                    .unwrap_or_default(),
                message: f.display_message().to_string(),
            }),
            Err(DecodeError::UnexpectedEof) => break,
            Err(DecodeError::Malformed) => {
                if table.encoding().can_recover() {
                    continue;
                }
                return Err(anyhow!("malformed defmt frame after {} lines", out.len()));
            }
        }
    }
    Ok(out)
}
