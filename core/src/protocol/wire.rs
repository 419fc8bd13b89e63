//! Little-endian field writer and reader over byte slices (no panics, typed shortfall),
//! for the fixed layouts: table rows and the flash slot. Message bodies are postcard
//! ([`super::msg`]).

/// Appends little-endian fields to a buffer; every write fails with `None` when full.
#[derive(Debug)]
pub struct Writer<'a> {
    buf: &'a mut [u8],
    len: usize,
}

impl<'a> Writer<'a> {
    /// A writer at the start of `buf`.
    pub fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, len: 0 }
    }
    /// Bytes written.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Nothing written yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Appends raw bytes.
    pub fn bytes(&mut self, b: &[u8]) -> Option<()> {
        let end = self.len.checked_add(b.len())?;
        self.buf.get_mut(self.len..end)?.copy_from_slice(b);
        self.len = end;
        Some(())
    }
    /// Appends a `u8`.
    pub fn u8(&mut self, v: u8) -> Option<()> {
        self.bytes(&[v])
    }
    /// Appends a `u16`.
    pub fn u16(&mut self, v: u16) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
    /// Appends a `u32`.
    pub fn u32(&mut self, v: u32) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
    /// Appends an `i16`.
    pub fn i16(&mut self, v: i16) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
    /// Appends an `i32`.
    pub fn i32(&mut self, v: i32) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
    /// Appends an `i64`.
    pub fn i64(&mut self, v: i64) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
    /// Appends an `f32` (IEEE 754 binary32).
    pub fn f32(&mut self, v: f32) -> Option<()> {
        self.bytes(&v.to_le_bytes())
    }
}

/// Reads little-endian fields; every read fails with `None` past the end.
#[derive(Clone, Debug)]
pub struct Reader<'a> {
    buf: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader over `buf`.
    pub fn new(buf: &'a [u8]) -> Self {
        Self { buf }
    }
    /// Bytes left.
    pub fn remaining(&self) -> usize {
        self.buf.len()
    }
    /// Takes `n` raw bytes.
    pub fn bytes(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.buf.len() {
            return None;
        }
        let (a, b) = self.buf.split_at(n);
        self.buf = b;
        Some(a)
    }
    fn arr<const K: usize>(&mut self) -> Option<[u8; K]> {
        self.bytes(K)?.try_into().ok()
    }
    /// Takes a `u8`.
    pub fn u8(&mut self) -> Option<u8> {
        self.arr::<1>().map(|[b]| b)
    }
    /// Takes a `u16`.
    pub fn u16(&mut self) -> Option<u16> {
        self.arr().map(u16::from_le_bytes)
    }
    /// Takes a `u32`.
    pub fn u32(&mut self) -> Option<u32> {
        self.arr().map(u32::from_le_bytes)
    }
    /// Takes an `i16`.
    pub fn i16(&mut self) -> Option<i16> {
        self.arr().map(i16::from_le_bytes)
    }
    /// Takes an `i32`.
    pub fn i32(&mut self) -> Option<i32> {
        self.arr().map(i32::from_le_bytes)
    }
    /// Takes an `i64`.
    pub fn i64(&mut self) -> Option<i64> {
        self.arr().map(i64::from_le_bytes)
    }
    /// Takes an `f32`.
    pub fn f32(&mut self) -> Option<f32> {
        self.arr().map(f32::from_le_bytes)
    }
}
