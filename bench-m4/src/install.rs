//! Table activation as the firmware's critical section pays it (docs/firmware.md):
//! [`Runtime::install`] of the board's law type, `Follower<2, 256>`
//! (`firmware/src/boot_config.rs`), at a safe point (Idle). The tick waits for this once per
//! activation.
//!
//! The firmware runs its law from one of two static buffers (`firmware/src/law_buffers.rs`), so
//! the runtime holds a `&'static mut Law` and the install swaps references; the law was
//! written into the spare buffer before, outside the section. Each call here swaps the
//! two buffers back and forth. (By value — the law moved into the runtime and the old
//! one out — the install would copy the 12.6 KiB law twice inside the section: about a
//! whole 1 ms tick at 168 MHz.)

use crate::harness::Figure;
use crate::runtime::{board_law, board_runtime, BoardRuntime, Law};
use core::hint::black_box;
use static_cell::StaticCell;

/// A law in a static buffer, as the firmware's runtime holds it.
type LawRef = &'static mut Law;

static LAW_A: StaticCell<Law> = StaticCell::new();
static LAW_B: StaticCell<Law> = StaticCell::new();

/// The measured call: the install inside the critical section.
#[inline(never)]
fn install(rt: &mut BoardRuntime, law: LawRef) -> Option<LawRef> {
    rt.install(law).ok().flatten()
}

/// `runtime_install_law`.
pub struct InstallLaw {
    rt: BoardRuntime,
    /// The buffer the next call installs (the one the last call took out).
    spare: Option<LawRef>,
    /// Every install was accepted and gave the old law back.
    ok: bool,
}

impl InstallLaw {
    /// A runtime at rest running the law in one buffer, the other buffer ready.
    pub fn new() -> Option<Self> {
        let running = board_law(&LAW_A)?;
        let next = board_law(&LAW_B)?;
        Some(Self {
            rt: board_runtime(running)?,
            spare: Some(next),
            ok: true,
        })
    }
}

impl Figure for InstallLaw {
    #[inline(always)]
    fn call(&mut self, _k: u32) {
        if let Some(law) = self.spare.take() {
            self.spare = install(&mut self.rt, law);
        }
        self.ok &= self.spare.is_some();
    }

    #[inline(always)]
    fn baseline(&mut self, _k: u32) {
        black_box(&mut self.spare);
    }

    fn healthy(&self) -> bool {
        self.ok
    }
}
