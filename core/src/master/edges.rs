//! The master at the sample instant, below one count, from timestamped encoder edges.
//!
//! A 0.001° encoder at 3 °/s changes its count every 333 µs: read once per 1 ms tick, the
//! count is late by up to one count (12 µm of the tangent axis' target), which is half of
//! the nominal tracking error. The board therefore also timestamps the master encoder's
//! edges: the timer that counts the encoder latches the count at every **rising edge of
//! channel A** (one per encoder line, i.e. every 4 counts of ×4 counting), and a
//! free-running *edge timer* latches its own time at the same instant (on the F407: TIM5's
//! capture 1 → its trigger output → TIM8's capture from TRC, `firmware/src/edge_timer.rs`).
//! Each tick reads the newest capture pair and the edge timer's time now.
//!
//! **Crossings.** The count `n` covers the cell `[n − ½, n + ½)` (an encoder whose count
//! is the rounded position, as the simulator's sensors are). A *crossing* is the master
//! passing a cell boundary at a known time, the way the count went:
//!
//! * a captured rising A edge: the count `c` latched and its time; passed upwards (the
//!   count rose this tick) the boundary is `c − ½`, downwards `c + ½`, for a timer that
//!   latches the count *after* the edge. Whether it latches the count after or before
//!   the edge is learnt from the first capture in a tick whose count stepped by one (the
//!   counts on both sides of that edge are then known); until then, after. An edge in a
//!   tick whose count did not move (it came back) has no known way and restarts the
//!   estimate;
//! * a step of the count by one between two samples, placed in the middle of the tick,
//!   for a slow master — its last crossing at least 8 ticks old (`SLOW_TICKS`): its time
//!   is then within 1/16 of the interval before it (the interval after it, to the next
//!   A edge, can be shorter: at 300 counts/s about 3 ticks, ±15 %) — and at a reversal
//!   (a step against the last crossing). At speed these steps are not used: half a tick
//!   is then a large part of the interval, and the A edges come often enough. A larger
//!   step against the last crossing restarts the estimate.
//!
//! From the last two crossings `(b₀, t₀)`, `(b₁, t₁)` the same way and the sample's time
//! `t`:
//!
//! ```text
//! Δb = b₁ − b₀ (counts; its sign is the way)      θ̇ = Δb / (t₁ − t₀)  counts per tick
//! θ(t) = b₁ + Δb · (t − t₁)/(t₁ − t₀)             counts
//! ```
//!
//! **Where the master can be**: the live count's cell, on the far side of `b₁` (the cell
//! alone after a reversal the crossings did not see). An extrapolation inside it is the
//! estimate; one beyond it (the next crossing has not come: the master slowed) is blended
//! from that edge towards the region's middle, reached when the extrapolation has gone
//! twice the distance from `b₁` to the edge. The result is never outside the live
//! count's cell, so its error is below one count whatever happens (below ½ wherever the
//! crossings are right; a master reversing inside cells measured 0.52 at worst against
//! the count's 0.50).
//!
//! **Fallback** to the middle of where the master can be (the count's centre after a
//! count step, exactly what the board fed before): no edge reading (then everything is
//! forgotten), fewer than two crossings the same way, an interval beyond
//! [`MAX_INTERVAL_TICKS`] or a step beyond [`MAX_STEP_COUNTS`], a crossing more than
//! twice the last interval old (the master stopped) or one in the future.
//!
//! Formats: times are edge-timer ticks in wrapping `u32` (only differences are used,
//! valid up to 2^31 ticks; a 16-bit timer is extended by the encoders' own
//! [`crate::runtime::encoder::Extender16`], its count read as a wrapping `u32`); the fraction `(t − t₁)/(t₁ − t₀)` is Q16 in a `u32` (≤ 2:
//! both times shifted right until the interval has 15 bits, then one 32-bit division,
//! `(t − t₁) << 16` < 2^32); `Δb` is `I48F16` in an `i32` (`|Δb|` ≤ [`MAX_STEP_COUNTS`]
//! < 2^13 counts); the position is [`Master`] (`I48F16` counts), formed relative to the
//! live count so that a wrapping count is followed.

use crate::units::{Counts, Master};

/// Longest accepted interval between two crossings, edge-timer ticks (2^30: 17.9 min at
/// the board's 1 MHz edge timer).
pub const MAX_INTERVAL_TICKS: u32 = 1 << 30;

/// Largest accepted |Δb| between two crossings, counts.
pub const MAX_STEP_COUNTS: i32 = (1 << 13) - 1;

/// Half a count, `I48F16` raw.
const HALF: i64 = 1 << 15;
/// Largest |c₁ − n| (the last crossing's count from the live count) used, counts.
const REL_MAX: i32 = 1 << 13;
/// The smallest distance the late blend divides by, `I48F16` raw (1/64 count).
const MIN_DIST: i64 = 1 << 10;
/// A count step of one is a crossing of its own when the last crossing is at least this
/// many ticks old (a slow master: its mid-tick time is then within 1/16 of the interval).
const SLOW_TICKS: u32 = 8;
/// Minus half a count, `I48F16` raw.
const NEG_HALF: i64 = -HALF;

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

/// One boundary crossing of the master: the count it entered (the boundary is half a
/// count behind it, [`boundary`]), when (edge-timer ticks) and which way (`true`:
/// counting up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Crossing {
    c: i32,
    at: u32,
    up: bool,
}

/// The sub-count estimator's state: the last crossing and, if the last two are usable,
/// their `(Δb, t₁ − t₀)` (worked out once per crossing, not per tick).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeEstimator {
    /// The time of the newest capture seen (a capture reported again is not new).
    capture_at: Option<u32>,
    /// The previous sample's count and time.
    prev: Option<(i32, u32)>,
    last: Option<Crossing>,
    /// Δb (`I48F16` raw, |Δb| < 2^29) and Δt (ticks) of the last two crossings.
    line: Option<(i32, u32)>,
    /// Whether the timer latches the count before the edge (learnt from a capture in a
    /// tick whose count stepped by one; `None`: not yet, taken as after).
    latches_before: Option<bool>,
}

impl EdgeEstimator {
    /// No edge seen.
    pub const START: Self = Self {
        capture_at: None,
        prev: None,
        last: None,
        line: None,
        latches_before: None,
    };

    /// Takes the live count and this sample's edge reading (`None`: the board has no
    /// edge timer, or it did not answer) and returns the master at the sample instant
    /// (see the module docs; the count's cell centre on every fallback).
    #[inline]
    pub fn update(&mut self, count: Counts, reading: Option<&EdgeReading>) -> Master {
        let n = count.0;
        let n_q16 = i64::from(n).wrapping_shl(16);
        let Some(r) = reading else {
            *self = Self::START;
            return Master::from_bits(n_q16);
        };
        let now = r.now_ticks;
        let new = r.edge.filter(|e| self.capture_at != Some(e.at_ticks));
        if let Some(e) = new {
            self.capture_at = Some(e.at_ticks);
        }
        let dn = self.prev.map(|(c, t)| (n.wrapping_sub(c), t));
        let crossing = match (new, dn) {
            // A timed rising A edge, passed the way the count went this tick; with a step
            // of one the count before and after it are known, which tells which of the
            // two the timer latches (learnt once; "after" until then).
            (Some(e), Some((d, _))) if d != 0 => {
                let up = d > 0;
                if d == 1 || d == -1 {
                    if e.count.0 == n {
                        self.latches_before = Some(false);
                    } else if e.count.0 == n.wrapping_sub(d) {
                        self.latches_before = Some(true);
                    }
                }
                let c = if self.latches_before == Some(true) {
                    e.count.0.wrapping_add(if up { 1 } else { -1 })
                } else {
                    e.count.0
                };
                Some(Crossing {
                    c,
                    at: e.at_ticks,
                    up,
                })
            }
            // An edge whose way is unknown (the count came back within the tick, or the
            // first sample): start again.
            (Some(_), _) => {
                self.last = None;
                self.line = None;
                None
            }
            // A count step of one is a crossing too, placed in the middle of the tick,
            // for a slow master (its last crossing at least `SLOW_TICKS` ago) and at a
            // reversal (a step against the last crossing).
            (None, Some((d @ (1 | -1), t_prev))) => {
                let tick = now.wrapping_sub(t_prev);
                let up = d > 0;
                let take = self.last.is_none_or(|c| {
                    c.up != up || now.wrapping_sub(c.at) >= tick.saturating_mul(SLOW_TICKS)
                });
                take.then(|| Crossing {
                    c: n,
                    at: t_prev.wrapping_add(tick >> 1),
                    up,
                })
            }
            // A larger step against the last crossing: a reversal the crossings did not
            // time: start again.
            (None, Some((d, _))) if d != 0 && self.last.is_some_and(|c| c.up != (d > 0)) => {
                self.last = None;
                self.line = None;
                None
            }
            _ => None,
        };
        if let Some(c) = crossing {
            self.line = self.last.and_then(|p| Self::step(&c, &p));
            self.last = Some(c);
        }
        self.prev = Some((n, now));
        Master::from_bits(n_q16.wrapping_add(self.offset_q16(n, now)))
    }

    /// The sub-count offset from the live count `n`'s centre, `I48F16` raw in ±½ count.
    #[inline]
    fn offset_q16(&self, n: i32, now: u32) -> i64 {
        let Some(c) = self.last else {
            return 0;
        };
        // The crossing relative to the live count (wrapping with the counter).
        let rel = c.c.wrapping_sub(n);
        if !(-REL_MAX..=REL_MAX).contains(&rel) {
            return 0;
        }
        let b = boundary(rel, c.up);
        // Where the master can be: its cell, on the far side of the last crossing (the
        // cell alone after a reversal the edges did not see).
        let (lo, hi) = if c.up {
            (b.max(NEG_HALF), HALF)
        } else {
            (NEG_HALF, b.min(HALF))
        };
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (NEG_HALF, HALF) };
        let mid = lo.wrapping_add(hi) >> 1;
        let Some((db, dt)) = self.line else {
            return mid;
        };
        let age = now.wrapping_sub(c.at);
        if age > dt.saturating_mul(2) {
            return mid;
        }
        // Both shifted right until the interval has at most 15 bits (a slow master loses
        // only resolution it does not need): then age ≤ 2^16 − 1 and age << 16 < 2^32.
        let k = 32u32.saturating_sub(dt.leading_zeros()).saturating_sub(15);
        let (age, dt) = (age.wrapping_shr(k), dt.wrapping_shr(k).max(1));
        let frac_q16 = age.wrapping_shl(16).checked_div(dt).unwrap_or(0);
        // |Δb| < 2^29, frac ≤ 2^17: the product below 2^46.
        let x = b.wrapping_add(i64::from(db).wrapping_mul(i64::from(frac_q16)) >> 16);
        // Beyond where it can be (the next crossing has not come: the master slowed):
        // blended from that edge towards the middle, reached when the extrapolation has
        // gone twice the distance.
        let (edge, over, dist) = if c.up {
            (hi, x.saturating_sub(hi), hi.saturating_sub(b))
        } else {
            (lo, lo.saturating_sub(x), b.saturating_sub(lo))
        };
        if over <= 0 {
            return x.clamp(lo, hi);
        }
        let w_q16 = over
            .wrapping_shl(16)
            .checked_div(dist.max(MIN_DIST))
            .unwrap_or(0)
            .min(1 << 16);
        edge.wrapping_add(mid.wrapping_sub(edge).wrapping_mul(w_q16) >> 16)
    }

    /// `(Δb, t₁ − t₀)` of two crossings the same way: Δb of that sign within
    /// ±[`MAX_STEP_COUNTS`], the interval in 1 … [`MAX_INTERVAL_TICKS`].
    fn step(c: &Crossing, p: &Crossing) -> Option<(i32, u32)> {
        // Both boundaries half a count behind their counts, the same way: Δb = Δc.
        let dc = c.c.wrapping_sub(p.c);
        let dt = c.at.wrapping_sub(p.at);
        let ok = c.up == p.up
            && (dc > 0) == c.up
            && dc != 0
            && (-MAX_STEP_COUNTS..=MAX_STEP_COUNTS).contains(&dc)
            && (1..=MAX_INTERVAL_TICKS).contains(&dt);
        ok.then_some((dc.wrapping_shl(16), dt))
    }

    /// The master's speed from the last two crossings, counts/s `I48F16`, for an edge
    /// timer of `timer_hz`: `Δb · f / (t₁ − t₀)`; `None` without two usable crossings.
    /// Off the tick's path (one 64-bit division).
    pub fn speed_counts_per_s(&self, timer_hz: u32) -> Option<crate::units::MasterRate> {
        let (db, dt) = self.line?;
        // |Δb| < 2^29 (Q16), f < 2^32: the numerator is below 2^61.
        let num = i64::from(db).saturating_mul(i64::from(timer_hz));
        num.checked_div(i64::from(dt))
            .map(crate::units::MasterRate::from_bits)
    }
}

/// The boundary a crossing into count `c` marks, `I48F16` raw: `c − ½` counting up,
/// `c + ½` counting down.
#[inline]
fn boundary(c: i32, up: bool) -> i64 {
    i64::from(c)
        .wrapping_shl(16)
        .wrapping_sub(if up { HALF } else { NEG_HALF })
}

#[cfg(test)]
mod tests;
