//! Real-time adaptive contour-error estimation (SPEC §C, seed 003), in fixed point.
//!
//! The contour error is the shortest distance from the actual tool point P to the desired
//! path — not the distance to the current reference point. The method:
//!
//! 1. **Parametric interpolation** ([`Interpolator`]): each servo period the path
//!    parameter u advances by the 2nd-order Taylor step for an arc length ΔS = v·Ts;
//!    r(u) is the **ordinary point** (the motion command). Between two ordinary points
//!    h = ⌊Q·κ·v⌋ (capped) **extra points** are placed by the same step with ΔS/(h + 1),
//!    into a fixed-capacity [`ContourWindow`]; they are never motion commands.
//! 2. **Estimation** ([`ContourWindow::estimate`]): the nearest ordinary point, the
//!    segment on P's side of its normal, bisection over that segment's extra points, the
//!    distance to the final short chord, its foot point, signed by the path normal.
//! 3. **Baselines** ([`ContourWindow::estimate_tangent`], [`ContourWindow::estimate_chord`]):
//!    the tangent line at the reference point and the polyline of the ordinary points.
//!
//! Paths implement [`ParametricPath`] (position, r′, r″ at u); built in: [`Line`],
//! [`Arc`], [`Parabola`], each validated once by its `…Spec::build`.
//!
//! # Sign convention
//!
//! **ε > 0 when P lies to the right of the path's direction of travel** (ε = (P − F)·N
//! with N the right-hand normal, the tangent turned −90°). This is SPEC §D's convention:
//! for a line ε = −sin θ·E1 + cos θ·E2 with E = V − P (tested), so a cross-coupled
//! controller correcting along the left normal (−C1, C2) uses ε as is. Inside a
//! counter-clockwise circle ε < 0.
//!
//! # Formats
//!
//! | quantity | type | unit | resolution | range |
//! |---|---|---|---|---|
//! | path parameter u | [`Param`] = `I32F32` | path unit (µm for the built-in paths) | 2.3·10⁻¹⁰ | ±2.1·10⁹ |
//! | point on the path, window point, foot | [`PosFine`] = `I52F12` | µm | 0.244 nm | ±2.2·10⁹ m (paths validated to ±8.388 m) |
//! | actual point P (input) | [`hydra_core::units::PosUm`] = `I24F8` | µm | 3.9 nm | ±8.39 m |
//! | relative vectors (extra points, chords, P − S), contour error ε | [`RelUm`] = `I20F12` | µm | 0.244 nm | ±524 mm (saturated at ±262 mm) |
//! | r′, r″ | [`Deriv`] = `I32F32` | µm per unit of u (of u²) | 2.3·10⁻¹⁰ | ±2.1·10⁹ |
//! | unit tangent / normal | [`UnitQ30`] = `I2F30` | 1 | 9.3·10⁻¹⁰ | ±2 |
//! | sin, cos | `i64` Q2.62 | 1 | 2.2·10⁻¹⁹ (error < 10⁻¹⁵) | ±2 |
//! | angle | `u32` Q0.32 | turn | 2^-32 turn = 1.46·10⁻⁹ rad | one turn, wrapping |
//! | curvature κ (interpolator) | `i64` Q32.32 | 1/µm | 2.3·10⁻¹⁰ /µm | ±2.1·10⁹ |
//! | feed v | [`hydra_core::units::VelUmPerS`] = `I24F8` | µm/s | 3.9 nm/s | 0 … 8.39 m/s |
//! | period Ts | `i64` Q24.40 | s | 9·10⁻¹³ s | 10 µs … 1 s |
//! | Q | `i64` Q16.16 | s | 15 µs | 0 … 1000 s |
//! | advance per period ΔS | `i64` Q32.32 | µm | 2.3·10⁻¹⁰ µm | 0 … 65 536 µm |
//!
//! Why 12 fractional bits for positions: the target accuracy is 0.1 µm and the extra
//! chords' sagitta is ~1–10 nm, so the points themselves must be ten times finer than
//! that; `I24F8` (3.9 nm) would dominate the error at low speed. Relative vectors are
//! `i32`, so the estimator's products are `i32×i32→i64` (one `smull` on a Cortex-M4);
//! the interpolator's and the parabola's products are split into 32-bit products while
//! their operands are in the usual ranges (|x_l| < 65.5 mm, r″ and the Taylor terms below
//! 2^31), with the exact `i128` form beyond (the arc's sin/cos still use it).
//! Rounding: a point of a built-in path is within 0.4 nm of the exact path, a distance
//! is rounded to 0.24 nm: on a straight line every method matches the exact distance to
//! 0.2 nm (measured, `tests/tests/contour_estimate.rs`).
//!
//! # Per-tick use (no allocation, no float, no panic)
//!
//! ```
//! use hydra_xy::contour::{DefaultWindow, InterpConfig, Interpolator, ParabolaSpec, Xy};
//! use hydra_core::units::{PosUm, VelUmPerS};
//!
//! let path = ParabolaSpec { vertex_um: [0.0, 0.0], p_um: 10_000.0, axis_deg: 0.0,
//!                           x_start_um: -20_000.0, x_end_um: 20_000.0 }.build().unwrap();
//! let coeffs = InterpConfig { period_us: 1000, q_s: 1.0, h_max: 63 }.build().unwrap();
//! let mut window = DefaultWindow::new();           // 8.5 KiB: keep it in a static
//! let mut interp = Interpolator::start(&path, &mut window);
//! // every period:
//! let reference = interp.step(&coeffs, &path, VelUmPerS::from_num(200_000), &mut window);
//! let command: Xy<PosUm> = reference.pos_um();     // to the axes
//! let actual = Xy::new(PosUm::from_num(-19_950.0), PosUm::from_num(19_900.0));
//! let est = window.estimate(actual).unwrap();      // ε, foot, tangent, u_foot
//! // Exact: 0.056 µm, right of travel; the error is at most the sagitta of the one extra
//! // chord here (h = 1 near x = −20 mm at 200 mm/s): 0.011 µm.
//! assert!((est.eps_um.to_num::<f64>() - 0.056).abs() < 0.011);
//! ```
//!
//! Worst-case work: [`Interpolator::step`] 1 + h path evaluations and Taylor steps
//! (h ≤ min(h_max, H)); [`ContourWindow::estimate`] a warm-started walk to the nearest
//! point (3 squared distances in steady state, at most 2N with the full-scan fallback), one
//! dot product, ⌈log₂(H + 1)⌉ bisection steps, one point-to-chord distance (inverse square
//! roots by Newton steps, no division) and one 32-bit division. Measured on a Cortex-M4
//! (`./bench-m4.sh`, `DefaultWindow`, the patent parabola at 200 mm/s): 1 400 instructions
//! typical, 1 990 worst; the interpolator step 2 160 on average over the first 256 periods.

mod arc;
mod baseline;
mod estimate;
mod geom;
mod interp;
mod nearest;
mod parabola;
mod path;
pub mod trig;
mod window;

pub use arc::{Arc, ArcSpec};
pub use baseline::tangent_error;
pub use estimate::{max_bisection_steps, ContourEstimate};
pub use interp::{InterpCoeffs, InterpConfig, InterpConfigError, Interpolator, Reference};
pub use parabola::{Parabola, ParabolaSpec};
pub use path::{
    curvature_per_m, Line, LineSpec, ParametricPath, PathError, PathPoint, MAX_COORD_UM,
};
pub use window::{ContourWindow, DefaultWindow, OrdinaryPoint};

use fixed::types::{I20F12, I2F30, I32F32, I52F12};

/// Path parameter u (`I32F32`), in the path's own length-like unit (µm for the built-in
/// paths): resolution 2.3·10⁻¹⁰, range ±2.1·10⁹.
pub type Param = I32F32;
/// Absolute position on the path, µm (`I52F12`: 0.244 nm resolution, ±2.2·10⁹ m range;
/// paths are validated to ±8.388 m).
pub type PosFine = I52F12;
/// Relative vector or contour error, µm (`I20F12`: 0.244 nm, ±524 mm).
pub type RelUm = I20F12;
/// First or second derivative of a path, µm per unit of u (per unit of u²) (`I32F32`).
pub type Deriv = I32F32;
/// A component of a unit vector (`I2F30`: resolution 9.3·10⁻¹⁰, range ±2).
pub type UnitQ30 = I2F30;

/// A plane vector or point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Xy<T> {
    /// x component.
    pub x: T,
    /// y component.
    pub y: T,
}

impl<T> Xy<T> {
    /// A vector from its components.
    pub const fn new(x: T, y: T) -> Self {
        Self { x, y }
    }

    /// Applies `f` to both components.
    pub fn map<U>(self, mut f: impl FnMut(T) -> U) -> Xy<U> {
        Xy {
            x: f(self.x),
            y: f(self.y),
        }
    }
}
