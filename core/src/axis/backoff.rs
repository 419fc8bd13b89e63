//! Gain backoff: the position loop lowers its own proportional gain when it sees itself
//! oscillate.
//!
//! A gain set tuned for a 6 dB margin on the machine it was measured on shakes a machine
//! whose oil column is softer (twice the moving mass on aerated oil halves the hydraulic
//! frequency; docs/results.md, "Robustness"). The oscillation shows in the following error long
//! before a person sees it: a growing sine at the loop's crossover, riding on the slow
//! tracking error. The detector high-passes the error and counts its half-cycles across
//! a band:
//!
//! ```text
//! y(k) = α·(y(k−1) + e(k) − e(k−1)),  α = 1 / (1 + 2π·f_hp·T)    µm, f_hp = 10 Hz
//! a half-cycle: y crosses from above +b to below −b, or back        b = osc_band_um
//! N = 4 half-cycles within W = 150 ms  →  level += 1  (at most 4)
//! ```
//!
//! The first level scales the proportional and derivative terms and the active damping's
//! term to 0.36 of the set gain (an oscillation means no margin is left: −9 dB leaves
//! ≈ 3 dB on a loop that was just unstable), each next one by 0.75 more (0.27, 0.20,
//! 0.15); the feed-forward is kept, and so is the integrator gain at the first level,
//! so a valve-flow error is still integrated out at the set rate. From the second level
//! on the integrator step is scaled too, to min(1, s/0.36) (0.75, 0.56, 0.42): the PI
//! corner Ki/Kp never rises above 2.8× its set value (with Ki kept, the integrator's own
//! ≈ 6 Hz mode shook two soft corners at levels 3 and 4 without damping; measured).
//! (With equal steps of 0.6 the oscillation outgrows the first cut and the detector
//! goes a level too deep on the soft corners.)
//!
//! Counting: the first excursion beyond the band sets its side; each later crossing to
//! the other side counts, and the window opens at the first counted one — so four counted
//! crossings span three half-periods within 150 ms (oscillations from ≈ 10 Hz up).
//! After a backoff the band is raised to the peak |y| of the half-cycles that caused it
//! and decays back towards b with τ = 0.5 s: an oscillation that the lower gain damps
//! stays inside it and takes the gain no further; one that still grows crosses it and
//! takes the next level. For the first 100 ms after a cut the band rides 1.25× above the
//! oscillation (the valve and the oil column carry it on for a cycle or two) and nothing
//! is counted; an oscillation whose half-cycles in that settling's second half each
//! outgrow the last (and every peak before) still grows at the new gain and takes the
//! next level as the settling ends (at periods above 33 ms, fewer than four ticks of
//! settling, this test has no second half and does not act). Without it an oscillation
//! the first cuts do not stop grows for a further 150–250 ms per level to ≈ 150 µm, and
//! the lightly damped oil column rings on from there for a second (the undamped mass ×2
//! / bulk ×0.5 / flow ×1.2 / 180 bar corner).
//!
//! After the settling, while the raised band has not decayed back to b, a **growth
//! watch** runs beside the count: each half-cycle beyond ±b ends when y passes b on the
//! other side; the first after the settling is not judged (partly seen), each side's
//! first whole one is the reference, and three after it in a row on one side, each 1/16
//! above the last, grow at this gain — the next level at once. It catches an
//! oscillation whose settling happened to see a beat (the cut shifts its phase: the
//! second half small, no growth there) and that then grows back from below the raised
//! band: on the same corner, with the feed-forward trim, the levels come at 0.17 / 0.43
//! / 0.53 / 0.86 s, and the ringing the oil column's own damping must then decay starts
//! from ≈ 119 µm: 25.6 µm at 1.5 s, where the error is first counted (`host-sim run` on
//! that machine, `--csv`). Two tones beating rise on one side for half their beat
//! period (2½ periods at 25 and 30 Hz): not enough (a test; judging the partly seen
//! half-cycle, or counting the reference, would take a beating decay three levels
//! down). A decaying oscillation's peaks fall and a steady one's stay within 1/16 (the
//! band's decay takes that one); a tracking swing is one
//! half-cycle. The level is kept through restarts, cleared faults and new runs, and
//! through a rebuild of the law that keeps the axis' coefficients (on a board: a new
//! table, a board-wide or another axis' setting —
//! [`crate::follower::Follower::carry_learned_from`] in `protocol::device`); it returns
//! to 0 when the axis' own coefficients change (a gain set: the engineer's new value
//! starts as set);
//! [`crate::follower::Follower::backoff_level`] reads it (the board's Status carries it
//! per axis; `host-sim status` and `host-sim robust` print it). The integrator's state is
//! untouched: the command does not jump.
//!
//! The slow tracking error of a table corner is a single swing, not four alternating
//! crossings, and the 10 Hz high-pass takes most of it out. Measured with b = 4 µm on the
//! robustness box (`host-sim robust host-sim/scenarios/tangent_damped.toml`,
//! docs/results.md, "Robustness"): the nominal machine and 19 of the 24 others never trigger it, the four
//! mass ×2 / bulk ×0.5 corners end at levels 1, 1, 1 and 3, the stiff-oil mass ×2 corner
//! whose 43 Hz ringing crosses the band at 1, and no machine oscillates.
//!
//! Formats: e, y, b µm `I24F8` raw; α Q31; the level's scale `I16F16` (Q16, ≤ 1).
//!
//! **Settings.** Every threshold above — f_hp, N, W, the settling, τ, the deepest level,
//! the scales 0.36 and 0.75, the band margin 1.25 and the growth watch's 1/16 and three —
//! is the default of a [`BackoffSettings`] field, per axis under `axis/<n>/backoff/…`
//! (the band is `axis/<n>/osc_band_um`); the figures quoted here are those of the
//! defaults. **Beside the law:** the detector sees only the following error's change
//! and hands the law two scales; a level's scales are looked up once, at the cut that
//! reaches it, so the tick multiplies by a stored value.

mod settings;

pub use settings::{BackoffField, BackoffSettings};

use crate::fixed_point::mul_shr_floor_sat;

/// The deepest level the scales can describe (`max_level` ≤ this).
pub const MAX_LEVEL: u8 = 4;

/// Why the backoff cannot be built (reported as the axis' `AxisConfigError::OscBand`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BandError {
    /// The band is not finite or outside 0 … 10 000 µm.
    Range,
    /// A band on an axis whose law is not `Feedforward`: the paper's law and the
    /// traditional one are the baselines and run as published (as the active damping).
    Law,
    /// A threshold of [`BackoffSettings`] out of its range.
    Setting(BackoffField),
}

/// Validated coefficients. `OFF` (all zero): no detector, the law keeps its gains.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BackoffCoeffs {
    /// b, µm, `I24F8` raw (0: off).
    band: i32,
    /// α of the high-pass, Q31.
    alpha_q31: i32,
    /// W in ticks (≥ 1).
    window_ticks: u16,
    /// The settling in ticks (≥ 1).
    settle_ticks: u16,
    /// The raised band decays by 2^-shift per tick (τ = 2^shift·T ≈ `band_tau_ms`).
    decay_shift: u8,
    /// N, the half-cycles that make an oscillation (2 … 16).
    half_cycles: u8,
    /// The deepest level (1 … [`MAX_LEVEL`]).
    max_level: u8,
    /// Growing half-cycles in a row that take the next level (1 … 16).
    growth_half_cycles: u8,
    /// `band_margin` − 1, Q16 (0 … 196 608): the raised band is peak + peak·this.
    margin_q16: i32,
    /// `growth`, Q16 (0 … 65 536).
    growth_q16: i32,
    /// The proportional scale at each level, Q16 (index 0: 65 536).
    scale_q16: [i32; MAX_LEVEL as usize + 1],
    /// The integrator step's scale at each level, Q16: min(1, step_scale^(level − 1)).
    ki_scale_q16: [i32; MAX_LEVEL as usize + 1],
}

impl BackoffCoeffs {
    /// No backoff.
    pub const OFF: Self = Self {
        band: 0,
        alpha_q31: 0,
        window_ticks: 0,
        settle_ticks: 0,
        decay_shift: 0,
        half_cycles: 0,
        max_level: 0,
        growth_half_cycles: 0,
        margin_q16: 0,
        growth_q16: 0,
        scale_q16: [0; MAX_LEVEL as usize + 1],
        ki_scale_q16: [0; MAX_LEVEL as usize + 1],
    };

    /// Builds the detector for band `band_um` (0 = off; 0 … 10 000 µm) with the
    /// thresholds `set` at the control period `period_us` (checked by the caller to be
    /// 50 µs … 1 s). The thresholds are checked even with the band off, so a setting is
    /// refused when it is written, not when the band is later switched on.
    pub fn build(band_um: f32, set: &BackoffSettings, period_us: u32) -> Result<Self, BandError> {
        if !(band_um.is_finite() && (0.0..=10_000.0).contains(&band_um)) {
            return Err(BandError::Range);
        }
        set.check().map_err(BandError::Setting)?;
        if band_um == 0.0 {
            return Ok(Self::OFF);
        }
        let t = f64::from(period_us) * 1e-6;
        let alpha = 1.0 / (1.0 + 2.0 * core::f64::consts::PI * f64::from(set.high_pass_hz) * t);
        // Ticks: at 50 µs … 1 s, 10 s is at most 200 000 ticks, clamped to a u16.
        let ticks =
            |ms: f32| libm::ceil(f64::from(ms) * 1e-3 / t).clamp(1.0, f64::from(u16::MAX)) as u16;
        let q16 = |x: f64| libm::round(x * 65_536.0) as i32;
        let mut scale_q16 = [65_536; MAX_LEVEL as usize + 1];
        let mut ki_scale_q16 = [65_536; MAX_LEVEL as usize + 1];
        let (first, step) = (f64::from(set.first_scale), f64::from(set.step_scale));
        let mut depth = 1.0; // step_scale^(level − 1)
        for (s, k) in scale_q16.iter_mut().zip(ki_scale_q16.iter_mut()).skip(1) {
            // 0.05^4 … 1: 0.4 … 65 536 in Q16, at least 1 LSB.
            *s = q16(first * depth).max(1);
            *k = q16(depth.min(1.0)).max(1);
            depth *= step;
        }
        // Checked integers in range by `check`: the casts are exact.
        Ok(Self {
            // ≤ 10 000 µm · 256: far inside an i32; a band below 1/256 µm is 1 LSB.
            band: (libm::round(f64::from(band_um) * 256.0) as i32).max(1),
            // 0 < α < 1: below 2^31 in Q31.
            alpha_q31: (alpha * 2_147_483_648.0).min(2_147_483_647.0) as i32,
            window_ticks: ticks(set.window_ms),
            settle_ticks: ticks(set.settle_ms),
            // τ/T = 2^shift, rounded (τ within 0.71 … 1.41 of the setting at periods whose
            // τ/T is not a power of two).
            decay_shift: libm::round(libm::log2(f64::from(set.band_tau_ms) * 1e-3 / t))
                .clamp(0.0, 20.0) as u8,
            half_cycles: set.half_cycles as u8,
            max_level: set.max_level as u8,
            growth_half_cycles: set.growth_half_cycles as u8,
            margin_q16: q16(f64::from(set.band_margin) - 1.0),
            growth_q16: q16(f64::from(set.growth)),
            scale_q16,
            ki_scale_q16,
        })
    }

    /// Whether the detector runs.
    #[inline(always)]
    pub fn is_on(&self) -> bool {
        self.band != 0
    }
}

/// The detector's state and the level reached. All zero at reset (a `.bss` law buffer).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BackoffState {
    /// y(k−1), µm `I24F8` raw.
    y: i32,
    /// Ticks left in the counting window (0: none open).
    window: u16,
    /// The raised band after a backoff, µm `I24F8` raw (decays to `band`).
    env: i32,
    /// Peak |y| in the counting window, µm `I24F8` raw.
    peak: i32,
    /// Ticks left of the settling after a backoff.
    settle: u16,
    /// The side of the band y was last beyond: −1, +1, or 0 (none since the reset).
    side: i8,
    /// Half-cycles counted in the window.
    half_cycles: u8,
    /// Backoff level, 0 … [`MAX_LEVEL`].
    level: u8,
    /// The growth watch after a settling: the side of the half-cycle y is in (beyond
    /// ±b; 0: none yet).
    hc_side: i8,
    /// Its peak |y| so far, µm `I24F8` raw.
    hc_peak: i32,
    /// The last finished half-cycle's peak on each side (`[−, +]`), µm `I24F8` raw.
    hc_last: [i32; 2],
    /// How many half-cycles in a row on each side outgrew the one before by 1/16.
    hc_grew: [u8; 2],
    /// Whether the first half-cycle after the settling has ended (it is not judged).
    hc_whole: bool,
    /// The proportional scale of `level`, Q16, set at the cut that reached it (read
    /// only while `level` > 0: the tick multiplies, the lookup happens at the cut; 0
    /// before the first cut, so the reset state stays all zero and a law buffer stays
    /// in `.bss`, not a flash image).
    scale_q16: i32,
    /// The integrator step's scale of `level`, Q16 (as `scale_q16`).
    ki_scale_q16: i32,
}

impl BackoffState {
    /// The reset state (`Default` as a `const`).
    pub const RESET: Self = Self {
        y: 0,
        window: 0,
        env: 0,
        peak: 0,
        settle: 0,
        side: 0,
        half_cycles: 0,
        level: 0,
        hc_side: 0,
        hc_peak: 0,
        hc_last: [0; 2],
        hc_grew: [0; 2],
        hc_whole: false,
        scale_q16: 0,
        ki_scale_q16: 0,
    };

    /// Forgets the detector's history, keeping the level (a restart, a cleared fault).
    pub fn restart(&mut self) {
        *self = Self {
            level: self.level,
            scale_q16: self.scale_q16,
            ki_scale_q16: self.ki_scale_q16,
            ..Self::RESET
        };
    }

    /// The backoff level, 0 (the set gain) … [`MAX_LEVEL`].
    pub fn level(&self) -> u8 {
        self.level
    }

    /// The proportional scale, Q16 (65 536 = the set gain).
    #[inline(always)]
    pub fn scale_q16(&self) -> i32 {
        if self.level == 0 {
            65_536
        } else {
            self.scale_q16
        }
    }

    /// `x` (an integrator step, any Q format) at this level: min(1,
    /// step_scale^(level − 1)) of it.
    #[inline(always)]
    pub fn scale_i(&self, x: i32) -> i32 {
        if self.level == 0 {
            x
        } else {
            mul_shr_floor_sat(x, self.ki_scale_q16, 16)
        }
    }

    /// `x` (a proportional, derivative or damping term, any Q format) at this level.
    #[inline(always)]
    pub fn scale(&self, x: i32) -> i32 {
        if self.level == 0 {
            x
        } else {
            mul_shr_floor_sat(x, self.scale_q16, 16)
        }
    }
}

/// `a` (≥ 0, µm `I24F8` raw) raised by the band margin: a + a·(margin − 1).
#[inline(always)]
fn raised(c: &BackoffCoeffs, a: i32) -> i32 {
    a.saturating_add(mul_shr_floor_sat(a, c.margin_q16, 16))
}

/// One tick of the detector on the following error's change since the last tick,
/// `de` = e(k) − e(k−1) (µm, `I24F8` raw; 0 on the first tick — the position law's own
/// history gives it, [`super::PosState::error_change`]). Returns `true` on the tick it
/// backs off one level.
#[inline(always)]
pub fn observe(c: &BackoffCoeffs, st: &mut BackoffState, de: i32) -> bool {
    // Q8 · Q31 → Q39 >> 31: |α| < 1, so |y| ≤ |y + de| fits an i32.
    st.y = (i64::from(st.y.saturating_add(de)).wrapping_mul(i64::from(c.alpha_q31)) >> 31) as i32;
    if st.settle > 0 {
        // Settling: the band rides 1.25× above the oscillation; nothing is counted. The
        // first half's carry-over raises the bar (`peak`). In the second half an
        // excursion beyond the bar raises it to its own peak; one beyond that on the
        // other side — a half-cycle larger than the last — still grows at this gain
        // (`half_cycles` marks it): the next level when the settling ends. A tracking
        // transient rises on one side, and the high-pass's overshoot of a decaying jump
        // is smaller than the jump: neither is growth.
        st.settle = st.settle.saturating_sub(1);
        let a = st.y.saturating_abs();
        st.env = st.env.max(raised(c, a));
        if st.settle >= c.settle_ticks >> 1 {
            st.peak = st.peak.max(a);
        } else if a > st.peak {
            let side = if st.y > 0 { 1 } else { -1 };
            if st.side != 0 && st.side != side {
                st.half_cycles = 1;
            }
            st.side = side;
            st.peak = a;
        }
        if st.settle > 0 {
            return false;
        }
        st.side = 0;
        let grew = st.half_cycles != 0;
        st.half_cycles = 0;
        if !grew || st.level >= c.max_level {
            return false;
        }
        // The new band above the grown oscillation (`peak`: its last half-cycle).
        return cut(c, st);
    }
    if st.env > c.band {
        st.env = st
            .env
            .saturating_sub(st.env.wrapping_shr(u32::from(c.decay_shift)).max(1));
        if st.level > 0 && st.level < c.max_level && grows(c, st) {
            return cut(c, st);
        }
    }
    let band = st.env.max(c.band);
    let side = if st.y > band {
        1
    } else if st.y < band.wrapping_neg() {
        -1
    } else {
        0
    };
    if st.window > 0 {
        st.window = st.window.saturating_sub(1);
        st.peak = st.peak.max(st.y.saturating_abs());
        if st.window == 0 {
            st.half_cycles = 0;
        }
    }
    if side == 0 || side == st.side {
        return false;
    }
    let crossed = st.side != 0;
    st.side = side;
    if !crossed {
        return false;
    }
    if st.half_cycles == 0 {
        st.window = c.window_ticks;
        st.peak = st.y.saturating_abs();
    }
    st.half_cycles = st.half_cycles.saturating_add(1);
    if st.half_cycles < c.half_cycles || st.level >= c.max_level {
        return false;
    }
    cut(c, st)
}

/// The growth watch while the band is raised after a cut: each half-cycle beyond ±b
/// ends when y passes b on the other side; its peak is compared with the last one on
/// the same side. The first half-cycle after the settling is not judged (partly seen),
/// each side's first whole one is the reference, and three after it in a row, each 1/16
/// above the last, grow at this gain: `true` (four whole half-cycles on one side, 3½
/// periods: two tones beating rise for half their beat period, 2½ periods at 25 and
/// 30 Hz, and do not qualify). A decaying oscillation's peaks fall, a steady one's stay
/// within 1/16 (the band's decay takes it), a tracking swing is one half-cycle. Sets `peak` to the grown half-cycle's when it returns `true`.
#[inline(always)]
fn grows(c: &BackoffCoeffs, st: &mut BackoffState) -> bool {
    let side: i8 = if st.y > c.band {
        1
    } else if st.y < c.band.wrapping_neg() {
        -1
    } else {
        return false;
    };
    let a = st.y.saturating_abs();
    if side == st.hc_side {
        st.hc_peak = st.hc_peak.max(a);
        return false;
    }
    let done = (st.hc_side, st.hc_peak);
    st.hc_side = side;
    st.hc_peak = a;
    if done.0 == 0 {
        return false;
    }
    if !st.hc_whole {
        // The first half-cycle after the settling was partly inside it: not a peak.
        st.hc_whole = true;
        return false;
    }
    let i = usize::from(done.0 > 0);
    let (Some(last), Some(grew)) = (st.hc_last.get_mut(i), st.hc_grew.get_mut(i)) else {
        return false;
    };
    // The side's first whole half-cycle is the reference; each later one that outgrows
    // the last by 1/16 counts, any other starts the count again.
    *grew =
        if *last != 0 && done.1 > last.saturating_add(mul_shr_floor_sat(*last, c.growth_q16, 16)) {
            grew.saturating_add(1)
        } else {
            0
        };
    *last = done.1;
    if *grew < c.growth_half_cycles {
        return false;
    }
    // The new band above the grown half-cycle.
    st.peak = done.1;
    true
}

/// One level down: the band raised 1.25× above the oscillation's peak, the settling
/// started. Returns `true`.
#[inline(always)]
fn cut(c: &BackoffCoeffs, st: &mut BackoffState) -> bool {
    st.level = st.level.saturating_add(1);
    let l = usize::from(st.level);
    st.scale_q16 = c.scale_q16.get(l).copied().unwrap_or(65_536);
    st.ki_scale_q16 = c.ki_scale_q16.get(l).copied().unwrap_or(65_536);
    st.half_cycles = 0;
    st.side = 0;
    st.window = 0;
    st.env = raised(c, st.peak);
    st.settle = c.settle_ticks;
    st.hc_side = 0;
    st.hc_peak = 0;
    st.hc_last = [0; 2];
    st.hc_grew = [0; 2];
    st.hc_whole = false;
    true
}

#[cfg(test)]
mod tests;
