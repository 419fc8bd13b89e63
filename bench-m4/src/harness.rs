//! Measuring one figure: the calls under test against a baseline of the same loop without
//! the call, both timed with SysTick (see [`crate::clock`]).
//!
//! A figure is a type implementing [`Figure`]: `call(k)` prepares the inputs of call `k`
//! (a realistic moving master, measured positions lagging the target, …), calls the core
//! function through one `#[inline(never)]` wrapper and keeps its outputs; `baseline(k)`
//! prepares the same inputs and keeps the previous outputs. The figure is
//! `(ticks(call loop) − ticks(baseline loop)) · instructions_per_tick / calls`: the cost of
//! the call as the control loop pays it (argument set-up, call, body, return, outputs).

use crate::clock;
use core::hint::black_box;

/// One benchmark figure.
pub trait Figure {
    /// Prepares the inputs of call `k`, makes the call, keeps the outputs.
    fn call(&mut self, k: u32);
    /// Prepares the inputs of call `k` and keeps the previous outputs (no call).
    fn baseline(&mut self, k: u32);
    /// Whether the last call still measured the intended path (no fault latched, the
    /// table not ended, …); a figure that is not healthy fails the run.
    fn healthy(&self) -> bool {
        true
    }
    /// Calls before the traced ones in the profile run: [`PROFILE_WARM_UP`] for a figure
    /// with state that settles (filters); a stateless figure or a costly one overrides it
    /// (QEMU logs every instruction of the profile run).
    fn profile_warm_up(&self) -> u32 {
        PROFILE_WARM_UP
    }
    /// Anything worth printing about the case measured (e.g. the worst case found).
    fn describe(&self, _w: &mut dyn core::fmt::Write) {}
}

/// Calls before the measured ones (filters settle, cursors find their segment).
pub const WARM_UP: u32 = 300;
/// Measured calls per figure (≥ 1000 so the 40-instruction SysTick step averages out).
pub const CALLS: u32 = 2000;
/// Calls traced instruction by instruction in the profile run.
pub const PROFILE_CALLS: u32 = 16;
/// Calls before the traced ones in the profile run, by default (fewer than [`WARM_UP`]:
/// QEMU logs every instruction of the run; the filters have settled and the instruction
/// mix is that of the running loop after this many).
pub const PROFILE_WARM_UP: u32 = 100;

/// SysTick counts of `n` calls from `k0`.
#[inline(never)]
fn time_calls<F: Figure>(f: &mut F, k0: u32, n: u32) -> u32 {
    let t0 = clock::now();
    for k in k0..k0.saturating_add(n) {
        f.call(black_box(k));
    }
    clock::since(t0)
}

/// SysTick counts of `n` baseline iterations from `k0`.
#[inline(never)]
fn time_baseline<F: Figure>(f: &mut F, k0: u32, n: u32) -> u32 {
    let t0 = clock::now();
    for k in k0..k0.saturating_add(n) {
        f.baseline(black_box(k));
    }
    clock::since(t0)
}

/// SysTick counts of a measured figure.
pub struct Timing {
    /// Counts of the call loop.
    pub calls_ticks: u32,
    /// Counts of the baseline loop.
    pub base_ticks: u32,
    /// Calls measured.
    pub calls: u32,
}

/// Warms up, then times [`CALLS`] calls and the baseline.
pub fn measure<F: Figure>(f: &mut F) -> Timing {
    for k in 0..WARM_UP {
        f.call(k);
    }
    // The baseline prepares the inputs of the same calls (same `k`).
    let calls_ticks = time_calls(f, WARM_UP, CALLS);
    let base_ticks = time_baseline(f, WARM_UP, CALLS);
    Timing {
        calls_ticks,
        base_ticks,
        calls: CALLS,
    }
}

/// SysTick counts of `n` calls minus their baseline, from `k = 0`, without warm-up (for
/// a figure that selects its worst case among candidates).
pub fn measure_calls<F: Figure>(f: &mut F, n: u32) -> u32 {
    time_calls(f, 0, n).saturating_sub(time_baseline(f, 0, n))
}

/// Marks the start of a profiled window in QEMU's instruction trace (the address of this
/// function is what `bench-m4/profile.awk` looks for).
#[inline(never)]
pub fn profile_begin() {
    black_box(0x5a5a_0001_u32);
}

/// Marks the end of a profiled window.
#[inline(never)]
pub fn profile_end() {
    black_box(0x5a5a_0002_u32);
}

/// The profiled window: [`PROFILE_CALLS`] calls between the two markers. Instructions of
/// this function itself (the loop and input preparation) are the harness and are not
/// attributed to the figure.
#[inline(never)]
fn profile_calls<F: Figure>(f: &mut F, k0: u32) {
    profile_begin();
    for k in k0..k0.saturating_add(PROFILE_CALLS) {
        f.call(black_box(k));
    }
    profile_end();
}

/// Warms up, then runs the profiled window.
pub fn profile<F: Figure>(f: &mut F) {
    let warm_up = f.profile_warm_up();
    for k in 0..warm_up {
        f.call(k);
    }
    profile_calls(f, warm_up);
}
