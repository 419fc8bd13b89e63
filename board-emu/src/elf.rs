//! The firmware image: its loadable segments (at their load addresses, i.e. in flash),
//! its symbols (to name the function at a PC) and the addresses the emulator needs.

use anyhow::{anyhow, Context, Result};
use object::{Object, ObjectSegment, ObjectSymbol, SymbolKind};

/// A loaded ELF.
pub struct Image {
    /// The whole file (the defmt decoder reads its tables from it).
    pub bytes: Vec<u8>,
    /// `(load address, contents)` of every loadable segment.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// Function symbols sorted by address: `(start, size, demangled name)`.
    functions: Vec<(u32, u32, String)>,
    /// The RTT control block (`_SEGGER_RTT`), if the image has one.
    pub rtt: Option<u32>,
    /// The lowest address of the stack region (`_stack_end` of flip-link / cortex-m-rt:
    /// the stack grows down to it), and the initial stack pointer.
    pub stack: (u32, u32),
}

impl Image {
    /// Reads and parses `path`.
    pub fn load(path: &std::path::Path) -> Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        Self::parse(bytes)
    }

    /// Parses an ELF already in memory.
    pub fn parse(bytes: Vec<u8>) -> Result<Self> {
        let file = object::File::parse(&*bytes).context("not an ELF file")?;
        let mut segments = Vec::new();
        for seg in file.segments() {
            let data = seg.data().context("segment data")?;
            if data.is_empty() {
                continue;
            }
            let (pa, _) = seg.file_range();
            let _ = pa;
            // object's `address()` is the virtual address; the load address comes from
            // the program header's p_paddr, which object exposes only through the raw
            // header: find it by matching the file offset.
            let paddr = phys_addr(&bytes, seg.file_range().0).ok_or_else(|| {
                anyhow!(
                    "segment at file offset {:#x} has no program header",
                    seg.file_range().0
                )
            })?;
            segments.push((paddr, data.to_vec()));
        }
        let mut functions = Vec::new();
        let mut rtt = None;
        let mut stack_start = None;
        let mut stack_end = None;
        for sym in file.symbols() {
            let name = sym.name().unwrap_or("");
            match name {
                "_SEGGER_RTT" => rtt = Some(sym.address() as u32),
                "_stack_start" => stack_start = Some(sym.address() as u32),
                "_stack_end" => stack_end = Some(sym.address() as u32),
                _ => {}
            }
            if sym.kind() == SymbolKind::Text && sym.size() > 0 {
                let demangled = demangle(name);
                functions.push(((sym.address() as u32) & !1, sym.size() as u32, demangled));
            }
        }
        functions.sort_by_key(|f| f.0);
        // Without the linker's symbols: the initial SP from the vector table, and the
        // stack assumed to reach down to the RAM's start.
        let initial_sp = segments
            .iter()
            .find(|(a, d)| *a == 0x0800_0000 && d.len() >= 8)
            .map(|(_, d)| u32::from_le_bytes([d[0], d[1], d[2], d[3]]))
            .ok_or_else(|| anyhow!("no vector table at 0x0800_0000"))?;
        let top = stack_start.unwrap_or(initial_sp);
        let bottom = stack_end.unwrap_or(0x2000_0000);
        Ok(Self {
            bytes,
            segments,
            functions,
            rtt,
            stack: (bottom, top),
        })
    }

    /// The function containing `pc`, as `name+0xoff`, or the bare address.
    pub fn symbolize(&self, pc: u32) -> String {
        let pc = pc & !1;
        let i = self.functions.partition_point(|f| f.0 <= pc);
        if let Some((start, size, name)) = i.checked_sub(1).and_then(|i| self.functions.get(i)) {
            if pc < start.saturating_add((*size).max(1)) {
                return format!("{name}+{:#x}", pc - start);
            }
        }
        format!("{pc:#010x}")
    }

    /// The address of the first function whose name contains `needle`.
    pub fn function(&self, needle: &str) -> Option<u32> {
        self.functions
            .iter()
            .find(|f| f.2.contains(needle))
            .map(|f| f.0)
    }
}

/// The p_paddr of the program header whose p_offset is `offset` (32-bit little-endian
/// ELF).
fn phys_addr(elf: &[u8], offset: u64) -> Option<u32> {
    let rd32 =
        |o: usize| -> Option<u32> { Some(u32::from_le_bytes(elf.get(o..o + 4)?.try_into().ok()?)) };
    let rd16 =
        |o: usize| -> Option<u16> { Some(u16::from_le_bytes(elf.get(o..o + 2)?.try_into().ok()?)) };
    let phoff = rd32(0x1C)? as usize;
    let phentsize = rd16(0x2A)? as usize;
    let phnum = rd16(0x2C)? as usize;
    for k in 0..phnum {
        let h = phoff + k * phentsize;
        let (ty, off, paddr) = (rd32(h)?, rd32(h + 4)?, rd32(h + 12)?);
        if ty == 1 && u64::from(off) == offset {
            return Some(paddr);
        }
    }
    None
}

/// Rust's legacy (`_ZN…E`) mangling, undone enough to read a symbol.
fn demangle(name: &str) -> String {
    let Some(rest) = name.strip_prefix("_ZN") else {
        return name.to_string();
    };
    let mut out = Vec::new();
    let b = rest.as_bytes();
    let mut i = 0;
    while i < b.len() && b[i].is_ascii_digit() {
        let mut n = 0usize;
        while i < b.len() && b[i].is_ascii_digit() {
            n = n * 10 + usize::from(b[i] - b'0');
            i += 1;
        }
        let Some(part) = rest.get(i..i + n) else {
            break;
        };
        i += n;
        // The trailing hash (`h0123…`) is noise.
        if !(part.len() == 17 && part.starts_with('h')) {
            out.push(
                part.replace("$LT$", "<")
                    .replace("$GT$", ">")
                    .replace("$u20$", " ")
                    .replace("..", "::"),
            );
        }
    }
    out.join("::")
}
