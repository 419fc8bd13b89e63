//! The master/slave follower: one master, `S` slave axes, a cam table of `N` nodes
//! (SPEC §A, loop steps 3–8), one call per control period.
//!
//! Per tick, from the master sample θ_m(k) and the slave positions x(k):
//!
//! 1. The master tracking filter ([`MasterFilter`]) and the eq. 4 predictor
//!    ([`Predictor`]) take θ_m(k). A follower whose axes are all `Paper` runs the
//!    predictor alone (SPEC §A has no tracking filter): its "now" is θ_m(k) itself, its
//!    direction the sign of θ_m(k) − θ_m(k−1), its jump test θ_m(k) against θ̂(k).
//!    Every axis on one law (all Feedforward, all Paper) takes that law's own path, with
//!    the per-axis dispatch resolved at compile time; other mixes and an ended table take
//!    the general one.
//! 2. End of table (steps 3 and 8): once the master is at or past the last node while
//!    moving up, or below the first while moving down, the follower latches `ended` and
//!    every slave holds its final table position (no feed-forward).
//! 3. Per axis, by its [`ControlMode`]:
//!    - `Feedforward`: x_ref = X(θ_f(k)), the table at the filtered master now (the error
//!      at the sampling instant); v_ff = ΔX_j·θ̇/len_j and a_ff = ΔX_j·θ̈/len_j taken at
//!      θ_f(k + n), n = 1.5 + t_valve/T periods ahead: the middle of the period in which
//!      this command acts (one period of computation delay) plus the valve's lag. Inside
//!      a segment kv±·v_ff + ka·a_ff is two products of the filter's own speed and
//!      acceleration with per-axis constants, worked out when the look-ahead enters the
//!      segment (`ff_plan`).
//!    - `Paper`: x_ref = X(θ̂(k+1)), the table at the eq. 4 prediction (eq. 5–6).
//!    - `NextNode`: x_ref = the node at the far end of the current segment in the
//!      direction of master motion.
//! 4. The axis law ([`crate::axis::position_law`]), less the active damping's term where
//!    the axis has it ([`crate::axis::damping`]), and the valve output stage give the DAC
//!    code.
//! 5. Following error e = X(θ_f(k)) − x(k) beyond the axis limit latches that axis'
//!    fault: its valve goes to null, its controller state is cleared, until
//!    [`Follower::clear_faults`].
//!
//! Every table lookup starts from its own cursor, so the search is O(1) amortised. On
//! nearly every tick of an all-Feedforward follower the sampled master, the filtered
//! master and its look-ahead are in the cursor's segment: that tick takes the fast path
//! (one segment read, no end test — `Follower::tick_ff_fast`).

use crate::axis::backoff::{self, BackoffCoeffs, BackoffState};
use crate::axis::damping::{damped_cmd, damping_bits, DampingCoeffs, DampingState};
use crate::axis::ff_trim::{FfTrimCoeffs, FfTrimState};
use crate::axis::position::{paper_law_bits, positional_law_ff, positional_law_with};
use crate::axis::{
    position_law, AxisCoeffs, AxisConfig, AxisConfigError, ControlMode, PosRef, PosState,
};
use crate::master::{
    MasterEstimate, MasterFilter, MasterFilterCoeffs, MasterFilterConfig, MasterFilterError,
};
use crate::master::{Predictor, PredictorKind};
use crate::table::{Beyond, CamTable, Span};
use crate::units::{CmdLsb, DacCode, Master, PosUm, PressureBar};
use ff_plan::FfPlan;

mod ff_plan;

/// Follower configuration in engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FollowerConfig<const S: usize> {
    /// Control period T, µs (50 … 1 000 000).
    pub period_us: u32,
    /// Master tracking filter.
    pub master_filter: MasterFilterConfig,
    /// Extrapolation of the `Paper` mode's predictor (eq. 4 as printed by default).
    pub predictor: PredictorKind,
    /// The slave axes, one per table column.
    pub axes: [AxisConfig; S],
}

impl<const S: usize> Default for FollowerConfig<S> {
    fn default() -> Self {
        Self {
            period_us: 1000,
            master_filter: MasterFilterConfig::default(),
            predictor: PredictorKind::Eq4,
            axes: [AxisConfig::default(); S],
        }
    }
}

/// Why a follower configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FollowerError {
    /// The master filter's parameters.
    MasterFilter(MasterFilterError),
    /// Axis `axis`'s parameters.
    Axis {
        /// Slave index.
        axis: usize,
        /// What is wrong.
        error: AxisConfigError,
    },
}

/// A latched per-axis fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AxisFault {
    /// |X(θ_f) − x| exceeded the axis' following-error limit.
    FollowingError,
}

/// One tick's inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FollowerInputs<const S: usize> {
    /// Master sample θ_m(k), master counts.
    pub master: Master,
    /// Slave positions x(k), µm.
    pub pos_um: [PosUm; S],
    /// Per slave, chamber A and B pressures, bar (the active damping's input; unused by
    /// an axis without it).
    pub pressure_bar: [[PressureBar; 2]; S],
}

/// One tick's outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FollowerOutputs<const S: usize> {
    /// Valve codes to apply from the start of the next period.
    pub dac: [DacCode; S],
    /// Commands before the output stage, LSB.
    pub cmd_lsb: [CmdLsb; S],
    /// X(θ_f(k)): the table at the filtered master now, µm.
    pub target_um: [PosUm; S],
    /// target − x(k), µm.
    pub error_um: [PosUm; S],
    /// Latched faults.
    pub fault: [Option<AxisFault>; S],
    /// The master has passed the end of the table: the slaves hold.
    pub end_of_table: bool,
    /// The master moved 2^15 counts or more from its prediction this tick (the tracking
    /// filter's residual, or the eq. 4 predictor's for an all-Paper follower).
    pub master_jump: bool,
}

impl<const S: usize> Default for FollowerOutputs<S> {
    fn default() -> Self {
        Self {
            dac: [DacCode::NULL; S],
            cmd_lsb: [CmdLsb::ZERO; S],
            target_um: [PosUm::ZERO; S],
            error_um: [PosUm::ZERO; S],
            fault: [None; S],
            end_of_table: false,
            master_jump: false,
        }
    }
}

/// Per-axis runtime data.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct AxisRt {
    st: PosState,
    fault: Option<AxisFault>,
    /// The feed-forward constants of the segment the axis' look-ahead was last in.
    ff: FfPlan,
    /// The active damping's high-pass.
    damp: DampingState,
    /// The gain backoff's detector and level (kept by a restart, reset by `configure`).
    backoff: BackoffState,
    /// The feed-forward trims learned (kept by a restart, reset by `configure`).
    trim: FfTrimState,
}

/// The follower: validated coefficients, the table, and the loop state.
///
/// `repr(C)`, in this order: the tick's per-call state and the axes' coefficients and
/// runtime first, the table (kilobytes) last, so every field the tick reads lies within
/// the Cortex-M4's 12-bit load offset of the struct (measured: `follower_ff_1axis`).
#[derive(Clone, Debug)]
#[repr(C)]
pub struct Follower<const S: usize, const N: usize> {
    filter: MasterFilter,
    mf: MasterFilterCoeffs,
    cur_now: usize,
    cur_pred: usize,
    cur_ff: usize,
    /// The lead of the first Feedforward axis (its lookup is taken before the axis loop).
    ff_lead0: Option<i32>,
    /// Whether any axis runs the Paper law (only then is the prediction looked up).
    any_paper: bool,
    /// Whether every axis runs one law (the tick then takes that law's specialised path).
    modes: Modes,
    /// Whether the Feedforward axes have different leads (only then does the axis loop
    /// check for another lookup).
    ff_leads_differ: bool,
    ended: bool,
    /// Which end `ended` latched at (true: the last node): fixed while ended, so a master
    /// estimate ringing through zero speed after the end cannot swap the held position.
    end_high: bool,
    /// Whether [`Follower::configure`] succeeded once (see [`Follower::is_ready`]).
    configured: bool,
    axes: [AxisCoeffs; S],
    rt: [AxisRt; S],
    pred: Predictor,
    table: CamTable<S, N>,
}

impl<const S: usize, const N: usize> Follower<S, N> {
    /// A law buffer's starting value: no configuration (every coefficient zero, valve
    /// nulls at DAC code 0) and the [empty](CamTable::empty) table. `const` and all-zero
    /// bytes, so a static law buffer is `.bss`, initialised at link time and never
    /// through the stack; it is configured
    /// and given a table in place ([`Self::configure`], [`Self::load_table`] or
    /// [`Self::rebuild_table_from_nodes`]) before it runs. [`Self::is_ready`] tells the
    /// two apart.
    pub const fn unconfigured() -> Self {
        const AXIS: AxisCoeffs = AxisCoeffs {
            mode: ControlMode::Feedforward,
            kp: 0,
            ki_tick: 0,
            kd_tick: 0,
            i_zone: 0,
            i_limit: 0,
            kv_pos: 0,
            kv_neg: 0,
            ka: 0,
            lead_q16: 0,
            fe_limit: 0,
            valve: crate::valve::ValveCoeffs::UNSET,
            damping: DampingCoeffs::OFF,
            backoff: BackoffCoeffs::OFF,
            ff_trim: FfTrimCoeffs::OFF,
            extras: false,
        };
        const RT: AxisRt = AxisRt {
            st: PosState::RESET,
            fault: None,
            ff: FfPlan::ZEROED,
            damp: DampingState::RESET,
            backoff: BackoffState::RESET,
            trim: FfTrimState::RESET,
        };
        Self {
            axes: [AXIS; S],
            mf: MasterFilterCoeffs::UNSET,
            filter: MasterFilter::START,
            pred: Predictor::new(PredictorKind::Eq4),
            table: CamTable::empty(),
            cur_now: 0,
            cur_pred: 0,
            cur_ff: 0,
            any_paper: false,
            modes: Modes::Feedforward,
            ff_lead0: None,
            ff_leads_differ: false,
            rt: [RT; S],
            ended: false,
            end_high: false,
            configured: false,
        }
    }

    /// Validates the configuration and takes the table (by value: the host's form; a
    /// board builds its law in place, see [`Self::unconfigured`]).
    pub fn new(cfg: &FollowerConfig<S>, table: CamTable<S, N>) -> Result<Self, FollowerError> {
        let mut f = Self::unconfigured();
        f.configure(cfg)?;
        f.table = table;
        f.restart();
        Ok(f)
    }

    /// Validates `cfg` and, only if all of it is valid, makes it this follower's
    /// configuration, in place; the loop state restarts. On an error nothing changes.
    pub fn configure(&mut self, cfg: &FollowerConfig<S>) -> Result<(), FollowerError> {
        let mf = cfg
            .master_filter
            .build(cfg.period_us)
            .map_err(FollowerError::MasterFilter)?;
        let default = AxisConfig::default()
            .build(1000)
            .map_err(|error| FollowerError::Axis { axis: 0, error })?;
        let mut axes = [default; S];
        for (axis, (c, a)) in axes.iter_mut().zip(cfg.axes.iter()).enumerate() {
            *c = a
                .build(cfg.period_us)
                .map_err(|error| FollowerError::Axis { axis, error })?;
        }
        let ff_lead0 = axes
            .iter()
            .find(|a| a.mode == ControlMode::Feedforward)
            .map(|a| a.lead_q16);
        for (r, c) in self.rt.iter_mut().zip(axes.iter()) {
            *r = AxisRt {
                ff: FfPlan::new(c, mf.tps_q16()),
                ..AxisRt::default()
            };
        }
        self.mf = mf;
        self.pred = Predictor::new(cfg.predictor);
        self.any_paper = cfg.axes.iter().any(|a| a.mode == ControlMode::Paper);
        self.modes = if cfg.axes.iter().all(|a| a.mode == ControlMode::Feedforward) {
            Modes::Feedforward
        } else if cfg.axes.iter().all(|a| a.mode == ControlMode::Paper) {
            Modes::Paper
        } else {
            Modes::Mixed
        };
        self.ff_leads_differ = axes
            .iter()
            .filter(|a| a.mode == ControlMode::Feedforward)
            .any(|a| Some(a.lead_q16) != ff_lead0);
        self.ff_lead0 = ff_lead0;
        self.axes = axes;
        self.configured = true;
        self.restart();
        Ok(())
    }

    /// Makes this follower's table a copy of `table`, in place, and restarts the loop
    /// state (at a safe point: the caller checks that the axes are idle or the current
    /// table has ended).
    pub fn load_table(&mut self, table: &CamTable<S, N>) {
        self.table.copy_from(table);
        self.restart();
    }

    /// Validates `nodes` and rebuilds this follower's table from them in place
    /// ([`CamTable::rebuild_from_nodes`]); the loop state restarts. On an error the table
    /// is unchanged.
    pub fn rebuild_table_from_nodes(
        &mut self,
        nodes: &[crate::table::Node<S>],
        limits: &crate::table::TableLimits<S>,
    ) -> Result<(), crate::table::TableError> {
        self.table.rebuild_from_nodes(nodes, limits)?;
        self.restart();
        Ok(())
    }

    /// Configured and holding a built table: the law may run.
    pub fn is_ready(&self) -> bool {
        self.configured && !self.table.is_empty()
    }

    /// Slave `i`'s following-error limit (the law's own), µm (`None`: no such slave).
    pub fn following_error_limit_um(&self, i: usize) -> Option<PosUm> {
        self.axes.get(i).map(|c| PosUm::from_bits(c.fe_limit))
    }

    /// Every slave's table position at master `m` (an end's value beyond it), µm.
    pub fn table_position_um(&self, m: Master) -> [PosUm; S] {
        let mut cursor = 0;
        let lk = self.table.locate(&mut cursor, m);
        let mut out = [PosUm::ZERO; S];
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.table.value(&lk, i);
        }
        out
    }

    /// One period of position control toward `refs` instead of the table (manual motion,
    /// `runtime::manual`): per axis the axis law ([`crate::axis::position_law`]: the
    /// feedback on e = x_ref − x plus kv±·v + ka·a for the positional laws) and the
    /// output stage; an error beyond the axis' limit latches its fault as in
    /// [`Follower::tick`]. The master history is not touched (a run restarts it).
    pub fn tick_manual(
        &mut self,
        pos_um: &[PosUm; S],
        pressure_bar: &[[PressureBar; 2]; S],
        refs: &[PosRef; S],
    ) -> FollowerOutputs<S> {
        let mut out = FollowerOutputs::default();
        let axes = self
            .axes
            .iter()
            .zip(self.rt.iter_mut())
            .zip(pos_um.iter().zip(refs.iter()).zip(pressure_bar.iter()));
        for (i, ((c, rt), ((&x, r), p))) in axes.enumerate() {
            let err = r.x_ref_um.to_bits().saturating_sub(x.to_bits());
            if rt.fault.is_none() && err.saturating_abs() > c.fe_limit {
                rt.fault = Some(AxisFault::FollowingError);
                rt.st.reset();
                rt.damp = DampingState::RESET;
            }
            let (u, code) = if rt.fault.is_some() {
                (CmdLsb::ZERO, c.valve.null_code())
            } else {
                let u = position_law(c, &mut rt.st, r, x);
                // Manual: the damping after the law's clamp (the integrator's anti-windup
                // does not see it, unlike the following path's feed-forward entry; a
                // manual reference moves slowly, so its integrator rarely winds).
                let u = damped_cmd(&c.damping, &mut rt.damp, p, u, c.valve.clamp_lsb());
                (u, c.valve.output(u))
            };
            if let (Some(d), Some(cl), Some(t), Some(e), Some(f)) = (
                out.dac.get_mut(i),
                out.cmd_lsb.get_mut(i),
                out.target_um.get_mut(i),
                out.error_um.get_mut(i),
                out.fault.get_mut(i),
            ) {
                *d = code;
                *cl = u;
                *t = r.x_ref_um;
                *e = PosUm::from_bits(err);
                *f = rt.fault;
            }
        }
        out
    }

    /// The table in use.
    pub fn table(&self) -> &CamTable<S, N> {
        &self.table
    }

    /// Replaces the table (at a safe point: the caller checks that the axes are idle or
    /// the current table has ended) and restarts the loop state.
    pub fn replace_table(&mut self, table: CamTable<S, N>) -> CamTable<S, N> {
        let old = core::mem::replace(&mut self.table, table);
        self.restart();
        old
    }

    /// Forgets the master history, controller states and the end-of-table latch.
    pub fn restart(&mut self) {
        self.filter.reset();
        self.pred.reset();
        self.cur_now = 0;
        self.cur_pred = 0;
        self.cur_ff = 0;
        for rt in &mut self.rt {
            rt.st.reset();
            rt.ff.invalidate();
            rt.damp = DampingState::RESET;
            rt.backoff.restart();
        }
        self.ended = false;
    }

    /// The gain backoff's level of slave `i` ([`crate::axis::backoff`]: 0 = the set
    /// gain; 0 for an axis without one).
    pub fn backoff_level(&self, i: usize) -> u8 {
        self.rt.get(i).map_or(0, |r| r.backoff.level())
    }

    /// The feed-forward trim's ratios of slave `i`, `[negative, positive]` feed-forward,
    /// Q16 (65 536 = the calibrated gain; [`crate::axis::ff_trim`]).
    pub fn ff_trim_q16(&self, i: usize) -> [i32; 2] {
        self.rt.get(i).map_or([65_536; 2], |r| {
            [r.trim.ratio_q16(false), r.trim.ratio_q16(true)]
        })
    }

    /// Takes over `old`'s gain backoff levels and feed-forward trims for every slave
    /// whose coefficients are the same in both (a law rebuilt for a new table or another
    /// axis' setting keeps what this axis learned; a changed setting of the axis starts
    /// from the set values). The detectors' histories start afresh.
    pub fn carry_learned_from(&mut self, old: &Self) {
        for ((rt, c), (o_rt, o_c)) in self
            .rt
            .iter_mut()
            .zip(self.axes.iter())
            .zip(old.rt.iter().zip(old.axes.iter()))
        {
            if c == o_c {
                rt.backoff = o_rt.backoff;
                rt.backoff.restart();
                rt.trim = o_rt.trim;
            }
        }
    }

    /// Clears latched axis faults (the controller states start afresh).
    pub fn clear_faults(&mut self) {
        for rt in &mut self.rt {
            if rt.fault.take().is_some() {
                rt.st.reset();
                rt.damp = DampingState::RESET;
                rt.backoff.restart();
            }
        }
    }

    /// The filtered master estimate after the last tick (position, speed and
    /// acceleration now). Computed on demand — for telemetry and the host tools — rather
    /// than by every tick: the loop itself never needs it in these formats.
    pub fn master_estimate(&self) -> MasterEstimate {
        if self.modes == Modes::Paper {
            // Every axis Paper: no tracking filter runs; the predictor's differences.
            self.pred.estimate(self.mf.tps_q16())
        } else {
            self.filter.estimate_now(&self.mf)
        }
    }

    /// Whether the end-of-table latch is set.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// The safe output of every axis (valve null).
    pub fn safe_outputs(&self) -> [DacCode; S] {
        let mut out = [DacCode::NULL; S];
        for (o, c) in out.iter_mut().zip(self.axes.iter()) {
            *o = c.valve.null_code();
        }
        out
    }

    /// One control period (steps 3–8).
    pub fn tick(&mut self, inp: &FollowerInputs<S>) -> FollowerOutputs<S> {
        let mut out = FollowerOutputs::default();
        self.tick_into(inp, &mut out);
        out
    }

    /// [`Follower::tick`] writing into the caller's outputs (no copy of the outputs:
    /// the form the firmware's tick uses).
    pub fn tick_into(&mut self, inp: &FollowerInputs<S>, out: &mut FollowerOutputs<S>) {
        // One law on every axis: that law's path, with the per-axis dispatch resolved at
        // compile time (each path out of line, with its own register allocation).
        match self.modes {
            Modes::Feedforward => self.tick_path::<MODE_FF>(inp, out),
            Modes::Paper => self.tick_path::<MODE_PAPER>(inp, out),
            Modes::Mixed => self.tick_path::<MODE_MIXED>(inp, out),
        }
    }

    /// Steps 3–8 for laws `M` (`MODE_*`).
    #[inline(never)]
    fn tick_path<const M: u8>(&mut self, inp: &FollowerInputs<S>, out: &mut FollowerOutputs<S>) {
        // Every axis Paper: the paper's own predictor is the master estimate (SPEC §A
        // has no tracking filter); otherwise the tracking filter.
        if M == MODE_PAPER {
            let (jump, dir) = self.pred.observe(inp.master);
            self.tick_general::<M>(inp, out, jump, dir);
        } else {
            let jump = filter_step(&mut self.filter, &self.mf, inp.master);
            out.master_jump = jump;
            if M == MODE_FF && !self.ended && self.tick_ff_fast(inp, out) {
                return;
            }
            if M == MODE_FF {
                // Out of line: the fast path keeps its own register allocation.
                self.tick_general_outlined(inp, out, jump);
            } else {
                let dir = self.filter.direction();
                self.tick_general::<M>(inp, out, jump, dir);
            }
        }
    }

    /// [`Follower::tick_general`] for the Feedforward path, out of line.
    #[inline(never)]
    fn tick_general_outlined(
        &mut self,
        inp: &FollowerInputs<S>,
        out: &mut FollowerOutputs<S>,
        master_jump: bool,
    ) {
        let dir = self.filter.direction();
        self.tick_general::<MODE_FF>(inp, out, master_jump, dir);
    }

    /// Steps 3–8 after the master's update, off the Feedforward fast path: the end test,
    /// then the ended or the general lookups.
    #[inline(always)]
    fn tick_general<const M: u8>(
        &mut self,
        inp: &FollowerInputs<S>,
        out: &mut FollowerOutputs<S>,
        master_jump: bool,
        dir: i8,
    ) {
        let t = &self.table;
        if !self.ended
            && ((dir > 0 && inp.master >= t.master_last())
                || (dir < 0 && inp.master < t.master_first()))
        {
            self.ended = true;
            self.end_high = dir > 0;
        }
        out.end_of_table = self.ended;
        out.master_jump = master_jump;
        if M != MODE_MIXED && self.ended {
            self.tick_ended(inp, out, dir);
        } else {
            self.tick_mode::<M>(inp, out, dir);
        }
    }

    /// The Feedforward fast path (steps 3–5 of a tick where every axis is Feedforward and
    /// the table has not ended): the sampled master, the filtered master now and the first
    /// axis' look-ahead all in the cursor's segment — nearly every tick. The sampled
    /// master inside a segment is inside the table, so the end test of step 3 cannot fire
    /// (and needs no direction); both lookups and the feed-forward come from that segment
    /// (an axis with another lead takes its own lookup in the axis loop). Returns `false`,
    /// having written nothing, otherwise.
    #[inline(always)]
    fn tick_ff_fast(&mut self, inp: &FollowerInputs<S>, out: &mut FollowerOutputs<S>) -> bool {
        let Some(lead) = self.ff_lead0 else {
            return false;
        };
        let t = &self.table;
        let f = &self.filter;
        let mut v_q16 = 0;
        let Some(now) = t.span_pair(self.cur_now, inp.master, f.pos(), || {
            let (delta, v) = f.ahead_delta(lead);
            v_q16 = v;
            delta
        }) else {
            return false;
        };
        out.end_of_table = false;
        let ctx = TickCtx {
            now,
            pred: now,
            ff: FfRef {
                lead,
                at: Some((self.cur_now, now)),
                v_q16,
                acc_q32: self.filter.acc_q32(),
            },
            // No NextNode axis on this path.
            dir: 0,
            ended: false,
        };
        axes_loop::<S, N, MODE_FF>(
            Axes {
                axes: &self.axes,
                rt: &mut self.rt,
                filter: &self.filter,
                table: t,
                cur_ff: &mut self.cur_ff,
                check_leads: self.ff_leads_differ,
            },
            inp,
            out,
            ctx,
        );
        true
    }

    /// Steps 3–5 of an ended table (every slave holds its end), out of line.
    #[inline(never)]
    fn tick_ended(&mut self, inp: &FollowerInputs<S>, out: &mut FollowerOutputs<S>, dir: i8) {
        self.tick_mode::<MODE_MIXED>(inp, out, dir);
    }

    /// Steps 3–5 after the master's update, for laws `M` (`MODE_*`; `MODE_FF` and
    /// `MODE_PAPER` only while the table has not ended).
    #[inline(always)]
    fn tick_mode<const M: u8>(
        &mut self,
        inp: &FollowerInputs<S>,
        out: &mut FollowerOutputs<S>,
        dir: i8,
    ) {
        let t = &self.table;
        // Where the feedback looks: the filtered master now, or the end it stopped at.
        let m_now = match (self.ended, self.end_high) {
            // Paper path: the sampled master θ(k) itself (no tracking filter runs).
            (false, _) if M == MODE_PAPER => inp.master,
            (false, _) => self.filter.pos(),
            (true, true) => t.master_last(),
            (true, false) => t.master_first(),
        };
        let lk_now = t.locate(&mut self.cur_now, m_now);
        let lk_pred = if M == MODE_PAPER {
            // `observe` has pushed θ(k): the prediction θ̂(k+1) from the history.
            t.locate(&mut self.cur_pred, self.pred.predict())
        } else if M != MODE_FF && self.any_paper && !self.ended {
            let predicted = self.pred.update(inp.master);
            t.locate(&mut self.cur_pred, predicted)
        } else {
            lk_now
        };
        let (Some(now), Some(pred)) = (t.span(&lk_now), t.span(&lk_pred)) else {
            // Unreachable: `locate` only returns segments of this table.
            out.dac = self.safe_outputs();
            return;
        };
        // Feed-forward lookup, shared by the axes with the same lead (taken here for the
        // first Feedforward axis' lead, again only for an axis with another lead).
        let ff = match (M != MODE_PAPER, self.ff_lead0, self.ended) {
            (true, Some(lead), false) => ff_lookup_inline(&self.filter, t, &mut self.cur_ff, lead),
            _ => FfRef {
                lead: -1,
                at: None,
                v_q16: 0,
                acc_q32: 0,
            },
        };
        let ctx = TickCtx {
            now,
            pred,
            ff,
            dir,
            ended: self.ended,
        };
        axes_loop::<S, N, M>(
            Axes {
                axes: &self.axes,
                rt: &mut self.rt,
                filter: &self.filter,
                table: t,
                cur_ff: &mut self.cur_ff,
                check_leads: M != MODE_PAPER && self.ff_leads_differ && !self.ended,
            },
            inp,
            out,
            ctx,
        );
    }
}

/// What the axis loop works on: the follower's fields it reads or updates, borrowed apart
/// from the table the tick's lookups point into.
struct Axes<'a, 't, const S: usize, const N: usize> {
    axes: &'a [AxisCoeffs; S],
    rt: &'a mut [AxisRt; S],
    filter: &'a MasterFilter,
    table: &'t CamTable<S, N>,
    cur_ff: &'a mut usize,
    /// Whether an axis may need a lookup of its own (decided once, outside the loop).
    check_leads: bool,
}

/// Steps 4–5 for every axis, from the tick's lookups.
#[inline(always)]
fn axes_loop<'t, const S: usize, const N: usize, const M: u8>(
    a: Axes<'_, 't, S, N>,
    inp: &FollowerInputs<S>,
    out: &mut FollowerOutputs<S>,
    mut ctx: TickCtx<'t, S>,
) {
    for i in 0..S {
        let (Some(c), Some(rt), Some(x)) = (a.axes.get(i), a.rt.get_mut(i), inp.pos_um.get(i))
        else {
            continue;
        };
        let p = &inp.pressure_bar;
        if a.check_leads
            && (M == MODE_FF || c.mode == ControlMode::Feedforward)
            && c.lead_q16 != ctx.ff.lead
        {
            ctx.ff = ff_lookup(a.filter, a.table, a.cur_ff, c.lead_q16);
        }
        if S == 1 {
            // One axis: no loop to keep registers for, so no call.
            axis_step_inline::<S, M>(&ctx, c, rt, x.to_bits(), p, i, out);
        } else {
            axis_step::<S, M>(&ctx, c, rt, x.to_bits(), p, i, out);
        }
    }
}

/// Which laws the axes run (chosen once, at [`Follower::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Modes {
    /// Every axis `Feedforward`.
    Feedforward,
    /// Every axis `Paper`.
    Paper,
    /// Any other mix.
    Mixed,
}

/// `tick_mode` / `axis_step` law selector: every axis `Feedforward`, table not ended.
const MODE_FF: u8 = 0;
/// Every axis `Paper`, table not ended.
const MODE_PAPER: u8 = 1;
/// Any laws, ended or not: the per-axis `match`.
const MODE_MIXED: u8 = 2;

/// What every axis of one tick reads.
struct TickCtx<'a, const S: usize> {
    /// The table at the filtered master now (or the end it stopped at).
    now: Span<'a, S>,
    /// The table at the eq. 4 prediction (Paper axes).
    pred: Span<'a, S>,
    /// The feed-forward lookup.
    ff: FfRef<'a, S>,
    /// Direction of the master: 1, 0, −1.
    dir: i8,
    /// The end-of-table latch.
    ended: bool,
}

/// One axis of one tick (steps 4–5 of [`Follower`]): the law, the output stage and the
/// following-error check, written into `out[i]`. Kept out of line so the axis loop does
/// not spill the shared state around every axis.
#[inline(never)]
fn axis_step<const S: usize, const M: u8>(
    ctx: &TickCtx<'_, S>,
    c: &AxisCoeffs,
    rt: &mut AxisRt,
    x: i32,
    p: &[[PressureBar; 2]; S],
    i: usize,
    out: &mut FollowerOutputs<S>,
) {
    axis_step_inline::<S, M>(ctx, c, rt, x, p, i, out);
}

/// The active damping's command correction of a Feedforward axis, `I16F16` LSB
/// ([`crate::axis::damping`]; 0 when it is off). It enters the law as a (negative)
/// feed-forward, so the law's clamp and its integrator's anti-windup see it.
#[inline(always)]
fn damping_term<const S: usize>(
    c: &AxisCoeffs,
    st: &mut DampingState,
    p: &[[PressureBar; 2]; S],
    i: usize,
) -> i32 {
    if !c.damping.is_on() {
        return 0;
    }
    damping_term_on(c, st, p, i)
}

/// [`damping_term`] of a damped axis, out of line (an undamped axis pays one test).
#[inline(never)]
fn damping_term_on<const S: usize>(
    c: &AxisCoeffs,
    st: &mut DampingState,
    p: &[[PressureBar; 2]; S],
    i: usize,
) -> i32 {
    p.get(i).map_or(0, |p| damping_bits(&c.damping, st, p))
}

/// The Feedforward law of an axis with the gain backoff or the feed-forward trim (and
/// perhaps the active damping; [`AxisCoeffs::extras`]): the backoff's detector on the error,
/// then the law — feed-forward `ff` (`I16F16` LSB) at the trim's ratio, less the
/// damping's term — with the proportional, derivative and damping terms and the
/// integrator step at the backoff level's scales (1 at level 0), then the trim's
/// transfer from the integrator. Out of line: an axis without them pays one test.
#[inline(never)]
fn ff_law_extras<const S: usize>(
    c: &AxisCoeffs,
    rt: &mut AxisRt,
    err: i32,
    ff: i32,
    p: &[[PressureBar; 2]; S],
    i: usize,
) -> i32 {
    if c.backoff.is_on() {
        backoff::observe(&c.backoff, &mut rt.backoff, rt.st.error_change(err));
    }
    let d = rt.backoff.scale(damping_term(c, &mut rt.damp, p, i));
    let ff_trimmed = if c.ff_trim.is_on() {
        rt.trim.apply(ff)
    } else {
        ff
    };
    let u = positional_law_with::<true>(
        c,
        &mut rt.st,
        err,
        ff_trimmed.saturating_sub(d),
        &rt.backoff,
    );
    if c.ff_trim.is_on() {
        rt.st.offload_to_trim(&mut rt.trim, &c.ff_trim, ff);
    }
    u
}

/// The Feedforward law of a following axis with feed-forward `ff` (`I16F16` LSB; 0 once
/// the table has ended): the plain law after one test; with the gain backoff or the
/// trim out of line ([`ff_law_extras`]); with the active damping alone, the plain law
/// on `ff` less its term (measured: through `ff_law_extras` the damped axis cost 23
/// instructions more, `follower_ff_1axis_damped`).
#[inline(always)]
fn ff_law<const S: usize>(
    c: &AxisCoeffs,
    rt: &mut AxisRt,
    err: i32,
    ff: i32,
    p: &[[PressureBar; 2]; S],
    i: usize,
) -> i32 {
    if !c.extras {
        return positional_law_ff(c, &mut rt.st, err, ff);
    }
    if c.backoff.is_on() || c.ff_trim.is_on() {
        return ff_law_extras(c, rt, err, ff, p, i);
    }
    let ff = ff.saturating_sub(damping_term_on(c, &mut rt.damp, p, i));
    positional_law_ff(c, &mut rt.st, err, ff)
}

/// [`axis_step`]'s body.
#[inline(always)]
fn axis_step_inline<const S: usize, const M: u8>(
    ctx: &TickCtx<'_, S>,
    c: &AxisCoeffs,
    rt: &mut AxisRt,
    x: i32,
    p: &[[PressureBar; 2]; S],
    i: usize,
    out: &mut FollowerOutputs<S>,
) {
    if i >= S {
        // Never: the caller iterates 0..S (and this lets every index below go unchecked).
        return;
    }
    let target = ctx.now.value_bits(i);
    let err = target.saturating_sub(x);
    if rt.fault.is_none() && err.saturating_abs() > c.fe_limit {
        rt.fault = Some(AxisFault::FollowingError);
        rt.st.reset();
        rt.damp = DampingState::RESET;
    }
    let (u, code) = if rt.fault.is_some() {
        (0, c.valve.null_code())
    } else {
        let mode = match M {
            MODE_FF => (ControlMode::Feedforward, false),
            MODE_PAPER => (ControlMode::Paper, false),
            _ => (c.mode, ctx.ended),
        };
        let u = match mode {
            (ControlMode::Paper, true) => paper_law_bits(c, &mut rt.st, err),
            (ControlMode::Paper, false) => {
                let e = ctx.pred.value_bits(i).saturating_sub(x);
                paper_law_bits(c, &mut rt.st, e)
            }
            (ControlMode::Feedforward, false) => {
                let ff = match ctx.ff.at {
                    Some((seg, span)) => {
                        if !rt.ff.is_for(seg) {
                            enter(&mut rt.ff, seg, span.rise_bits(i), span.recip());
                        }
                        rt.ff.ff_q16(ctx.ff.v_q16, ctx.ff.acc_q32)
                    }
                    // The look-ahead beyond an end of the table: no feed-forward.
                    None => 0,
                };
                ff_law(c, rt, err, ff, p, i)
            }
            (ControlMode::NextNode, false) => {
                // The node at the far end of the segment in the direction of motion.
                let node = if ctx.dir >= 0 {
                    ctx.now.start_bits(i).saturating_add(ctx.now.rise_bits(i))
                } else {
                    ctx.now.start_bits(i)
                };
                positional_law_ff(c, &mut rt.st, node.saturating_sub(x), 0)
            }
            // Ended: no feed-forward (0 − d is d negated, saturating alike).
            (ControlMode::Feedforward, true) => ff_law(c, rt, err, 0, p, i),
            (ControlMode::NextNode, true) => positional_law_ff(c, &mut rt.st, err, 0),
        };
        // The laws clamp u to the valve's clamp: the output stage need not again.
        (u, c.valve.output_within_clamp(CmdLsb::from_bits(u)))
    };
    if let Some(o) = out.dac.get_mut(i) {
        *o = code;
    }
    if let Some(o) = out.cmd_lsb.get_mut(i) {
        *o = CmdLsb::from_bits(u);
    }
    if let Some(o) = out.target_um.get_mut(i) {
        *o = PosUm::from_bits(target);
    }
    if let Some(o) = out.error_um.get_mut(i) {
        *o = PosUm::from_bits(err);
    }
    if let Some(o) = out.fault.get_mut(i) {
        *o = rt.fault;
    }
}

/// The feed-forward's view of the table and the master for one lead.
#[derive(Clone, Copy)]
struct FfRef<'a, const S: usize> {
    /// The lead it was taken for, ticks Q16 (−1: none).
    lead: i32,
    /// The segment containing θ_f(k + lead) and its index (`None` beyond the ends: no
    /// feed-forward).
    at: Option<(usize, Span<'a, S>)>,
    /// Master speed at θ_f(k + lead), counts/tick, Q16.
    v_q16: i32,
    /// Master acceleration, counts/tick², Q32.
    acc_q32: i32,
}

/// Locates θ_f(k + lead) with the feed-forward cursor (out of line: the call inside the
/// axis loop, for an axis whose lead differs from the previous one's).
#[inline(never)]
fn ff_lookup<'a, const S: usize, const N: usize>(
    filter: &MasterFilter,
    t: &'a CamTable<S, N>,
    cursor: &mut usize,
    lead: i32,
) -> FfRef<'a, S> {
    ff_lookup_inline(filter, t, cursor, lead)
}

/// [`ff_lookup`]'s body (inlined for the first lead, before the loop).
#[inline(always)]
fn ff_lookup_inline<'a, const S: usize, const N: usize>(
    filter: &MasterFilter,
    t: &'a CamTable<S, N>,
    cursor: &mut usize,
    lead: i32,
) -> FfRef<'a, S> {
    let (delta, v_q16) = filter.ahead_delta(lead);
    let ahead = Master::from_bits(filter.pos().to_bits().wrapping_add(delta));
    let lk = t.locate_segment(cursor, ahead);
    let at = match lk.beyond {
        Beyond::Inside => t.span(&lk).map(|span| (lk.seg, span)),
        Beyond::Low | Beyond::High => None,
    };
    FfRef {
        lead,
        at,
        v_q16,
        acc_q32: filter.acc_q32(),
    }
}

/// Axis `i`'s feed-forward constants in segment `seg` (out of line and cold: once each
/// time the axis' look-ahead enters a segment).
#[cold]
#[inline(never)]
fn enter(ff: &mut FfPlan, seg: usize, dx: i32, (recip_m, recip_s): (u32, u32)) {
    ff.enter(seg, dx, recip_m, recip_s);
}

#[cfg(test)]
mod tests;

/// The tracking filter's update, out of line (measured: the Feedforward path is cheaper
/// with the filter's registers freed before the lookups). Returns the jump flag.
#[inline(never)]
fn filter_step(f: &mut MasterFilter, c: &MasterFilterCoeffs, m: Master) -> bool {
    f.update(c, m)
}
