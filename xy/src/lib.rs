//! # hydra-xy — contour control of two-axis paths, in fixed point
//!
//! `#![no_std]`, no allocation, built on `hydra-core`'s fixed-point arithmetic and units:
//! contour-error estimation (SPEC §C: [`contour`]) and the nonlinear PID with
//! cross-coupled control (§D: [`npid`]). The valve board's firmware does not run them;
//! host-sim's X–Y table (`host-sim xy`, `host-sim contour-estimate`) and bench-m4's
//! Cortex-M4 figures do. Like `hydra-core` it cannot panic: the same lints deny it
//! outside tests.
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

#[cfg(test)]
extern crate std;

pub mod contour;
pub mod npid;
