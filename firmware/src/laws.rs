//! The two law buffers: a table activation swaps *references* inside the tick's critical
//! section instead of moving the law.
//!
//! The runtime runs a `&'static mut Law` ([`LawRef`]). A new law (a table activated, a
//! gain changed) is built by the link task and written into the spare buffer — the
//! ≈ 14 KiB copy happens here, in thread mode, while the tick keeps running — then
//! `Runtime::install` swaps it with the running one in a critical section of a few dozen
//! instructions, and the old buffer becomes the spare. Moving `Follower<2, 256>` by value
//! inside that section was measured at 119 448 instructions (bench-m4
//! `runtime_install_law` at 67685ae: ≈ 0.96 ms at 168 MHz, estimated — one whole tick).
//!
//! Exactly two buffers: one runs, one is spare (or not yet used). [`place`] takes the
//! spare the runtime gave back, else a buffer never used.

use static_cell::StaticCell;

use crate::program::Law;

/// A law in one of the two static buffers.
pub type LawRef = &'static mut Law;

static LAW_A: StaticCell<Law> = StaticCell::new();
static LAW_B: StaticCell<Law> = StaticCell::new();

/// Writes `law` into `spare` (the buffer the runtime gave back at the last swap) or, if
/// there is none, into a buffer not used yet. `None` only if both buffers are taken and
/// no spare was given — the caller lost track of one (never: it keeps the spare).
pub fn place(law: Law, spare: Option<LawRef>) -> Option<LawRef> {
    if let Some(s) = spare {
        *s = law;
        return Some(s);
    }
    LAW_A
        .try_uninit()
        .or_else(|| LAW_B.try_uninit())
        .map(|m| m.write(law))
}
