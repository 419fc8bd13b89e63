//! A table upload as a host sends it — the one sequence every host uses (host-sim's
//! `upload`, the board emulator's test host, the virtual board's test host):
//!
//! `TableBegin{id, columns S, rows n}`, then `TableChunk{offset, count, rows}` for rows
//! `0 … n−1` in chunks of at most `per` rows (each row in [`super::msg::write_row`]'s
//! wire format), then `TableCommit{crc}` with the CRC-32 of every row's bytes in order.
//! Each request must be acknowledged before the next is sent; the caller sends them and
//! stops at the first Nak.

use super::frame::CRC32;
use super::msg::{row_len, write_row, Request};
use super::wire::Writer;
use crate::table::Node;

/// Why an upload cannot be formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UploadError {
    /// More rows than a `TableBegin` can announce (65 535).
    TooManyRows,
    /// More slave columns than a table row carries (8, [`super::msg::MAX_AXES`]).
    TooManyColumns,
    /// The chunk size is 0 or above 255 rows.
    ChunkRows,
    /// The caller's buffer holds fewer than one chunk's bytes.
    BufferTooSmall,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    Begin,
    /// The next chunk starts at this row.
    Chunk(usize),
    Commit,
    Done,
}

/// The requests of one upload, in order ([`TableUpload::next_request`]).
#[derive(Clone, Debug)]
pub struct TableUpload<'a, const S: usize> {
    id: u32,
    nodes: &'a [Node<S>],
    per: usize,
    crc: u32,
    step: Step,
}

/// CRC-32 of every row's wire bytes in order (what `TableCommit` carries, and what
/// Status reports for the active table); `None` for more than 8 slave columns.
pub fn rows_crc<const S: usize>(nodes: impl Iterator<Item = Node<S>>) -> Option<u32> {
    let mut crc = CRC32.digest();
    let mut row = [0u8; row_len(super::msg::MAX_AXES)];
    for n in nodes {
        let mut w = Writer::new(&mut row);
        write_row(&mut w, &n)?;
        let len = w.len();
        crc.update(row.get(..len).unwrap_or(&[]));
    }
    Some(crc.finalize())
}

impl<'a, const S: usize> TableUpload<'a, S> {
    /// An upload of `nodes` as table `id` in chunks of at most `per_chunk_rows` rows (the
    /// board's `max_chunk_rows` from Info).
    pub fn new(id: u32, nodes: &'a [Node<S>], per_chunk_rows: usize) -> Result<Self, UploadError> {
        if u16::try_from(nodes.len()).is_err() {
            return Err(UploadError::TooManyRows);
        }
        if S > super::msg::MAX_AXES {
            return Err(UploadError::TooManyColumns);
        }
        if per_chunk_rows == 0 || u8::try_from(per_chunk_rows).is_err() {
            return Err(UploadError::ChunkRows);
        }
        let crc = rows_crc(nodes.iter().copied()).ok_or(UploadError::TooManyColumns)?;
        Ok(Self {
            id,
            nodes,
            per: per_chunk_rows,
            crc,
            step: Step::Begin,
        })
    }

    /// The same upload under another id (the CRC is the rows', whatever the id: a host
    /// that names a table by its CRC builds the upload once).
    pub fn with_id(self, id: u32) -> Self {
        Self { id, ..self }
    }

    /// CRC-32 of every row's wire bytes (what `TableCommit` carries).
    pub fn crc(&self) -> u32 {
        self.crc
    }

    /// Rows of the table.
    pub fn rows(&self) -> usize {
        self.nodes.len()
    }

    /// Rows handed out in chunks so far.
    pub fn rows_sent(&self) -> usize {
        match self.step {
            Step::Begin => 0,
            Step::Chunk(off) => off,
            Step::Commit | Step::Done => self.nodes.len(),
        }
    }

    /// Bytes a buffer needs for the largest chunk.
    pub fn chunk_bytes(&self) -> usize {
        self.per.min(self.nodes.len()).saturating_mul(row_len(S))
    }

    /// The next request (its chunk rows written into `buf`), or `None` after the commit.
    pub fn next_request<'b>(
        &mut self,
        buf: &'b mut [u8],
    ) -> Result<Option<Request<'b>>, UploadError> {
        let rows = self.nodes.len();
        match self.step {
            Step::Begin => {
                self.step = if rows == 0 {
                    Step::Commit
                } else {
                    Step::Chunk(0)
                };
                Ok(Some(Request::TableBegin {
                    id: self.id,
                    columns: u8::try_from(S).map_err(|_| UploadError::TooManyColumns)?,
                    rows: u16::try_from(rows).map_err(|_| UploadError::TooManyRows)?,
                }))
            }
            Step::Chunk(off) => {
                let end = off.saturating_add(self.per).min(rows);
                let chunk = self.nodes.get(off..end).unwrap_or(&[]);
                let mut w = Writer::new(buf);
                for n in chunk {
                    write_row(&mut w, n).ok_or(UploadError::BufferTooSmall)?;
                }
                let len = w.len();
                self.step = if end >= rows {
                    Step::Commit
                } else {
                    Step::Chunk(end)
                };
                Ok(Some(Request::TableChunk {
                    offset: u16::try_from(off).map_err(|_| UploadError::TooManyRows)?,
                    count: u8::try_from(chunk.len()).map_err(|_| UploadError::ChunkRows)?,
                    data: buf.get(..len).unwrap_or(&[]),
                }))
            }
            Step::Commit => {
                self.step = Step::Done;
                Ok(Some(Request::TableCommit { crc: self.crc }))
            }
            Step::Done => Ok(None),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::frame::crc32;
    use super::*;
    use crate::units::{Master, PosUm};
    use std::string::String;
    use std::vec::Vec;

    fn nodes(n: usize) -> Vec<Node<2>> {
        (0..n)
            .map(|i| Node {
                master: Master::from_num(i as i32 * 100),
                slave_um: [PosUm::from_num(i as i32), PosUm::from_num(-(i as i32))],
            })
            .collect()
    }

    /// The sequence: Begin, ⌈n/per⌉ chunks covering every row once in order, Commit
    /// with the CRC of the concatenated chunk bytes.
    #[test]
    fn begin_chunks_commit() {
        let ns = nodes(23);
        let mut up = TableUpload::new(7, &ns, 5).unwrap();
        let mut buf = [0u8; 5 * 16];
        let mut all = Vec::new();
        let mut kinds = Vec::new();
        while let Some(q) = up.next_request(&mut buf).unwrap() {
            match q {
                Request::TableBegin { id, columns, rows } => {
                    assert_eq!((id, columns, rows), (7, 2, 23));
                    kinds.push('B');
                }
                Request::TableChunk {
                    offset,
                    count,
                    data,
                } => {
                    assert_eq!(usize::from(offset), all.len() / 16);
                    assert_eq!(data.len(), usize::from(count) * 16);
                    all.extend_from_slice(data);
                    kinds.push('C');
                }
                Request::TableCommit { crc } => {
                    assert_eq!(crc, crc32(&all));
                    kinds.push('E');
                }
                q => panic!("{q:?}"),
            }
        }
        assert_eq!(kinds.iter().collect::<String>(), "BCCCCCE");
        assert_eq!(all.len(), 23 * 16);
        assert_eq!(up.rows_sent(), 23);
        assert_eq!(up.crc(), crc32(&all));
    }

    #[test]
    fn refuses_what_cannot_be_sent() {
        let ns = nodes(3);
        assert_eq!(
            TableUpload::new(1, &ns, 0).err(),
            Some(UploadError::ChunkRows)
        );
        assert_eq!(
            TableUpload::new(1, &ns, 256).err(),
            Some(UploadError::ChunkRows)
        );
        let mut up = TableUpload::new(1, &ns, 3).unwrap();
        let mut small = [0u8; 20];
        assert!(up.next_request(&mut small).unwrap().is_some()); // Begin
        assert_eq!(
            up.next_request(&mut small).err(),
            Some(UploadError::BufferTooSmall)
        );
        let big: Vec<Node<1>> = (0..70_000)
            .map(|i| Node {
                master: Master::from_num(i),
                slave_um: [PosUm::ZERO],
            })
            .collect();
        assert_eq!(
            TableUpload::new(1, &big, 10).err(),
            Some(UploadError::TooManyRows)
        );
    }
}
