//! # bench-m4 — what the control loop costs on a Cortex-M4F, without a board
//!
//! Runs on QEMU's `mps2-an386` (Cortex-M4 with FPU) with `-icount shift=0` and
//! semihosting; `./bench-m4.sh` at the workspace root builds it with the workspace's
//! release profile, runs it and checks the figures against `bench-budget.toml`.
//!
//! Two modes, chosen by the semihosting command line:
//!
//! * default: every figure is timed with SysTick ([`clock`], [`harness`]) and printed as
//!   `FIG <name> calls=<n> ticks=<t> base_ticks=<b> instr_x1000=<i>`;
//! * `profile`: every figure's [`harness::PROFILE_CALLS`] calls run between two marker
//!   functions, for QEMU's per-instruction trace (`-singlestep -d exec,nochain`); the
//!   script weighs the traced instructions with the Cortex-M4 cycle table
//!   (`bench-m4/profile.awk`) to estimate cycles. Printed: `PROFILE <name>` per window.
//!
//! The functions called are the real `hydra_core` ones, with no peripherals.
#![no_std]
#![no_main]

mod clock;
mod follower;
mod harness;
mod out;
mod semihost;

use core::fmt::Write;
use cortex_m_rt::entry;
use follower::FollowerFig;
use harness::Figure;
use hydra_core::axis::ControlMode;
use out::Out;

/// Measure (SysTick) or trace (profile) run.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Measure,
    Profile,
}

/// Runs one figure in `mode` and prints its line; false if the set-up was rejected or
/// the figure did not stay on its intended path.
fn run<F: Figure>(o: &mut Out, mode: Mode, ipt_x1000: u64, name: &str, fig: Option<F>) -> bool {
    let Some(mut fig) = fig else {
        let _ = writeln!(o, "ERROR {name}: set-up rejected by hydra_core");
        return false;
    };
    match mode {
        Mode::Measure => {
            let t = harness::measure(&mut fig);
            let net = u64::from(t.calls_ticks.saturating_sub(t.base_ticks));
            let instr_x1000 = net * ipt_x1000 / u64::from(t.calls.max(1));
            let _ = writeln!(
                o,
                "FIG {name} calls={} ticks={} base_ticks={} instr_x1000={instr_x1000}",
                t.calls, t.calls_ticks, t.base_ticks
            );
        }
        Mode::Profile => {
            let _ = writeln!(o, "PROFILE {name} calls={}", harness::PROFILE_CALLS);
            harness::profile(&mut fig);
        }
    }
    if !fig.healthy() {
        let _ = writeln!(o, "ERROR {name}: left its intended path (fault or end)");
        return false;
    }
    true
}

#[entry]
fn main() -> ! {
    let mut o = Out::new();
    let mut ok = true;
    let Some(p) = cortex_m::Peripherals::take() else {
        semihost::exit(false);
    };
    clock::start(p.SYST);

    let mut buf = [0u8; 128];
    let line = semihost::cmdline(&mut buf);
    let mode = if line.windows(7).any(|w| w == b"profile") {
        Mode::Profile
    } else {
        Mode::Measure
    };

    // Instructions per SysTick count, ×1000, from a loop of known length (not needed
    // for, and kept out of, the instruction trace of a profile run).
    let cal_ticks = if mode == Mode::Measure {
        clock::calibrate()
    } else {
        0
    };
    let cal_instr = 2 * u64::from(clock::CAL_ITERATIONS);
    let ipt_x1000 = (cal_instr * 1000 + u64::from(cal_ticks) / 2) / u64::from(cal_ticks.max(1));
    let _ = writeln!(
        o,
        "CAL instructions={cal_instr} ticks={cal_ticks} instr_per_tick_x1000={ipt_x1000}"
    );

    ok &= run(
        &mut o,
        mode,
        ipt_x1000,
        "follower_ff_1axis",
        FollowerFig::<1>::new(ControlMode::Feedforward),
    );
    ok &= run(
        &mut o,
        mode,
        ipt_x1000,
        "follower_ff_4axes",
        FollowerFig::<4>::new(ControlMode::Feedforward),
    );
    ok &= run(
        &mut o,
        mode,
        ipt_x1000,
        "follower_ff_8axes",
        FollowerFig::<8>::new(ControlMode::Feedforward),
    );
    ok &= run(
        &mut o,
        mode,
        ipt_x1000,
        "follower_paper_1axis",
        FollowerFig::<1>::new(ControlMode::Paper),
    );

    let _ = writeln!(o, "DONE ok={ok}");
    semihost::exit(ok);
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    semihost::write0(b"ERROR panic\n\0");
    semihost::exit(false);
}
