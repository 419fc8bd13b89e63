//! The tick-by-tick stream of a profile's samples, monotone by construction.
//!
//! [`Profile::position_at`] is a pure function of the tick. Its rounding error can, in
//! principle, make two neighbouring samples step back by one LSB where the exact
//! increment per tick is below about 2^-10 LSB (phase joins of extremely slow moves).
//! The cursor removes that case with `s(k) = max(s(k − 1), position_at(k))`. This never
//! moves a sample farther from the exact profile x: if `s(k−1) > position_at(k)` then
//! `x(k) − e ≤ position_at(k) < s(k−1) ≤ x(k−1) + e ≤ x(k) + e` (x is non-decreasing),
//! so the error bound e of [`Profile::position_at`] still holds.

use super::profile::Profile;

/// The next-tick state of a move being executed (the tick index and the last sample).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Cursor {
    k: u32,
    last_lsb: i64,
}

impl Cursor {
    /// A cursor at tick 0.
    pub const fn new() -> Self {
        Cursor { k: 0, last_lsb: 0 }
    }

    /// The tick the next call of [`Cursor::next`] samples.
    pub fn tick(&self) -> u32 {
        self.k
    }

    /// `true` once the target sample has been produced.
    pub fn done(&self, profile: &Profile) -> bool {
        self.k > profile.end_tick()
    }

    /// The sample of the current tick (LSB, non-decreasing from call to call), then
    /// advances one tick. After the last tick it keeps returning D.
    #[inline]
    pub fn next(&mut self, profile: &Profile) -> i64 {
        let s = profile.position_at(self.k).max(self.last_lsb);
        self.last_lsb = s;
        if self.k <= profile.end_tick() {
            self.k = self.k.saturating_add(1);
        }
        s
    }
}
