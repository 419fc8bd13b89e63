//! # hydra-core — the fixed-point algorithms of the hydraulic motion controller
//!
//! `#![no_std]`, no allocation, no HAL. Everything that can be tested on the host lives
//! here: master prediction, cam-table interpolation, the axis control laws, the
//! master/slave follower (SPEC §A), the 7-phase S-curve (§B), the runtime state machine
//! and the UART protocol. (Contour-error estimation (§C) and the nonlinear PID with
//! cross-coupled control (§D), which the valve board does not run, are `hydra-xy`.)
//!
//! Every fixed-point quantity has a documented unit, format, resolution and range: see
//! [`units`] for the table. Configuration is validated once by a builder (`build`)
//! that returns a typed error; the per-tick hot path then cannot fail and never panics.
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic,
        clippy::arithmetic_side_effects
    )
)]

#[cfg(any(test, feature = "std"))]
extern crate std;

pub mod axis;
pub mod dac;
pub mod fixed_point;
pub mod follower;
pub mod master;
pub mod plc;
pub mod profile;
pub mod protocol;
pub mod runtime;
pub mod scurve;
pub mod table;
pub mod units;
pub mod valve;

/// Property-test case counts that a command line can raise: `var` (an environment
/// variable) if set to a number, else `default`.
#[cfg(test)]
pub(crate) fn env_cases(var: &str, default: u32) -> u32 {
    std::env::var(var)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}
