//! Nonlinear PID and cross-coupled contour control (SPEC §D, seed 004).
//!
//! | file | what |
//! |---|---|
//! | [`fhan`] | Han's time-optimal synthesis function on 32-bit words (a0 within 5·10⁻⁶ relative) |
//! | [`td`] | the discrete tracking differentiator |
//! | [`fal`] | the power law with a linear zone |
//! | `term` (private) | one law term `β·fal(e)` fused on 32-bit words (β in the power's exponent, one `smull` in the linear zone) |
//! | [`feedforward`] | velocity feed-forward per axis from the interpolated reference (direction-dependent gain, lead) |
//! | [`npid`] | the single-axis nonlinear PID (TD-I on the reference, TD-II on the measurement) |
//! | [`pid`] | the linear PID of the classic CCC |
//! | [`contour_model`] | C1, C2 and ε for lines and circles, the sign convention |
//! | [`ccc`] | the X–Y cross-coupled controller: independent, model-based, estimator-based |
//! | [`xy_loop`] | one full X–Y period: interpolator + contour estimator + cross-coupled NPID |
//!
//! Every law implements [`ErrorLaw`]: `track` (reference and measurement of an axis) and
//! `regulate` (an error signal, the contour loop). Configuration structs in engineering
//! units are validated once by `build()`, which returns a small `Copy` error naming the
//! bad parameter; the per-tick methods cannot fail, never allocate and use no float.
//!
//! Fixed-point formats of the nonlinear PID (32-bit words except `z1`; the linear PID,
//! the contour model and the feed-forward document theirs):
//!
//! | quantity | unit | format | resolution | range |
//! |---|---|---|---|---|
//! | TD position z1 | µm | Q40 `i64` (high word µm Q8) | 9·10⁻¹³ µm | ±7.86 m (clamped) |
//! | TD input, fhan's x1, y, errors e1, ε | µm | Q8 `i32` ([`PosUm`] bits) | 3.9·10⁻³ µm | ±8.4 m (saturating) |
//! | TD velocity z2, fhan's x2 and a, e2 | µm/s | Q8 `i32` | 3.9·10⁻³ µm/s | ±2²² µm/s = ±4.2 m/s (z2 clamped) |
//! | `fhan` (public form) | µm/s² | Q8 `i64` | 3.9·10⁻³ µm/s² | ±r ≤ 10⁹ µm/s² |
//! | d = r·h0, d0 = r·h0² | µm/s, µm | Q8 `i32` | 3.9·10⁻³ | d 100 µm/s … 2²¹ µm/s, d0 ≥ 2 µm |
//! | integral e0 | µm·s | Q16 `i32` | 1.5·10⁻⁵ µm·s | ±integral limit ≤ 32 767 µm·s |
//! | h, h0 | s | Q32 `i32` | 2.3·10⁻¹⁰ s | h 10 µs … 10 ms, h0 10 µs … 0.1 s |
//! | β | LSB per unit^α | `f64` at build → a slope mantissa/shift and a Q24 `log2 β` | 6·10⁻⁸ relative | 0 … 10⁶ |
//! | α | 1 | Q16 | 1.5·10⁻⁵ | 0 … 2 |
//! | each term β·fal, u | DAC LSB | Q16 `i32` | 1.5·10⁻⁵ LSB | term ±2¹⁵ (saturated), u ±2047 |
//! | sin θ, cos θ, C1, C2 | 1 | Q30 | 9.3·10⁻¹⁰ | ±2³³ |
//! | κ | 1/µm | Q48 | 3.6·10⁻¹⁵ 1/µm | ±0.1 (R ≥ 10 µm) |
//! | outputs | DAC LSB | [`CmdLsb`] (I16F16) | 1.5·10⁻⁵ LSB | ±2047 |

pub mod ccc;
pub mod contour_model;
pub mod fal;
mod fal_term;
pub mod feedforward;
pub mod fhan;
#[allow(clippy::module_inception)]
pub mod npid;
pub mod pid;
pub mod td;
pub mod xy_loop;

pub use ccc::{Ccc, Cnp, CrossCoupled, XyCoeffs, XyOutput};
pub use contour_model::{contour_model, ContourModel, PathFrame};
pub use fal::{fal, FalCoeffs, FalConfig};
pub use feedforward::{FfError, VelocityFf, VelocityFfCoeffs, VelocityFfConfig};
pub use fhan::{fhan, FhanCoeffs, FhanConfig, V_MAX_UM_PER_S};
pub use npid::{Npid, NpidCoeffs, NpidConfig};
pub use pid::{Pid, PidCoeffs, PidConfig};
pub use td::{Td, TdCoeffs, TdConfig};
pub use xy_loop::{EstimatedXy, XyPeriod};

use hydra_core::units::{CmdLsb, PosUm};

/// A control law on one error channel.
pub trait ErrorLaw {
    /// Its validated coefficients.
    type Coeffs;
    /// One period of axis tracking: `reference_um` and `measured_um` in µm.
    fn track(&mut self, c: &Self::Coeffs, reference_um: PosUm, measured_um: PosUm) -> CmdLsb;
    /// One period on an error signal (the contour error), µm.
    fn regulate(&mut self, c: &Self::Coeffs, error_um: PosUm) -> CmdLsb;
    /// Back to rest at `position_um` (µm; the error channel rests at 0).
    fn reset(&mut self, position_um: PosUm);
}

/// Why a tracking differentiator's parameters were rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TdError {
    /// Speed factor r outside 10³ … 10⁹ µm/s² or not finite.
    SpeedFactor,
    /// Filter factor h0 outside 10 µs … 0.1 s or not finite.
    FilterFactor,
    /// Step h outside 10 µs … 10 ms or not finite.
    Step,
    /// h0 below the step h.
    FilterBelowStep,
    /// d = r·h0 outside 100 µm/s … 2²¹ µm/s (2.1 m/s), or d0 = r·h0² below 2 µm.
    Boundary,
}

/// Why a `fal` parameter was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FalError {
    /// α outside 0 … 2 or not finite.
    Alpha,
    /// δ outside 2⁻¹⁰ … 2¹⁵ or not finite.
    Delta,
}

/// Why a PID (linear or nonlinear) configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NpidError {
    /// TD-I (reference) parameters.
    TdReference(TdError),
    /// TD-II (measurement) parameters.
    TdMeasurement(TdError),
    /// The `fal` of term 0 (integral), 1 (proportional) or 2 (derivative).
    Fal(u8, FalError),
    /// The gain of term 0 (integral), 1 (proportional) or 2 (derivative) out of range.
    Gain(u8),
    /// Control period outside 10 µs … 10 ms.
    Period,
    /// Derivative filter time constant outside 0 … 1 s.
    DerivativeFilter,
    /// Integral limit out of range (NPID: 0 … 32 767 µm·s).
    IntegralLimit,
    /// Output limit outside 1 … 2047 LSB.
    OutputLimit,
}

impl core::error::Error for NpidError {}

impl core::fmt::Display for NpidError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "invalid PID parameter: {self:?}")
    }
}

/// A position (µm, I24F8) as µm Q16.
#[inline(always)]
pub(crate) fn q16_from_pos(p: PosUm) -> i64 {
    i64::from(p.to_bits()).wrapping_shl(8)
}

/// LSB Q16 to [`CmdLsb`], saturated to its range.
#[inline(always)]
pub(crate) fn cmd_from_q16(u: i64) -> CmdLsb {
    CmdLsb::from_bits(u.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
}
