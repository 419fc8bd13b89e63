//! The master at the sample instant, below one count, from timestamped encoder edges.
//!
//! A 0.001° encoder at 3 °/s changes its count every 333 µs: read once per 1 ms tick, the
//! count is late by up to one count (12 µm of the tangent axis' target), which is half of
//! the nominal tracking error. The board therefore also timestamps the master encoder's
//! edges: the timer that counts the encoder latches the count at every **rising edge of
//! channel A** (one per encoder line, i.e. every 4 counts of ×4 counting), and a
//! free-running *edge timer* latches its own time at the same instant (on the F407: TIM5's
//! capture 1 → its trigger output → TIM8's capture from TRC, `firmware/src/encoders.rs`).
//! Each tick reads the newest capture pair and the edge timer's time now.
//!
//! From the last two captured edges `(c₀, t₀)` and `(c₁, t₁)` (counts and edge-timer
//! ticks) and the time `t` of the sample:
//!
//! ```text
//! Δc = c₁ − c₀ (a nonzero multiple of 4: both are edges of one kind, passed the same way)
//! b₁ = c₁ − ½·sign(Δc)                      the cell boundary the edge marks, counts
//! θ(t) = b₁ + Δc · min(1, (t − t₁)/(t₁ − t₀))   counts, clamped to where it can be
//! θ̇   = Δc / (t₁ − t₀)                           counts per edge-timer tick
//! ```
//!
//! The count `n` covers the cell `[n − ½, n + ½)` (an encoder whose count is the rounded
//! position, as the simulator's sensors are), so the rising A edge entered while counting
//! up is the boundary `c − ½` below the latched count `c` (the count *after* the edge),
//! and the one entered counting down the boundary `c + ½`. The estimate is clamped to
//! where the master can be: the live count's cell, short of the next rising A edge (one
//! line past `b₁`) — never worse than the count itself.
//!
//! **A slowing master.** When the next edge is late (`t − t₁ > t₁ − t₀`), the estimate is
//! blended linearly from that clamped extrapolation towards the middle of where the
//! master can be, reached when the edge is twice as late; then the count.
//!
//! **Fallback to the count** (the cell's centre, exactly what the board fed before): no
//! edge reading, fewer than two edges, a reversal between them (`Δc` not a nonzero
//! multiple of 4), an interval beyond [`MAX_INTERVAL_TICKS`], an edge overdue
//! (`t − t₁ > 2·(t₁ − t₀)`: the master has slowed to half speed or stopped) or an edge
//! time in the future.
//!
//! Formats: times are edge-timer ticks in wrapping `u32` (only differences are used,
//! valid up to 2^31 ticks); the fraction `(t − t₁)/(t₁ − t₀)` is Q16 in a `u32` (≤ 2:
//! both times shifted right until the interval has 15 bits, then one 32-bit division,
//! `(t − t₁) << 16` < 2^32); the position is [`Master`] (`I48F16` counts), formed
//! relative to the live count so that a wrapping count is followed; `|Δc|` ≤
//! [`MAX_STEP_COUNTS`], so `Δc · fraction` < 2^31.

use crate::units::{Counts, Master};

/// Longest accepted interval between the two edges, edge-timer ticks (2^30: 17.9 min at
/// the board's 1 MHz edge timer).
pub const MAX_INTERVAL_TICKS: u32 = 1 << 30;

/// Largest accepted |Δc| between two captured edges, counts.
pub const MAX_STEP_COUNTS: i32 = (1 << 13) - 1;

/// Half a count, `I48F16` raw.
const HALF: i32 = 1 << 15;
/// Largest |c₁ − n| (the last edge's count from the live count) used, counts.
const REL_MAX: i32 = 1 << 13;
/// Minus half a count, `I48F16` raw.
const NEG_HALF: i32 = -HALF;
/// One encoder line (4 counts: the spacing of the rising A edges), `I48F16` raw.
const LINE: i32 = 4 << 16;
/// Minus one line, `I48F16` raw.
const NEG_LINE: i32 = -LINE;

/// One capture: the master count latched at a rising edge of channel A and the edge
/// timer's time of that edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeCapture {
    /// The edge's time, edge-timer ticks (wrapping).
    pub at_ticks: u32,
    /// The master count latched at the edge (the count after it), as the master channel
    /// reads (before `master_invert`).
    pub count: Counts,
}

/// The edge timer read with the master count at the sample instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeReading {
    /// The edge timer's time at the sample, ticks (wrapping).
    pub now_ticks: u32,
    /// The newest edge captured since the previous reading, if any.
    pub edge: Option<EdgeCapture>,
}

/// The sub-count estimator's state: the last captured edge and, if the two last edges are
/// usable, their `(Δc, t₁ − t₀)` (worked out once per edge, not per tick).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeEstimator {
    last: Option<EdgeCapture>,
    line: Option<(i32, u32)>,
}

impl EdgeEstimator {
    /// No edge seen.
    pub const START: Self = Self {
        last: None,
        line: None,
    };

    /// Takes the live count and this sample's edge reading (`None`: the board has no
    /// edge timer, or it did not answer) and returns the master at the sample instant
    /// (see the module docs; the count's cell centre on every fallback).
    #[inline]
    pub fn update(&mut self, count: Counts, reading: Option<&EdgeReading>) -> Master {
        let n = i64::from(count.0).wrapping_shl(16);
        let Some(r) = reading else {
            *self = Self::START;
            return Master::from_bits(n);
        };
        if let Some(e) = r.edge {
            if self.last.map(|l| l.at_ticks) != Some(e.at_ticks) {
                self.line = self.last.and_then(|p| Self::step(&e, &p));
                self.last = Some(e);
            }
        }
        Master::from_bits(n.wrapping_add(self.offset_q16(count, r.now_ticks)))
    }

    /// The sub-count offset from the live count's centre, `I48F16` raw in ±½ count (0 on
    /// a fallback).
    #[inline]
    fn offset_q16(&self, count: Counts, now: u32) -> i64 {
        let (Some(l), Some((dc, interval))) = (self.last, self.line) else {
            return 0;
        };
        let age = now.wrapping_sub(l.at_ticks);
        // The last edge's count within ±2^13 of the live count (else a torn reading).
        let rel_count = l.count.0.wrapping_sub(count.0);
        if age > interval.saturating_mul(2) || !(-REL_MAX..=REL_MAX).contains(&rel_count) {
            return 0;
        }
        // Both shifted right until the interval has at most 15 bits (a slow master loses
        // only resolution it does not need): then age ≤ 2^16 − 1 and age << 16 < 2^32.
        let k = 32u32.saturating_sub(interval.leading_zeros()).saturating_sub(15);
        let (age, interval) = (age.wrapping_shr(k), interval.wrapping_shr(k).max(1));
        let frac_q16 = age.wrapping_shl(16).checked_div(interval).unwrap_or(0);
        // In Q16 counts relative to the live count: every value below 2^30 in magnitude
        // (|rel_count| ≤ 2^13, |Δc| < 2^13, the fraction capped at 1).
        let up = dc > 0;
        let boundary = rel_count
            .wrapping_shl(16)
            .wrapping_sub(if up { HALF } else { NEG_HALF });
        // Where the master can be: its cell, and short of the next rising A edge (one line,
        // 4 counts, past the last). Empty after a reversal the edges did not see: the cell.
        let next = boundary.wrapping_add(if up { LINE } else { NEG_LINE });
        let (lo, hi) = if up { (boundary, next) } else { (next, boundary) };
        let (lo, hi) = match (lo.max(NEG_HALF), hi.min(HALF)) {
            (lo, hi) if lo <= hi => (lo, hi),
            _ => (NEG_HALF, HALF),
        };
        let frac1 = frac_q16.min(1 << 16) as i32;
        let at = boundary.wrapping_add(dc.wrapping_mul(frac1)).clamp(lo, hi);
        // Overdue (t − t₁ > t₁ − t₀: the master has slowed): blended towards the middle
        // of where it can be, reached when the edge is twice as late (then the count).
        let late_q16 = frac_q16.saturating_sub(1 << 16).min(1 << 16);
        let pos = if late_q16 == 0 {
            at
        } else {
            let mid = lo.wrapping_add(hi) >> 1;
            // |mid − at| ≤ 2^16, late ≤ 2^16: the product in i64.
            let pull = i64::from(mid.wrapping_sub(at)).wrapping_mul(i64::from(late_q16)) >> 16;
            at.wrapping_add(pull as i32)
        };
        i64::from(pos)
    }

    /// `(Δc, t₁ − t₀)` of two usable edges: Δc a nonzero multiple of 4 within
    /// ±[`MAX_STEP_COUNTS`], the interval in 1 … [`MAX_INTERVAL_TICKS`].
    fn step(l: &EdgeCapture, p: &EdgeCapture) -> Option<(i32, u32)> {
        let dc = l.count.0.wrapping_sub(p.count.0);
        let interval = l.at_ticks.wrapping_sub(p.at_ticks);
        let ok = dc != 0
            && dc & 3 == 0
            && (-MAX_STEP_COUNTS..=MAX_STEP_COUNTS).contains(&dc)
            && (1..=MAX_INTERVAL_TICKS).contains(&interval);
        ok.then_some((dc, interval))
    }

    /// The master's speed from the last two edges, counts/s `I48F16`, for an edge timer
    /// of `timer_hz`: `Δc · f / (t₁ − t₀)`; `None` on a fallback of the position (no two
    /// usable edges). Off the tick's path (one 64-bit division).
    pub fn speed_counts_per_s(&self, timer_hz: u32) -> Option<crate::units::MasterRate> {
        let (dc, interval) = self.line?;
        // |Δc| < 2^13, f < 2^32, 2^16: the numerator is below 2^61.
        let num = i64::from(dc)
            .saturating_mul(i64::from(timer_hz))
            .saturating_mul(1 << 16);
        num.checked_div(i64::from(interval))
            .map(crate::units::MasterRate::from_bits)
    }

    /// Forgets every edge (the next two captures start the estimate again).
    pub fn reset(&mut self) {
        *self = Self::START;
    }
}

/// Extends a 16-bit edge timer to the wrapping `u32` time the estimator takes: the
/// timer is read every tick (its wrap must be longer than a period), a capture since the
/// last reading is placed before it.
///
/// ```text
/// now32(k) = now32(k−1) + (raw(k) − raw(k−1)) mod 2^16
/// at32     = now32(k) − (raw(k) − capture) mod 2^16
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeClock16 {
    last_raw: u16,
    now: u32,
}

impl EdgeClock16 {
    /// A clock at 0 for the raw reading `raw`.
    pub const fn new(raw: u16) -> Self {
        Self {
            last_raw: raw,
            now: 0,
        }
    }

    /// Takes the timer's reading now and returns the extended time.
    #[inline]
    pub fn update(&mut self, raw: u16) -> u32 {
        self.now = self
            .now
            .wrapping_add(u32::from(raw.wrapping_sub(self.last_raw)));
        self.last_raw = raw;
        self.now
    }

    /// The extended time of a capture taken at most 2^16 − 1 ticks before the last
    /// reading.
    #[inline]
    pub const fn past(&self, capture: u16) -> u32 {
        self.now
            .wrapping_sub(self.last_raw.wrapping_sub(capture) as u32)
    }
}

#[cfg(test)]
mod tests;
