//! Time-optimal jerk-limited 7-phase moves (SPEC §B), sampled at the control period.
//!
//! * [`Plan`] (`plan.rs`): the time-optimal rest-to-rest profile for limits V, A, J in
//!   `f64`, once per move, outside the control loop; the four [`Regime`]s.
//! * [`Profile`] (`profile.rs`): the plan in fixed point; [`Profile::position_at`] is the
//!   per-period sample: the closed form of the current phase evaluated from its start
//!   (no accumulation), within 0.5 + 2^-8 LSB of the exact profile, exactly the target
//!   from the last tick on. [`Cursor`] (`cursor.rs`) streams it tick by tick, monotone.
//! * [`LineMove`] (`line.rs`): a straight line in N axes; the limits apply to the path,
//!   the leader (largest |Δ|) follows the profile and every axis i follows the leader
//!   with γ_i = Δ_i/Δ_leader (exact rational, rounded once), so all axes start and stop
//!   together and stay within ½ LSB of the line.
//! * [`CountsOut`] (`counts.rs`): per-axis output in encoder counts, the rounding
//!   remainder carried from period to period so it never accumulates.
//! * [`ScurveMaster`] (`master.rs`): a planned move as a time-based master variable
//!   ([`crate::units::Master`] per tick) to run a cam table against.
//!
//! Position unit: a profile works in the LSB of the caller's position format, D ≤
//! [`MAX_DISTANCE_LSB`] = 2^40 LSB. For axes that is `PosUm` raw (1/256 µm: the line
//! is bounded by `PosUm`'s ±8.39 m), for a master `Master` raw (2^-16 count: up to
//! 2^24 = 16.7 M counts per move). Bad input is a typed [`ScurveError`]; a zero-length
//! move is the valid empty move.

mod counts;
mod cursor;
mod line;
mod master;
mod plan;
mod profile;
#[cfg(test)]
mod proptests;

pub use counts::{CountsError, CountsOut, CountsScale};
pub use cursor::Cursor;
pub use line::{LineMove, PathLimits};
pub use master::{MasterLimits, MasterMove, ScurveMaster};
pub use plan::{Limits, Plan, Regime, MAX_LIMIT};
pub use profile::{Profile, Sample, MAX_PERIOD_S, POS_FRAC_BITS};

/// Longest move, in LSB of the position format (2^40: keeps every Q.14 coefficient of
/// the evaluator below 2^60).
pub const MAX_DISTANCE_LSB: u64 = 1 << 40;

/// Why a move cannot be planned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScurveError {
    /// The velocity limit is not finite, not positive, or above [`MAX_LIMIT`].
    Velocity,
    /// The acceleration limit is not finite, not positive, or above [`MAX_LIMIT`].
    Acceleration,
    /// The jerk limit is not finite, not positive, or above [`MAX_LIMIT`].
    Jerk,
    /// The control period is not finite, not positive, or above [`MAX_PERIOD_S`].
    Period,
    /// The distance exceeds [`MAX_DISTANCE_LSB`] (or a line's end is not representable).
    DistanceTooLong,
    /// The move lasts 2^32 − 2 control periods or more.
    DurationTooLong,
}

impl core::fmt::Display for ScurveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ScurveError::Velocity => "velocity limit must be finite, > 0 and ≤ 1e18 LSB/s",
            ScurveError::Acceleration => "acceleration limit must be finite, > 0 and ≤ 1e18 LSB/s²",
            ScurveError::Jerk => "jerk limit must be finite, > 0 and ≤ 1e18 LSB/s³",
            ScurveError::Period => "control period must be finite, > 0 and ≤ 3600 s",
            ScurveError::DistanceTooLong => "move too long for the position format (2^40 LSB)",
            ScurveError::DurationTooLong => "move lasts 2^32 − 2 control periods or more",
        })
    }
}

impl core::error::Error for ScurveError {}
