//! Fixed-point helpers, in one place: every algorithm of the crate forms its products,
//! shifts, saturations, square roots and powers here.
//!
//! | file | what | formats |
//! |---|---|---|
//! | [`saturate`] | saturation to `i32`/`i64`, 32×32 → 64-bit products with a shift (truncating, rounding), the 64×64 product with its 32-bit fast path, symmetric clamps | raw `i32`/`i64` of any `IaFb` |
//! | [`products`] | rounding shifts, `i64` products through 32-bit multiplies (Cortex-M4 `smull`/`umull`), high halves of 64×64 products, division by a small integer, clamps to `i32` | `i64` positions, Q0.64 fractions |
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

pub mod products;
pub mod saturate;
pub mod sqrt_pow;
pub mod unit_vector;

pub use products::*;
pub use saturate::*;
pub use sqrt_pow::*;
pub use unit_vector::*;
