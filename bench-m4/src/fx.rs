//! The crate's one square root, `hydra_core::fixed_point::sqrt_u64` (table + one Newton step,
//! one 32-bit division), on a 64-bit LCG shifted right by 0…15 bits (magnitudes 2^48 …
//! 2^64: the fhan and contour ranges). On these inputs it is the cheaper of the two
//! forms the crate could use; the other is √x = x·(1/√x) by three Newton steps of the
//! reciprocal square root, no division (docs/bench.md, "Design choices").

use crate::harness::Figure;
use core::hint::black_box;

#[inline(always)]
fn input(k: u32) -> u64 {
    let x = u64::from(k)
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    (x >> (k & 15)) | 1
}

/// Not inlined, so the profile run attributes the square root to the figure.
#[inline(never)]
fn sqrt(x: u64) -> (u32, u32) {
    hydra_core::fixed_point::sqrt_u64(x)
}

/// `fixed_point::sqrt_u64`.
pub struct Sqrt {
    x: u64,
    out: (u32, u32),
}

impl Sqrt {
    pub fn new() -> Option<Self> {
        Some(Self { x: 1, out: (0, 0) })
    }
}

impl Figure for Sqrt {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.x = input(k);
        self.out = sqrt(black_box(self.x));
        black_box(&mut self.out);
    }
    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.x = input(k);
        black_box(self.x);
        black_box(&mut self.out);
    }
    /// Stateless.
    fn profile_warm_up(&self) -> u32 {
        0
    }
}
