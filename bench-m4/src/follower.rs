//! Follower figures (SPEC §A): one [`Follower::tick`] with 1, 2, 4 and 8 slave axes in
//! `Feedforward` mode and 1 axis in `Paper` mode, on the reference machine's cam table
//! ([`Motion::Cruise`]); and the board's two Feedforward slaves on ticks that each enter
//! a new table segment ([`Motion::EveryNode`], the worst case of the segment search and
//! of the feed-forward constants).
//!
//! Set-up (PLANT.md): the tangent-cylinder table of the rotary-table stretch-bending
//! machine, 181 nodes every 0.5° (500 master counts of 0.001°), 20…480 mm. Slave `i`
//! of a multi-axis table follows the same die curve with its stroke scaled by
//! 1 − i/16 (every column different, all inside the table's validation limits). Period 1 ms; the master
//! advances 3.07 counts per tick on average (3.07 °/s, integer encoder counts: steps of 3
//! and 4), so the segment search crosses a node every ~163 ticks and the tracking
//! filter, both table lookups, the feed-forward and every PID term run on every call.
//! The measured positions lag the target by 3 µm, quantised to the 1 µm encoder, so the
//! integrator stays inside its zone and no following-error fault is ever latched.

use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::axis::{AxisConfig, ControlMode, PositionGains};
use hydra_core::follower::{Follower, FollowerConfig, FollowerInputs, FollowerOutputs};
use hydra_core::table::{AxisLimits, CamTable, Node, TableLimits};
use hydra_core::units::{Master, MasterRate, PosUm, PressureBar, VelUmPerS};

/// Table capacity of the benchmark (nodes).
pub const NODES: usize = 256;
/// Master counts between nodes (0.5° at 0.001° per count).
const NODE_SPACING: i64 = 500;
/// Master start, counts (5°: inside the table, on the rising flank).
const MASTER_START: i64 = 5_000;
/// Master advance, counts per tick, ×100.
const MASTER_STEP_X100: u32 = 307;
/// Measured position = target − this lag (raw `I24F8`, 3 µm).
const LAG_BITS: i32 = 3 << 8;
/// [`Motion::EveryNode`]: master counts between nodes (the master moves 3.07 per tick).
const EVERY_NODE_SPACING: i64 = 2;
/// [`Motion::EveryNode`]: the die curve's stroke above 20 mm divided by this (slopes of
/// ≤ 12 µm per count, ≤ 37 mm/s of slave at 3 070 counts/s).
const EVERY_NODE_STROKE_DIV: i64 = 256;
/// [`Motion::EveryNode`]: the master runs back and forth between these, counts (inside
/// the 360 counts of the table, clear of its ends and of the filter's overshoot).
const EVERY_NODE_LOW: i64 = 20;
/// See [`EVERY_NODE_LOW`].
const EVERY_NODE_HIGH: i64 = 340;

/// The master motion and table of a follower figure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// The reference table (nodes 500 counts apart), the master cruising up at 3.07 counts
    /// per tick from 5 000: the look-ahead enters a segment every ≈ 163 ticks.
    Cruise,
    /// Nodes 2 counts apart (the die curve, stroke / 256), the master at 3.07 counts per
    /// tick back and forth between 20 and 340 counts: nearly every tick the master and
    /// its look-ahead (17 counts ahead) are in new segments, so every tick searches both
    /// and works out every axis' feed-forward constants.
    EveryNode,
}

impl Motion {
    /// Master counts between nodes.
    fn spacing(self) -> i64 {
        match self {
            Self::Cruise => NODE_SPACING,
            Self::EveryNode => EVERY_NODE_SPACING,
        }
    }

    /// Divisor of the stroke above 20 mm.
    fn stroke_div(self) -> i64 {
        match self {
            Self::Cruise => 1,
            Self::EveryNode => EVERY_NODE_STROKE_DIV,
        }
    }

    /// The master of call `k`, whole counts (u32 arithmetic, one UDIV: the harness must
    /// cost little next to the call).
    #[inline(always)]
    fn master(self, k: u32) -> i64 {
        let advance = k.wrapping_mul(MASTER_STEP_X100) / 100;
        match self {
            Self::Cruise => MASTER_START + i64::from(advance),
            Self::EveryNode => {
                let span = (EVERY_NODE_HIGH - EVERY_NODE_LOW) as u32;
                let p = advance % (2 * span);
                let up = if p < span { p } else { 2 * span - p };
                EVERY_NODE_LOW + i64::from(up)
            }
        }
    }
}

include!(concat!(env!("OUT_DIR"), "/die_table.rs"));

/// The reference table with `S` columns ([`Motion::Cruise`], see [`table_for`]).
pub(crate) fn table<const S: usize>() -> Option<CamTable<S, NODES>> {
    table_for(Motion::Cruise)
}

/// The table with `S` columns: column 0 is the die curve scaled to 20…480 mm over
/// 0…90° (PLANT.md, [`DIE_UM`]), column `i` the same curve with its stroke above 20 mm
/// scaled by 1 − i/16 (integer arithmetic: no floating point on the target); nodes and
/// stroke as `motion` sets them.
fn table_for<const S: usize>(motion: Motion) -> Option<CamTable<S, NODES>> {
    let mut nodes = [Node {
        master: Master::ZERO,
        slave_um: [PosUm::ZERO; S],
    }; DIE_UM.len()];
    for ((j, n), x0) in nodes.iter_mut().enumerate().zip(DIE_UM.iter()) {
        n.master = Master::from_num(j as i64 * motion.spacing());
        for (i, x) in n.slave_um.iter_mut().enumerate() {
            let above = i64::from(x0.saturating_sub(20_000)) / motion.stroke_div();
            let scaled = above * (16 - i as i64) / 16;
            *x = PosUm::from_num(20_000 + scaled);
        }
    }
    let limits = TableLimits {
        master_speed_per_s: MasterRate::from_num(3300),
        axes: [AxisLimits {
            min_um: PosUm::from_num(0),
            max_um: PosUm::from_num(500_000),
            max_speed_um_per_s: VelUmPerS::from_num(200_000),
        }; S],
    };
    CamTable::try_from_nodes(&nodes, &limits).ok()
}

/// Gains of the reference tangent cylinder (every term of the law non-zero).
pub(crate) fn axis(mode: ControlMode) -> AxisConfig {
    AxisConfig {
        gains: PositionGains {
            kp_lsb_per_um: 0.4,
            ki_lsb_per_um_s: 5.0,
            kd_lsb_s_per_um: 0.0005,
            i_zone_um: 200.0,
            i_limit_lsb: 100.0,
            kv_pos_lsb_per_um_s: 0.017,
            kv_neg_lsb_per_um_s: 0.025,
            ka_lsb_per_um_s2: 0.0001,
            valve_lag_us: 4200.0,
            following_error_um: 5000.0,
            // Active damping, the gain backoff and the trim off: the plain law
            // (`follower_ff_1axis_damped` and `_shipped` measure them on).
            ..PositionGains::default()
        },
        mode,
        ..AxisConfig::default()
    }
}

/// The measured call: one follower tick, writing into the caller's outputs (as the
/// firmware's tick does).
#[inline(never)]
fn tick<const S: usize>(
    f: &mut Follower<S, NODES>,
    inp: &FollowerInputs<S>,
    out: &mut FollowerOutputs<S>,
) {
    f.tick_into(inp, out)
}

/// A follower with its inputs and last outputs.
pub struct FollowerFig<const S: usize> {
    f: Follower<S, NODES>,
    motion: Motion,
    inp: FollowerInputs<S>,
    out: FollowerOutputs<S>,
    /// Whether the chamber pressures change from call to call (a damped figure).
    pressures_move: bool,
}

impl<const S: usize> FollowerFig<S> {
    /// The follower on the reference table, every axis in `mode`, the master cruising;
    /// `None` if the core rejects the set-up (reported as a failed figure).
    pub fn new(mode: ControlMode) -> Option<Self> {
        Self::with_motion(mode, Motion::Cruise)
    }

    /// [`Self::new`] with active damping on every axis (16 LSB/kN, 5 Hz, the reference
    /// cylinder's areas), the chamber pressures changing every call.
    pub fn damped(mode: ControlMode) -> Option<Self> {
        let mut a = axis(mode);
        a.gains.dp_gain_lsb_per_kn = 16.0;
        a.areas = hydra_core::profile::piston_areas();
        Self::with_axes([a; S], Motion::Cruise)
    }

    /// [`Self::new`] with the board profile's gain backoff band and feed-forward trim on
    /// every axis (`profile::OSC_BAND_UM`, `profile::FF_TRIM_TAU_S`): the path the
    /// shipped tuning runs (the error stays below the band: the detector counts nothing).
    pub fn shipped(mode: ControlMode) -> Option<Self> {
        let mut a = axis(mode);
        a.gains.osc_band_um = hydra_core::profile::OSC_BAND_UM;
        a.gains.ff_trim_tau_s = hydra_core::profile::FF_TRIM_TAU_S;
        Self::with_axes([a; S], Motion::Cruise)
    }

    /// The follower on `motion`'s table and master, every axis in `mode`.
    pub fn with_motion(mode: ControlMode, motion: Motion) -> Option<Self> {
        Self::with_axes([axis(mode); S], motion)
    }

    fn with_axes(axes: [AxisConfig; S], motion: Motion) -> Option<Self> {
        let cfg = FollowerConfig {
            axes,
            ..FollowerConfig::default()
        };
        let t = table_for::<S>(motion)?;
        let mut f = Follower::new(&cfg, t).ok()?;
        let inp = FollowerInputs {
            master: Master::from_num(motion.master(0)),
            pos_um: [PosUm::ZERO; S],
            pressure_bar: [[PressureBar::ZERO; 2]; S],
        };
        // Positions start on the table at the master start.
        let mut fig_inp = inp;
        let mut cursor = 0;
        let lk = f.table().locate(&mut cursor, inp.master);
        for (i, x) in fig_inp.pos_um.iter_mut().enumerate() {
            *x = f.table().value(&lk, i);
        }
        let out = f.tick(&fig_inp);
        Some(Self {
            f,
            motion,
            inp: fig_inp,
            out,
            pressures_move: cfg.axes.iter().any(|a| a.gains.dp_gain_lsb_per_kn > 0.0),
        })
    }

    /// Inputs of call `k`: the master at 3.07 counts/tick, positions 3 µm behind the
    /// last target, whole µm.
    #[inline(always)]
    fn next_inputs(&mut self, k: u32) {
        self.inp.master = Master::from_bits(self.motion.master(k) << 16);
        for (x, t) in self.inp.pos_um.iter_mut().zip(self.out.target_um.iter()) {
            *x = PosUm::from_bits((t.to_bits() & !0xFF).saturating_sub(LAG_BITS));
        }
        // Chamber A between 80 and 86 bar, B at 40 (only where an axis reads them).
        if self.pressures_move {
            let p_a = PressureBar::from_bits((80 + (k % 7) as i32) << 16);
            for p in self.inp.pressure_bar.iter_mut() {
                *p = [p_a, PressureBar::from_bits(40 << 16)];
            }
        }
    }
}

impl<const S: usize> Figure for FollowerFig<S> {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.next_inputs(k);
        tick(&mut self.f, &self.inp, &mut self.out);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        self.next_inputs(k);
        black_box(&mut self.out);
    }

    /// No axis latched a fault and the table has not ended (the figure would then not
    /// measure the running loop).
    fn healthy(&self) -> bool {
        !self.out.end_of_table && self.out.fault.iter().all(Option::is_none)
    }
}
