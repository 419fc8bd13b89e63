//! Table activation as the firmware's critical section pays it (docs/firmware.md):
//! [`Runtime::install`] of the board's law type, `Follower<2, 256>`
//! (`firmware/src/program.rs`), at a safe point (Idle). The tick waits for this once per
//! activation. Each call swaps two laws built on the reference table: the new law moved
//! in, the old one moved out and kept for the next call (the firmware drops the old one
//! instead, so this is the slightly larger case: one more copy of the law).

use crate::follower::{axis, table, NODES};
use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::axis::ControlMode;
use hydra_core::follower::{Follower, FollowerConfig};
use hydra_core::runtime::{BootCause, Runtime, RuntimeConfig};

/// The firmware's law: two slave axes, 256 table nodes.
type Law = Follower<2, NODES>;
/// The firmware's pressure channels (`firmware/src/board.rs`).
const PRESSURES: usize = 4;

/// The measured call: the install inside the critical section.
#[inline(never)]
fn install(rt: &mut Runtime<Law, 2, PRESSURES>, law: Law) -> Option<Law> {
    rt.install(law).ok().flatten()
}

/// `runtime_install_law`.
pub struct InstallLaw {
    rt: Runtime<Law, 2, PRESSURES>,
    /// The law the next call installs (the one the last call took out).
    spare: Option<Law>,
    /// Every install was accepted and gave the old law back.
    ok: bool,
}

impl InstallLaw {
    /// A runtime at rest with one law and a second law ready.
    pub fn new() -> Option<Self> {
        let cfg = FollowerConfig {
            axes: [axis(ControlMode::Feedforward); 2],
            ..FollowerConfig::default()
        };
        let running = Follower::new(&cfg, table::<2>()?).ok()?;
        let next = Follower::new(&cfg, table::<2>()?).ok()?;
        let coeffs = RuntimeConfig::<2>::default().build().ok()?;
        Some(Self {
            rt: Runtime::new(coeffs, Some(running), BootCause::Normal),
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

    /// Nothing settles; each traced call copies ≈ 40 KiB (QEMU logs every instruction).
    fn profile_warm_up(&self) -> u32 {
        2
    }
}
