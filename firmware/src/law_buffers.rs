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
//! the old buffer becomes the spare. (Moving `Follower<2, 256>` by value inside that
//! section was measured at 119 448 instructions, bench-m4 `runtime_install_law` at
//! 67685ae: ≈ 0.96 ms at 168 MHz, estimated — one whole tick; and building one by value
//! put 50 KB frames on a 64 KB stack, the first-power-up issue.)
//!
//! Exactly two buffers: one runs, one is spare (or not yet used).

use static_cell::ConstStaticCell;

use crate::boot_config::Law;

/// A law in one of the two static buffers.
pub type LawRef = &'static mut Law;

static LAW_A: ConstStaticCell<Law> = ConstStaticCell::new(Law::unconfigured());
static LAW_B: ConstStaticCell<Law> = ConstStaticCell::new(Law::unconfigured());

/// Both law buffers (call once, at boot; `None` afterwards).
pub fn take() -> Option<[LawRef; 2]> {
    Some([LAW_A.try_take()?, LAW_B.try_take()?])
}
