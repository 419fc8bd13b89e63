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
mod contour;
mod follower;
mod fx;
mod harness;
mod install;
mod npid;
mod out;
mod runtime;
mod scurve;
mod semihost;
mod xy;

use core::fmt::Write;
use cortex_m_rt::entry;
use follower::{FollowerFig, Motion};
use harness::Figure;
use hydra_core::axis::ControlMode;
use out::Out;

/// Measure (SysTick) or trace (profile) run.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Measure,
    Profile,
}

/// Runs the figures of one mode and prints their lines.
struct Runner {
    o: Out,
    mode: Mode,
    /// Instructions per SysTick count, ×1000 (from the calibration).
    ipt_x1000: u64,
    /// Every figure so far set up, ran and stayed on its intended path.
    ok: bool,
}

impl Runner {
    /// Runs one figure and prints its line; records a failure if the set-up was
    /// rejected or the figure did not stay on its intended path.
    fn run<F: Figure>(&mut self, name: &str, fig: Option<F>) {
        let o = &mut self.o;
        let Some(mut fig) = fig else {
            let _ = writeln!(o, "ERROR {name}: set-up rejected by hydra_core");
            self.ok = false;
            return;
        };
        match self.mode {
            Mode::Measure => {
                let t = harness::measure(&mut fig);
                let net = u64::from(t.calls_ticks.saturating_sub(t.base_ticks));
                let instr_x1000 = net * self.ipt_x1000 / u64::from(t.calls.max(1));
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
        let mut note = NoteLine::new(name);
        fig.describe(&mut note);
        if note.used {
            let _ = writeln!(o, "{}", note.as_str());
        }
        if !fig.healthy() {
            let _ = writeln!(o, "ERROR {name}: left its intended path (fault, end, …)");
            self.ok = false;
        }
    }
}

/// `NOTE <figure>: <text>`, built in a fixed buffer.
struct NoteLine {
    buf: [u8; 160],
    len: usize,
    used: bool,
}

impl NoteLine {
    fn new(name: &str) -> Self {
        let mut n = Self {
            buf: [0; 160],
            len: 0,
            used: false,
        };
        let _ = write!(n, "NOTE {name}:");
        n.used = false;
        n
    }

    fn as_str(&self) -> &str {
        core::str::from_utf8(self.buf.get(..self.len).unwrap_or(&[])).unwrap_or("")
    }
}

impl Write for NoteLine {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &c in s.as_bytes() {
            if let Some(b) = self.buf.get_mut(self.len) {
                *b = if c == b'\n' { b' ' } else { c };
                self.len += 1;
            }
        }
        self.used = true;
        Ok(())
    }
}

/// `contour_worst=<lag2>:<offset>` on the command line (from the measure run's NOTE).
fn worst_pick(line: &[u8]) -> Option<(u32, i32)> {
    let key = b"contour_worst=";
    let at = line.windows(key.len()).position(|w| w == key)?;
    let rest = core::str::from_utf8(line.get(at + key.len()..)?).ok()?;
    let rest = rest.split(' ').next()?;
    let (a, b) = rest.split_once(':')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

#[entry]
fn main() -> ! {
    let mut o = Out::new();
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

    let mut r = Runner {
        o,
        mode,
        ipt_x1000,
        ok: true,
    };
    // Follower (SPEC §A).
    r.run(
        "follower_ff_1axis",
        FollowerFig::<1>::new(ControlMode::Feedforward),
    );
    r.run(
        "follower_ff_1axis_damped",
        FollowerFig::<1>::damped(ControlMode::Feedforward),
    );
    r.run(
        "follower_ff_1axis_shipped",
        FollowerFig::<1>::shipped(ControlMode::Feedforward),
    );
    r.run(
        "follower_ff_2axes",
        FollowerFig::<2>::new(ControlMode::Feedforward),
    );
    r.run(
        "follower_ff_4axes",
        FollowerFig::<4>::new(ControlMode::Feedforward),
    );
    r.run(
        "follower_ff_8axes",
        FollowerFig::<8>::new(ControlMode::Feedforward),
    );
    r.run(
        "follower_paper_1axis",
        FollowerFig::<1>::new(ControlMode::Paper),
    );
    r.run(
        "follower_ff_2axes_every_node",
        FollowerFig::<2>::with_motion(ControlMode::Feedforward, Motion::EveryNode),
    );
    r.run(
        "follower_ff_8axes_every_node",
        FollowerFig::<8>::with_motion(ControlMode::Feedforward, Motion::EveryNode),
    );
    // S-curve (SPEC §B).
    r.run("scurve_sample", scurve::ProfileSample::new());
    r.run("scurve_line_xy", scurve::LineXy::new());
    // Contour estimation (SPEC §C).
    r.run("contour_interp_step", contour::InterpStep::new());
    r.run("contour_estimate_typical", contour::EstimateTypical::new());
    let pick = match (mode, worst_pick(line)) {
        (Mode::Profile, Some((l2, off))) => contour::WorstPick::Given(l2, off),
        _ => contour::WorstPick::Sweep,
    };
    r.run("contour_estimate_worst", contour::EstimateWorst::new(pick));
    // Nonlinear PID (SPEC §D).
    r.run("npid_td_fal", npid::NpidTrack::new());
    // The X–Y cross-coupled tick with estimation (SPEC §C + §D).
    r.run("xy_cross_coupled_estimated", xy::XyEstimated::new());
    r.run("xy_contour_part", xy::XyContourPart::new());
    r.run("runtime_install_law", install::InstallLaw::new());
    r.run("runtime_step_2axes", runtime::RuntimeStep::new());
    r.run("fx_sqrt_u64", fx::Sqrt::new());

    let ok = r.ok;
    let _ = writeln!(r.o, "DONE ok={ok}");
    semihost::exit(ok);
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    semihost::write("ERROR panic\n");
    semihost::exit(false);
}
