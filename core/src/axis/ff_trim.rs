//! Feed-forward trim: the velocity feed-forward learns the valve's real flow gain from
//! the integrator, per direction, while the axis follows.
//!
//! The feed-forward kv±·v is calibrated on one machine at one supply. A valve that
//! passes 20 % more at a 12 % higher supply (the robustness box's flow ×1.2, 180 bar
//! corner: √(180/160)·1.2 = 1.27) moves the piston 27 % faster than the feed-forward
//! asks; the integrator holds the difference, −21 % of the feed-forward. That is right
//! at one speed only: when the master slows to its stop the feed-forward falls and the
//! integrator must unwind at Ki's rate, so the error grows by its lag (on the mass ×2 /
//! bulk ×0.5 corner at the backoff's deepest level, where Ki is 0.42 of its set value,
//! 30.7 µm at the stop without the trim; with the trim 7.9 µm there).
//! A share of the integrator that is proportional to the speed belongs to the
//! feed-forward.
//!
//! While the axis moves — |ff| ≥ ff_min — each tick moves a share of the integrator's
//! content, in proportion to the speed, into the trim d of the feed-forward's
//! direction, without a bump:
//!
//! ```text
//! ff'  = ff·(1 + d±)              LSB: the law's feed-forward, d± of ff's direction
//! Δd±  = sign(ff)·I·2^−n / ff_ref        ff_ref = 2^round(log2(clamp/4)) LSB (512 of 2 047)
//! d±  ← clamp(d± + Δd±, −0.5, +1)        the ratio 1 + d± within 0.5 … 2
//! I   ← I − (d±_new − d±_old)·ff  what the trim took: ff' + I is unchanged
//! ```
//!
//! (ff the untrimmed feed-forward kv±·v + ka·a.) The integrator so empties with
//! τ·ff_ref/|ff| (τ = 2^n·T ≈ `ff_trim_tau_s`): with τ at |ff| = ff_ref, faster above
//! it, slower below — least where a constant is most of what the
//! integrator holds. Every step is a shift and one product: no division by ff, which
//! would be an `i64` division (`__aeabi_ldivmod`) every tick on the Cortex-M4
//! (docs/bench.md).
//!
//! The integrator keeps what does not scale with speed — a valve null offset, a load, a
//! ratio beyond the clamp. Below ff_min = 1/64 of the valve's clamp (32 LSB of 2 047)
//! the axis is taken to be at rest, and above the clamp (ff_max) the output saturates:
//! there nothing moves. With τ ≥ 16 periods a tick moves at most 5.7/16 of the
//! integrator (|ff|/ff_ref ≤ 4√2), so the transfer never overshoots. The transfer is no feedback of its own: the loop's gains and
//! margins are unchanged, only where the integrator's content lives. The trims are
//! kept through restarts and cleared faults (what the axis learned about its valve
//! stays true) and through a rebuild of the law that keeps the axis' coefficients, and
//! return to 0 when the axis' coefficients change — its gains, valve calibration,
//! damping or the control period; not its limits or areas with the damping off (as the
//! gain backoff's level).
//!
//! It learns from whatever the integrator holds while moving, also a start-up or
//! acceleration lag (the trim's time constant averages those) and, while the integrator
//! is at its clamp, content the clamp would have refused: the trim's own clamp (ratio
//! 0.5 … 2) bounds the integral action it can take on.
//!
//! What it cannot tell apart: a constant the integrator holds *while moving* in one
//! direction (an uncalibrated valve null, a steady load) is taken for a ratio at the
//! speeds it is seen at — calibrate the null first (`valve/null_lsb`); a load that
//! changes the chamber pressures changes the valve's flow gain, which is a ratio.
//!
//! Formats: ff, I `I16F16` LSB raw; d± Q30 (2^30 = +100 %): a step of d moves 2^−30 of
//! the feed-forward, so the integrator empties to within rounding (at Q16 the trim
//! stopped with 2^n·ff/2^16 still in the integrator: 6 LSB at 400 LSB, τ = 1 s).

/// Why the trim cannot be built (reported as the axis' `AxisConfigError::FfTrim`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FfTrimError {
    /// τ is not finite, not 0 and outside 0.01 … 1 000 s, or shorter than 16 periods.
    Range,
    /// A trim on an axis whose law is not `Feedforward` (the baselines have no or the
    /// published feed-forward).
    Law,
}

/// Validated coefficients. `OFF` (all zero): no trim.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FfTrimCoeffs {
    /// n + log2(ff_ref in `I16F16` raw): Δd (Q30) = I·2^30 >> this (0: off).
    shift: u8,
    /// ff_min, `I16F16` LSB raw: below it the axis is taken to be at rest.
    ff_min: i32,
    /// ff_max, `I16F16` LSB raw: the valve's clamp — beyond it the output saturates and
    /// nothing is learnt; it also bounds a tick's transfer to |ff|/ff_ref·2^−n ≤ 5.7/16
    /// of the integrator (no overshoot).
    ff_max: i32,
}

/// The trim's lower bound, Q30: the ratio 0.5.
const D_MIN: i32 = -(1 << 29);
/// The trim's upper bound, Q30: the ratio 2 (2^30 < 2^31).
const D_MAX: i32 = 1 << 30;

impl FfTrimCoeffs {
    /// No trim.
    pub const OFF: Self = Self {
        shift: 0,
        ff_min: 0,
        ff_max: 0,
    };

    /// The trim with time constant `tau_s` (0 = off; else 0.01 … 1 000 s and at least
    /// 16 control periods) at `period_us`, for a valve clamped at `clamp_lsb` (1 … 2 047;
    /// ff_min is 1/64 of it).
    pub fn build(tau_s: f32, period_us: u32, clamp_lsb: u16) -> Result<Self, FfTrimError> {
        if !(tau_s.is_finite() && (tau_s == 0.0 || (0.01..=1000.0).contains(&tau_s))) {
            return Err(FfTrimError::Range);
        }
        if tau_s == 0.0 {
            return Ok(Self::OFF);
        }
        let ticks = f64::from(tau_s) * 1e6 / f64::from(period_us.max(1));
        if ticks < 16.0 {
            return Err(FfTrimError::Range);
        }
        // 16 … 2·10^7 ticks: n = 4 … 24 (τ within 0.71 … 1.41 of the set value).
        let n = libm::round(libm::log2(ticks)).clamp(1.0, 30.0) as u8;
        // ff_ref = 2^round(log2(clamp/4)) LSB, in Q16: 2^14 … 2^25 raw for clamp 1 … 2 047.
        let ff_ref = libm::round(libm::log2(f64::from(clamp_lsb.max(1)) / 4.0)).max(-2.0);
        Ok(Self {
            // n + 16 + log2(ff_ref): 15 … 50, below 64.
            shift: n.saturating_add((16.0 + ff_ref) as u8),
            // ≤ 2 047 LSB / 64 in Q16: below 2^22.
            ff_min: i32::from(clamp_lsb).wrapping_shl(10),
            // ≤ 2 047 · 2^16: below 2^27.
            ff_max: i32::from(clamp_lsb).wrapping_shl(16),
        })
    }

    /// Whether the trim runs.
    #[inline(always)]
    pub fn is_on(&self) -> bool {
        self.shift != 0
    }
}

/// The trims learned, per direction. All zero at reset (a `.bss` law buffer).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FfTrimState {
    /// d for negative and positive feed-forward, Q30 (0: the calibrated gain).
    d_q30: [i32; 2],
}

impl FfTrimState {
    /// Nothing learned.
    pub const RESET: Self = Self { d_q30: [0; 2] };

    /// The ratio learned for feed-forward of the sign `positive`, 1 + d, Q16 (65 536:
    /// the calibrated gain).
    pub fn ratio_q16(&self, positive: bool) -> i32 {
        self.d_q30
            .get(usize::from(positive))
            .map_or(65_536, |d| (d >> 14).saturating_add(65_536))
    }

    /// ff·(1 + d±), `I16F16` LSB raw.
    #[inline(always)]
    pub fn apply(&self, ff: i32) -> i32 {
        let d = self.d_q30.get(usize::from(ff > 0)).copied().unwrap_or(0);
        // |ff| ≤ 2^31, |d| ≤ 2^30: the product is below 2^61; ff·d saturates at ±2^31.
        ff.saturating_add(crate::fixed_point::mul_shr_floor_sat(ff, d, 30))
    }

    /// One tick's transfer from the integrator `integ` (`I16F16` LSB raw) into the trim
    /// of the direction of `ff` (the untrimmed feed-forward, `I16F16` LSB raw); returns
    /// what the integrator gives up (the caller subtracts it). 0 below ff_min and above
    /// ff_max.
    #[inline(always)]
    pub fn offload(&mut self, c: &FfTrimCoeffs, ff: i32, integ: i32) -> i32 {
        let a = ff.saturating_abs();
        // Off: ff_max is 0 (and ff_min ≥ 2^10 when on, so ff = 0 never moves).
        if !c.is_on() || a < c.ff_min || a > c.ff_max {
            return 0;
        }
        let Some(d) = self.d_q30.get_mut(usize::from(ff > 0)) else {
            return 0;
        };
        // Δd = I·2^−n / ff_ref in Q30: |I·2^30| < 2^61, shifted right by 15 … 50.
        let dd = i64::from(integ).wrapping_shl(30) >> c.shift;
        let dd = if ff > 0 { dd } else { dd.wrapping_neg() };
        let new = i64::from(*d)
            .saturating_add(dd)
            .clamp(i64::from(D_MIN), i64::from(D_MAX)) as i32;
        // What the trim took, (new − d)·ff in Q30: |new − d| < 2^31, |ff| ≤ 2^31.
        let took = crate::fixed_point::mul_shr_floor_sat(new.wrapping_sub(*d), ff, 30);
        *d = new;
        took
    }
}

#[cfg(test)]
mod tests;
