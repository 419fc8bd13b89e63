//! Fixed-point helpers, in one place: every algorithm of the crate forms its products,
//! shifts, saturations, square roots and powers here.
//!
//! Grouped by operation; each name says how it rounds (`floor`: toward −∞, `round`: to
//! nearest) and whether it saturates (`sat`):
//!
//! | file | what | formats |
//! |---|---|---|
//! | [`saturate`] | saturation to `i32`/`i64` (`sat_*`) and clamps to a limit (`clamp_*`) | raw `i32`/`i64` of any `IaFb` |
//! | [`floor`] | products shifted toward −∞ (`mul_shr_floor_sat`, `mul64_shr_floor_sat`), high halves of 64×64 products, signed shifts, division by a small integer, bit length | raw `i32`/`i64`, Q0.64 fractions |
//! | [`round`] | shifts and products rounded to nearest (`shr_round_*`, `mul_shr_round_sat`, `mul64_shr_round_sat`, the 32-bit-multiply forms of the `i64` products) | `i64` positions, Q30 unit vectors |
//! | [`unit_vector`] | 1/√x and the normalisation of a vector to a unit vector and a length | Q2.30 unit vectors |
//! | [`sqrt_pow`] | the square root, base-2 logarithm and exponential, the power \|x\|^α | Q24 logarithms, Q30 tables, Q16 results |
//!
//! Every helper saturates instead of overflowing (or states the bound its caller proves)
//! and never panics; no helper calls a library routine on the hot paths (an `i128`
//! product is one on the Cortex-M4: each helper that could need one takes its 32-bit
//! form whenever the operands allow it, bit for bit equal, tested). Configuration-time
//! `f64` maths (building coefficients) uses `libm`, never these.
//!
//! One square root: [`sqrt_pow::sqrt_u64`] (table + one Newton step, one 32-bit division),
//! chosen by bench-m4 over the reciprocal-square-root form (docs/bench.md, "one square
//! root"); [`unit_vector::rsqrt_q30`] is the reciprocal square root the vector normalisation
//! needs (no division).

pub mod floor;
pub mod round;
pub mod saturate;
pub mod sqrt_pow;
pub mod unit_vector;

pub use floor::*;
pub use round::*;
pub use saturate::*;
pub use sqrt_pow::*;
pub use unit_vector::*;
