//! Real-time adaptive contour-error estimation (SPEC §C; placeholder docs, expanded below).

mod arc;
mod baseline;
mod estimate;
mod fx;
mod geom;
mod interp;
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
