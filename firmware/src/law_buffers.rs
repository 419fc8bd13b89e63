//! The two law buffers: a table activation or a gain change builds the new law *in
//! place* in the spare buffer, then swaps *references* inside the tick's critical
//! section. No law is ever moved by value.
//!
//! The runtime runs a `&'static mut Law` ([`LawRef`]). Both buffers are statics whose
//! starting value is the all-zero [`Law::unconfigured`] (`.bss`, initialised at link
//! time, never through the stack). A new law is written into the spare buffer by the
//! link task — `Follower::configure` then `Follower::load_table`, field by field and one
//! table copy, in thread mode while the tick keeps running — then `Runtime::install`
//! swaps it with the running one in a critical section of a few dozen instructions, and
//! the old buffer becomes the spare. (Moving `Follower<2, 256>`, 12.6 KiB, by value
//! inside that section would copy it in and the old one out with the tick masked —
//! about one whole 1 ms tick at 168 MHz; and building a law by value puts frames of
//! tens of KiB on the 64 KiB stack. bench-m4's `runtime_install_law` measures the swap.)
//!
//! Exactly two buffers: one runs, one is spare (or not yet used).

use static_cell::ConstStaticCell;

use crate::consts::Law;

/// A law in one of the two static buffers.
pub type LawRef = &'static mut Law;

static LAW_A: ConstStaticCell<Law> = ConstStaticCell::new(Law::unconfigured());
static LAW_B: ConstStaticCell<Law> = ConstStaticCell::new(Law::unconfigured());

/// Both law buffers (call once, at boot; `None` afterwards).
pub fn take() -> Option<[LawRef; 2]> {
    Some([LAW_A.try_take()?, LAW_B.try_take()?])
}
