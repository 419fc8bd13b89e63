//! The firmware's whole control step without its drivers: [`Runtime::step`] of
//! `Runtime<&'static mut Follower<2, 256>, 2, 4>` with the firmware's runtime
//! configuration (`firmware/src/boot_config.rs`: `RuntimeConfig::default()` at 1 ms — 1 µm per
//! slave count, master counts of 0.001°) — encoder scaling and plausibility, the stall
//! monitor, the fault rules, the follower with two Feedforward slaves, the status.
//!
//! Set-up: the follower figures' reference table in both columns and their gains; the
//! runtime started (Following) at 5° on the rising flank; the master advances 3.07
//! counts per tick, with the firmware's edge-timer reading (1 MHz; the newest rising A
//! edge, one per 4 counts, at its exact time — the sub-count estimate runs every call),
//! each slave's count is 3 µm behind its last target; four chamber pressures at 100 bar.

use crate::follower::{axis, table, NODES};
use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::axis::ControlMode;
use hydra_core::follower::{Follower, FollowerConfig};
use hydra_core::master::{EdgeCapture, EdgeReading};
use hydra_core::runtime::{
    BootCause, Command, EncoderSample, Runtime, RuntimeConfig, Sample, State, TickOutputs,
};
use hydra_core::units::{Counts, Master, PressureBar};
use static_cell::StaticCell;

/// The firmware's law: two slave axes, 256 table nodes (`firmware/src/boot_config.rs`).
pub(crate) type Law = Follower<2, NODES>;
/// The firmware's pressure channels (`firmware/src/board.rs`).
pub(crate) const PRESSURES: usize = 4;
/// The firmware's runtime: the law in a static buffer (`firmware/src/law_buffers.rs`).
pub(crate) type BoardRuntime = Runtime<&'static mut Law, 2, PRESSURES>;

/// The firmware's law on the reference table (both slaves Feedforward, the follower
/// figures' gains), in the static buffer `cell`; `None` if the core rejects the set-up
/// or the buffer is already used.
pub(crate) fn board_law(cell: &'static StaticCell<Law>) -> Option<&'static mut Law> {
    let cfg = FollowerConfig {
        axes: [axis(ControlMode::Feedforward); 2],
        ..FollowerConfig::default()
    };
    cell.try_init(Follower::new(&cfg, table::<2>()?).ok()?)
}

/// The firmware's runtime (its configuration: `RuntimeConfig::default()`, 1 ms) at rest,
/// running `law`.
pub(crate) fn board_runtime(law: &'static mut Law) -> Option<BoardRuntime> {
    let coeffs = RuntimeConfig::<2>::default().build().ok()?;
    Some(Runtime::new(coeffs, Some(law), BootCause::Normal))
}

static LAW: StaticCell<Law> = StaticCell::new();

/// Master start, counts (5°).
const MASTER_START: i32 = 5_000;
/// Master advance, counts per tick, ×100.
const MASTER_STEP_X100: u32 = 307;
/// Slave counts behind the last target (1 µm per count).
const LAG_COUNTS: i32 = 3;

/// The measured call: one control step.
#[inline(never)]
fn step(rt: &mut BoardRuntime, s: &Sample<2, PRESSURES>) -> TickOutputs<2> {
    rt.step(s, None)
}

/// `runtime_step_2axes`.
pub struct RuntimeStep {
    rt: BoardRuntime,
    s: Sample<2, PRESSURES>,
    out: TickOutputs<2>,
}

impl RuntimeStep {
    /// The runtime following the reference table from 5°.
    pub fn new() -> Option<Self> {
        let law = board_law(&LAW)?;
        // The slaves start on the table at the master start (a jump to it would be an
        // encoder fault).
        let mut cursor = 0;
        let lk = law
            .table()
            .locate(&mut cursor, Master::from_num(MASTER_START));
        let at = |i| Counts(law.table().value(&lk, i).to_num::<i32>());
        let slaves = [at(0), at(1)];
        let mut rt = board_runtime(law)?;
        let s = Sample {
            enc: EncoderSample {
                master: Counts(MASTER_START),
                slaves,
                master_edges: None,
            },
            pressure_bar: [PressureBar::from_num(100); PRESSURES],
            estop: false,
            overrun: false,
        };
        rt.step(&s, None);
        let out = rt.step(&s, Some(Command::Start));
        Some(Self { rt, s, out })
    }

    /// Inputs of call `k`: the master at 3.07 counts/tick with its newest rising A edge
    /// (counts 4j + 1, boundary 4j + ½, at 1 µs), slaves 3 counts behind.
    #[inline(always)]
    fn next_inputs(&mut self, k: u32) {
        let advance = k.wrapping_mul(MASTER_STEP_X100) / 100;
        self.s.enc.master = Counts(MASTER_START.wrapping_add(advance as i32));
        // The edge 4j + ½ ≤ the master, in counts from the start, and its time in µs.
        let edge = advance.saturating_sub(1) & !3;
        let at_us = (edge.wrapping_mul(100).wrapping_add(50)).wrapping_mul(1000) / MASTER_STEP_X100;
        self.s.enc.master_edges = Some(EdgeReading {
            now_ticks: k.wrapping_mul(1000),
            edge: Some(EdgeCapture {
                at_ticks: at_us,
                count: Counts(MASTER_START.wrapping_add(edge as i32).wrapping_add(1)),
            }),
        });
        for (c, t) in self
            .s
            .enc
            .slaves
            .iter_mut()
            .zip(self.rt.status().target_um.iter())
        {
            *c = Counts(t.to_num::<i32>().wrapping_sub(LAG_COUNTS));
        }
    }
}

impl Figure for RuntimeStep {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.next_inputs(k);
        self.out = step(&mut self.rt, &self.s);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.next_inputs(k);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        self.rt.state() == State::Following && self.out.enable
    }
}
