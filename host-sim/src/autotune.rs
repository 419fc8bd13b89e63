//! The tuning procedure: one rule for every controller and every control period.
//!
//! The reference gain sets of `tangent.toml` are this module's output
//! (`host-sim run SCENARIO --controller C --period-us T --tune`); `docs/sim.md` has the
//! procedure in words and the resulting figures.
//!
//! **Position laws** (`traditional`, `paper`, `feedforward`, on each follower axis):
//!
//! 1. *Ultimate gain* `K_u`: the smallest proportional gain at which the oscillation
//!    after a position step of `min(500 µm, 500 LSB/Kp)` (small enough that the first
//!    command stays within a quarter of the valve's range: a saturating relay-like loop
//!    would hide the instability; axis at mid-stroke, P only, the law's own form:
//!    positional or incremental, encoder and DAC quantisation, one period of delay) no
//!    longer decays: its amplitude (half the peak-to-peak error) in the last quarter of the
//!    test is more than half the amplitude in the second quarter (half the test apart: 30
//!    periods, or 0.25 s, or 5 time constants of the P loop, whichever is longest) and
//!    above `10 µm + 1 LSB/Kp`
//!    (quantisation limit cycles do not count: a few encoder counts, and the hunting by one
//!    DAC LSB, 1/Kp µm of error, that a slow loop shows against the leakage creep; a
//!    steady offset is not an oscillation). Found by doubling from 0.01 LSB/µm, then 6
//!    bisections (±1.1 %).
//!    With `--margins box` (`Margins::Box`) the test runs on every machine of the
//!    robustness box (`crate::robust`: nominal, 16 corners, 8 face centres) and `K_u` is
//!    the smallest — on the reference machine the softest oil column, mass ×2 with bulk
//!    modulus ×0.5, at 0.49 LSB/µm against 2.22 nominal (1 ms).
//! 2. `Kp = K_u / 2` — a gain margin of 2 (6 dB) on the P loop. With `--margins
//!    measured` (`Margins::Measured`) Kp (Ki with it, step 3) is then lowered until the
//!    whole loop — PI, feed-forward, damping, valve, oil — *measures* gain margin ≥ 6 dB
//!    and phase margin ≥ 45° on the machine (`crate::margins`: a probe at the valve).
//! 3. `Ki = Kp·ω_c/4`, `ω_c = Kp·K_vel` the crossover of the P loop around the
//!    integrating plant, `K_vel` the valve's velocity gain (µm/s per LSB: the slower,
//!    retracting full-opening speed / 2047): the PI corner a quarter of the crossover.
//! 4. `Kd = 0`: the oil column is lightly damped and the derivative of a 1 µm encoder
//!    signal is mostly quantisation noise.
//! 5. Integral separation zone `m` = 10 mm (the integral only drops out on gross
//!    errors: start-up, faults); integrator clamp: full range, except `feedforward`
//!    whose integral only trims the feed-forward: the shortfall of the feed-forward on
//!    the robustness box's slowest valve (flow ×0.8 at 120 bar: 630 LSB on the reference
//!    machine), whichever the margins — the valve tolerance a machine builder specifies
//!    is what the integral must be allowed to make up (a clamp of 200 LSB leaves that
//!    machine at 66 µm, 630 at 23 µm, and 630 changes nothing on the nominal one).
//! 6. `feedforward` only: `kv± = 2047 / v_max±` from the closed-form full-opening speeds
//!    (PLANT.md's "known" valve), aimed past the valve lag `2ζ_v/ω_v`.
//! 7. Master filter bandwidth: 8 Hz (core default), or the filter's limit `0.2/T`
//!    (rounded down to 2 digits) where that is lower: at long periods the start and stop
//!    ramps of the master need all the bandwidth the filter allows.
//!
//! **Force law** (side press): the same rule on the force loop. `K_u` from the press
//! scenario itself (approach, contact, 1 s ramp, hold) with P-only force control: unstable
//! when the force still swings by more than 10 % of the set-point in the last second of
//! the hold, peak-to-peak about its least-squares line (a weak P loop still creeping
//! toward its balance — the approach's feed-forward carried over bumplessly keeps
//! pushing — is slow, not unstable: measured without the trend, the swing would take
//! that creep for an oscillation, and the rule would give `kp_lsb_per_n = 0.00064`). `Kp_F = K_u/2`, `Ki_F = Kp_F·ω_c/4` with `ω_c = Kp_F·k_c·K_vel`
//! (`k_c` the contact stiffness: N/s per LSB of the force plant). The approach gains
//! are the position rule's `Kp` for the `feedforward` law and `kv = 2047/v_max+`.

use crate::plant::{valve_command, HydraulicAxis};
use crate::scenario::gains::filter_limit_hz;
use crate::scenario::{
    AxisCfg, Controller, PositionGains, PredictorCfg, PressGains, Role, Scenario, ScenarioError,
    Tuning,
};
use crate::sim::board::{tick_loop, SampledBoard, SimHost, CYCLES_PER_US};
use crate::sim::{run as simulate, RunSpec};
use hydra_core::axis::{AxisConfig, ControlMode};
use hydra_core::runtime::{
    BootCause, Command, EncoderSample, MasterSource, Runtime, RuntimeConfig,
};
use hydra_core::units::{Counts, DacCode, PosUm};
use step_law::{StepLaw, STEP_DELAY_TICKS};

mod step_law;
use std::collections::BTreeMap;

/// Largest position step of the test, µm.
const STEP_UM: f64 = 500.0;
/// Largest first command of the test, LSB.
const STEP_LSB: f64 = 500.0;

/// `x` rounded to `digits` significant decimal digits: the `f64` nearest to the decimal
/// number, so the value printed into a scenario file parses back to exactly it.
fn round_sig(x: f64, digits: usize) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    format!("{:.*e}", digits.saturating_sub(1), x)
        .parse()
        .unwrap_or(x)
}

fn round2(x: f64) -> f64 {
    round_sig(x, 2)
}

fn round4(x: f64) -> f64 {
    round_sig(x, 4)
}

/// Where the step test runs: mid-stroke, or the middle of the free travel before a
/// contact.
pub fn test_position_m(axis: &AxisCfg) -> f64 {
    let free = axis
        .contact
        .as_ref()
        .map_or(axis.cylinder.stroke_mm, |c| c.position_mm);
    0.5 * free * 1e-3
}

/// Velocity gain of the valve-cylinder, µm/s per DAC LSB (the slower direction).
pub fn velocity_gain(axis: &AxisCfg, s: &Scenario) -> f64 {
    let p = axis.plant(s.supply(), 0.5 * axis.cylinder.stroke_mm * 1e-3);
    p.no_load_speed_m_per_s(true)
        .min(p.no_load_speed_m_per_s(false))
        * 1e6
        / f64::from(DacCode::MAX)
}

/// The outcome of one step test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepTest {
    /// Oscillation amplitude (half the peak-to-peak error) in the second quarter, µm.
    pub early_um: f64,
    /// Oscillation amplitude in the last quarter, µm.
    pub late_um: f64,
    /// The proportional gain tested, LSB/µm.
    pub kp: f64,
    /// The runtime latched a fault during the test (the loop diverged).
    pub faulted: bool,
}

impl StepTest {
    /// Whether the response decays (see the module docs).
    pub fn stable(&self) -> bool {
        let growing = self.late_um > 0.5 * self.early_um && self.late_um > 10.0 + 1.0 / self.kp;
        !(self.faulted || growing)
    }
}

/// Running min and max.
#[derive(Clone, Copy, Debug)]
struct Span(f64, f64);

impl Span {
    const EMPTY: Span = Span(f64::MAX, f64::MIN);
    fn add(&mut self, x: f64) {
        self.0 = self.0.min(x);
        self.1 = self.1.max(x);
    }
    fn amplitude(&self) -> f64 {
        if self.1 >= self.0 {
            0.5 * (self.1 - self.0)
        } else {
            0.0
        }
    }
}

/// A step of the position reference (`min(500 µm, 500 LSB/Kp)`) with P-only control of
/// `mode` at `period_us`: the [`StepLaw`] inside the runtime, one `TickLoop::run` per
/// period over the axis' encoder (the firmware's tick), its valve codes acting from the
/// next period. A fault the runtime latches (a diverging loop's `encoder_jump` at a long
/// period) counts as unstable.
pub fn step_test(
    s: &Scenario,
    axis: &AxisCfg,
    mode: ControlMode,
    period_us: u32,
    kp: f64,
) -> Result<StepTest, ScenarioError> {
    let invalid = |value: String, reason: String| ScenarioError::Invalid {
        key: format!("axis.{}", axis.name),
        value,
        reason,
    };
    let cfg = AxisConfig {
        gains: PositionGains {
            kp_lsb_per_um: kp as f32,
            ki_lsb_per_um_s: 0.0,
            kd_lsb_s_per_um: 0.0,
            i_zone_um: 1e6,
            i_limit_lsb: 2047.0,
            kv_pos_lsb_per_um_s: 0.0,
            kv_neg_lsb_per_um_s: 0.0,
            ka_lsb_per_um_s2: 0.0,
            following_error_um: 1e6,
            ..PositionGains::default()
        },
        mode,
        valve: axis.calibration,
        areas: crate::scenario::gains::piston_areas(axis),
    };
    let c = cfg
        .build(period_us)
        .map_err(|e| invalid(format!("{e:?}"), format!("step test at Kp = {kp}")))?;
    let x0_m = test_position_m(axis);
    let mut plant: HydraulicAxis = axis.plant(s.supply(), x0_m);
    let enc = axis.encoder();
    let h = s.step_s();
    let t = f64::from(period_us) * 1e-6;
    let steps = (t / h).round().max(1.0) as u64;
    let tau = 1.0 / (kp * velocity_gain(axis, s)).max(1e-9);
    let duration = (60.0 * t).max(10.0 * tau).clamp(0.5, 300.0);
    let n = (duration / t).ceil() as u64;
    let x_ref0 = enc.value(enc.count(x0_m)) * 1e6;
    let x_ref1 = x_ref0 + STEP_UM.min(STEP_LSB / kp);
    let law = StepLaw::new(
        c,
        PosUm::saturating_from_num(x_ref0),
        PosUm::saturating_from_num(x_ref1),
    );
    let rc = RuntimeConfig::<1> {
        period_us,
        master_source: MasterSource::Time,
        slave_um_per_count: [axis.sensors.encoder_um as f32],
        slave_max_speed_um_per_s: [crate::sim::control::plausible_speed_um_per_s(
            s, axis, period_us,
        )],
        following_error_limit_um: [1e6],
        ..RuntimeConfig::default()
    };
    let coeffs = rc
        .build()
        .map_err(|e| invalid(format!("{e:?}"), format!("the runtime at {period_us} µs")))?;
    let mut tl = tick_loop(Runtime::<_, 1, 2>::new(
        coeffs,
        Some(law),
        BootCause::Normal,
    ));
    let mut host = SimHost::default();
    host.queue(Command::Start);
    let count = |p: &HydraulicAxis| {
        let c = enc.count(p.x_m());
        Counts(c.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
    };
    let mut io = SampledBoard::<1, 2>::new(EncoderSample {
        master: Counts(0),
        slaves: [count(&plant)],
        master_edges: None,
    });
    let period_ns = period_us.saturating_mul(CYCLES_PER_US);
    let mut u_now = 0.0;
    let (mut early, mut late) = (Span::EMPTY, Span::EMPTY);
    let mut faulted = false;
    for k in 0..n {
        let x_ref = if k < u64::from(STEP_DELAY_TICKS) {
            x_ref0
        } else {
            x_ref1
        };
        io.enc.slaves = [count(&plant)];
        tl.run(&mut io, &mut host);
        host.now_ns = host.now_ns.wrapping_add(period_ns);
        if let Some(Some(e)) = host.take_refusal() {
            return Err(invalid(
                format!("{e:?}"),
                "the runtime refused Start".into(),
            ));
        }
        faulted |= tl.runtime().status().fault.is_some();
        let u_next = valve_command(io.codes[0].get(), io.enable);
        for _ in 0..steps {
            plant.step(u_now, h);
        }
        u_now = u_next;
        let e = x_ref - plant.x_m() * 1e6;
        let q = 4 * k / n;
        if q == 1 {
            early.add(e);
        } else if q == 3 {
            late.add(e);
        }
    }
    Ok(StepTest {
        early_um: early.amplitude(),
        late_um: late.amplitude(),
        kp,
        faulted,
    })
}

/// The ultimate gain of a law at a period (see the module docs), LSB/µm.
pub fn ultimate_gain(
    s: &Scenario,
    axis: &AxisCfg,
    mode: ControlMode,
    period_us: u32,
) -> Result<f64, ScenarioError> {
    let mut lo = 0.0;
    let mut hi = 0.01;
    while step_test(s, axis, mode, period_us, hi)?.stable() {
        lo = hi;
        hi *= 2.0;
        if hi > 25.0 {
            // Beyond 25 LSB/µm the test step would be under 20 encoder counts.
            return Ok(25.0);
        }
    }
    if lo == 0.0 {
        return Ok(hi);
    }
    for _ in 0..6 {
        let mid = (lo * hi).sqrt();
        if step_test(s, axis, mode, period_us, mid)?.stable() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(hi)
}

/// The ultimate gain over the robustness box ([`crate::robust`]): the smallest `K_u` of
/// the nominal machine, the box's 16 corners and its 8 face centres (each the step test
/// on that plant), and the machine it was found on. A force axis is not varied by the
/// box: its nominal `K_u`.
pub fn box_ultimate_gain(
    s: &Scenario,
    axis: &AxisCfg,
    mode: ControlMode,
    period_us: u32,
) -> Result<(f64, String), ScenarioError> {
    use rayon::prelude::*;
    if axis.role != Role::Follower {
        return Ok((ultimate_gain(s, axis, mode, period_us)?, "nominal".into()));
    }
    let nominal_supply = s.supply.supply_bar;
    let found = crate::robust::cases(s)
        .par_iter()
        .map(|v| {
            let sv = v.apply(s);
            let a = sv.axes.iter().find(|a| a.name == axis.name).unwrap_or(axis);
            Ok((
                ultimate_gain(&sv, a, mode, period_us)?,
                v.label(nominal_supply),
            ))
        })
        .collect::<Result<Vec<_>, ScenarioError>>()?;
    Ok(found.into_iter().fold(
        (f64::MAX, String::new()),
        |m, k| if k.0 < m.0 { k } else { m },
    ))
}

/// The feed-forward integrator's clamp, LSB: the command the feed-forward lacks on the
/// box's slowest valve (rated flow ×0.8 at 120 bar: `(1 − 0.8·√(120/p_s))·2047`), so
/// the integral can make up the whole shortfall there; at least 200 LSB.
pub fn ff_integrator_limit_lsb(s: &Scenario) -> f64 {
    let slow = crate::robust::FLOW.0
        * (crate::robust::SUPPLY_BAR.0 / s.supply.supply_bar.max(1.0))
            .min(1.0)
            .sqrt();
    round2(((1.0 - slow) * f64::from(DacCode::MAX)).max(200.0))
}

/// Master-filter bandwidth of the rule, Hz.
pub fn master_filter_hz(period_us: u32) -> f64 {
    filter_limit_hz(period_us).min(8.0)
}

/// Which machine the rule's gain margin of 2 (6 dB) holds on, and how it is judged
/// (`Box`: [`box_ultimate_gain`]; `Measured`: [`meet_measured_margins`]). The variants'
/// doc lines are `--margins`' help: plain words, no links.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Margins {
    /// The scenario's own machine (the shipped reference sets).
    #[default]
    Nominal,
    /// Every machine of the robustness box (mass, oil, valve flow, supply off nominal).
    Box,
    /// The scenario's own machine, then Kp (and Ki with it) lowered until the loop
    /// measures gain margin ≥ 6 dB and phase margin ≥ 45° (the probe of `host-sim margins`).
    Measured,
}

impl Margins {
    /// The value's name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Nominal => "nominal",
            Self::Box => "box",
            Self::Measured => "measured",
        }
    }

    /// What `K_u` is the minimum over, for the printed comment.
    pub fn ku_note(&self) -> &'static str {
        match self {
            Self::Nominal => "",
            Self::Box => ", smallest over the robustness box",
            Self::Measured => ", then lowered to measured margins ≥ 6 dB / 45°",
        }
    }
}

/// The gain margin [`Margins::Measured`] asks for, dB.
pub const MIN_GAIN_MARGIN_DB: f64 = 6.0;
/// The phase margin [`Margins::Measured`] asks for, degrees.
pub const MIN_PHASE_MARGIN_DEG: f64 = 45.0;

/// Lowers follower `axis`' Kp in `t` (Ki following as Kp², step 3's PI corner) until
/// the loop, measured on `s` by the valve probe ([`crate::margins`]), has gain margin
/// ≥ [`MIN_GAIN_MARGIN_DB`] and phase margin ≥ [`MIN_PHASE_MARGIN_DEG`]: each round Kp
/// falls by the gain margin's shortfall plus 0.3 dB (× 0.85 for a phase margin short, ×
/// 0.5 when the loop oscillates), at most 8 rounds. Returns the margins met.
pub fn meet_measured_margins(
    s: &Scenario,
    t: &mut Tuning,
    axis: &AxisCfg,
) -> Result<crate::margins::LoopMargins, ScenarioError> {
    use crate::margins::{measure, MarginError};
    let table = s.load_table(None)?;
    let kvel = velocity_gain(axis, s);
    let mut last = String::from("not measured");
    for _ in 0..8 {
        let mut sc = s.clone();
        sc.tuning
            .retain(|x| !(x.controller == t.controller && x.period_us == t.period_us));
        sc.tuning.push(t.clone());
        let factor = match measure(&sc, &table, t.controller, t.period_us, Some(&axis.name)) {
            Ok(m) => {
                // No crossover in the measured range (up to 0.4/T): no limit found there.
                let (gm, pm) = (
                    m.gain_margin_db.unwrap_or(f64::INFINITY),
                    m.phase_margin_deg.unwrap_or(180.0),
                );
                if gm >= MIN_GAIN_MARGIN_DB && pm >= MIN_PHASE_MARGIN_DEG {
                    return Ok(m);
                }
                last = format!("gain margin {gm:.1} dB, phase margin {pm:.1}°");
                let g = if gm < MIN_GAIN_MARGIN_DB {
                    10f64.powf((gm - MIN_GAIN_MARGIN_DB - 0.3) / 20.0)
                } else {
                    1.0
                };
                g * if pm < MIN_PHASE_MARGIN_DEG { 0.85 } else { 1.0 }
            }
            Err(e @ MarginError::Unstable { .. }) => {
                last = e.to_string();
                0.5
            }
            Err(MarginError::Scenario(e)) => return Err(e),
            Err(e) => {
                return Err(ScenarioError::Invalid {
                    key: "tuning".into(),
                    value: axis.name.clone(),
                    reason: e.to_string(),
                })
            }
        };
        let g = t
            .axes
            .get_mut(&axis.name)
            .ok_or_else(|| ScenarioError::Invalid {
                key: "tuning".into(),
                value: axis.name.clone(),
                reason: "no gain set for the axis".into(),
            })?;
        // Two significant digits: a step the rounding would undo is one unit of the
        // last digit instead (NaN margins count as short: × 0.85).
        // (Compared as stored: the f32 of 1.1 is above the f64 1.1.)
        let kp0 = round2(f64::from(g.kp_lsb_per_um));
        let factor = if factor.is_finite() { factor } else { 0.85 };
        let mut kp = round2(kp0 * factor);
        if kp >= kp0 {
            kp = round2(kp0 - 10f64.powf(kp0.log10().floor() - 1.0));
        }
        if !(kp > 0.0 && (kp as f32) < g.kp_lsb_per_um) {
            break;
        }
        g.kp_lsb_per_um = kp as f32;
        g.ki_lsb_per_um_s = round2(kp * kp * kvel / 4.0) as f32;
    }
    Err(ScenarioError::Invalid {
        key: "tuning".into(),
        value: axis.name.clone(),
        reason: format!(
            "no Kp within 8 rounds gave gain margin ≥ {MIN_GAIN_MARGIN_DB} dB and phase margin ≥ {MIN_PHASE_MARGIN_DEG}° (last: {last})"
        ),
    })
}

/// Position gains of one follower axis by the rule (the shipped sets: [`Margins::Nominal`]).
pub fn position_gains(
    s: &Scenario,
    axis: &AxisCfg,
    controller: Controller,
    period_us: u32,
) -> Result<(PositionGains, f64), ScenarioError> {
    position_gains_with(s, axis, controller, period_us, Margins::Nominal)
}

/// Position gains of one follower axis by the rule, the gain margin on `margins`.
pub fn position_gains_with(
    s: &Scenario,
    axis: &AxisCfg,
    controller: Controller,
    period_us: u32,
    margins: Margins,
) -> Result<(PositionGains, f64), ScenarioError> {
    let ku = match margins {
        Margins::Nominal | Margins::Measured => {
            ultimate_gain(s, axis, controller.mode(), period_us)?
        }
        Margins::Box => box_ultimate_gain(s, axis, controller.mode(), period_us)?.0,
    };
    let kp = round2(ku / 2.0);
    let kvel = velocity_gain(axis, s);
    let ki = round2(kp * kp * kvel / 4.0);
    let p = axis.plant(s.supply(), 0.5 * axis.cylinder.stroke_mm * 1e-3);
    let ff = controller == Controller::Feedforward;
    // The feed-forward law at 1 ms carries the shipped gain backoff and trim.
    let shipped_extras = ff && period_us <= 1000;
    let lag_us =
        2.0 * axis.valve.damping / (2.0 * std::f64::consts::PI * axis.valve.bandwidth_hz) * 1e6;
    Ok((
        PositionGains {
            kp_lsb_per_um: kp as f32,
            ki_lsb_per_um_s: ki as f32,
            kd_lsb_s_per_um: 0.0,
            i_zone_um: 10_000.0,
            i_limit_lsb: if ff {
                ff_integrator_limit_lsb(s) as f32
            } else {
                2047.0
            },
            kv_pos_lsb_per_um_s: if ff {
                round4(2047.0 / (p.no_load_speed_m_per_s(true) * 1e6)) as f32
            } else {
                0.0
            },
            kv_neg_lsb_per_um_s: if ff {
                round4(2047.0 / (p.no_load_speed_m_per_s(false) * 1e6)) as f32
            } else {
                0.0
            },
            ka_lsb_per_um_s2: 0.0,
            valve_lag_us: lag_us.round() as f32,
            following_error_um: 20_000.0,
            // The gain backoff (core `axis::backoff`) and the feed-forward trim
            // (`axis::ff_trim`) on the feed-forward law, as measured on the robustness
            // box at 1 ms (docs/results.md, "Robustness"); not measured at longer
            // periods, where they stay off.
            osc_band_um: if shipped_extras {
                hydra_core::profile::OSC_BAND_UM
            } else {
                0.0
            },
            ff_trim_tau_s: if shipped_extras {
                hydra_core::profile::FF_TRIM_TAU_S
            } else {
                0.0
            },
            ..PositionGains::default()
        },
        ku,
    ))
}

/// A scenario with only this force axis, for the press tests.
fn press_only(s: &Scenario, axis: &AxisCfg, period_us: u32, g: &PressGains) -> Scenario {
    let mut p = s.clone();
    p.axes = vec![axis.clone()];
    p.tuning = vec![Tuning {
        controller: Controller::Feedforward,
        period_us,
        master_filter_hz: master_filter_hz(period_us),
        predictor: PredictorCfg::Eq4,
        axes: BTreeMap::new(),
        press: BTreeMap::from([(axis.name.clone(), *g)]),
    }];
    p
}

/// Whether the P-only force loop holds (see the module docs).
fn press_stable(
    s: &Scenario,
    axis: &AxisCfg,
    period_us: u32,
    g: &PressGains,
) -> Result<bool, ScenarioError> {
    let press = axis.press.as_ref().map_or(20_000.0, |p| p.force_set_n);
    let mut p = press_only(s, axis, period_us, g);
    let (start, speed) = axis.press.as_ref().map_or((0.0, 1.0), |pc| {
        (axis.x0_mm.unwrap_or(0.0), pc.approach_speed_mm_per_s)
    });
    let contact = axis
        .contact
        .as_ref()
        .map_or(axis.cylinder.stroke_mm, |c| c.position_mm);
    let ramp = axis.press.as_ref().map_or(1.0, |pc| pc.force_ramp_s);
    let t_contact = ((contact - start) / speed).max(0.0);
    let duration = t_contact + ramp + 4.0;
    p.sim.duration_s = Some(duration);
    let r = simulate(
        &p,
        &crate::die::DieTable::default().table(),
        &RunSpec {
            controller: Controller::Feedforward,
            period_us,
            trace_every_s: Some(1e-3),
        },
        &mut |_| {},
    )?;
    let tr = r.trace.unwrap_or_default();
    let t = tr.column("t_s").unwrap_or_default();
    let f = tr
        .column(&format!("{}_force_n", axis.name))
        .unwrap_or_default();
    let last: Vec<(f64, f64)> = t
        .iter()
        .zip(&f)
        .filter(|(t, _)| **t >= duration - 1.0)
        .map(|(t, f)| (*t, *f))
        .collect();
    Ok(swing_about_trend(&last).is_some_and(|s| s < 0.1 * press))
}

/// The peak-to-peak of `(t, y)` about its least-squares line, or `None` if it is not
/// finite or there are fewer than 2 samples: an oscillation, not a slow creep (a weak
/// P-only force loop still creeping toward its balance is not unstable).
fn swing_about_trend(s: &[(f64, f64)]) -> Option<f64> {
    let n = s.len() as f64;
    if s.len() < 2 {
        return None;
    }
    let (mt, my) = s
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, y)| (a + t / n, b + y / n));
    let (sty, stt) = s.iter().fold((0.0, 0.0), |(a, b), (t, y)| {
        (a + (t - mt) * (y - my), b + (t - mt) * (t - mt))
    });
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    let (lo, hi) = s.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (t, y)| {
        let r = y - my - slope * (t - mt);
        (lo.min(r), hi.max(r))
    });
    let swing = hi - lo;
    swing.is_finite().then_some(swing)
}

/// Press gains of one force axis by the rule; returns the gains and the force loop's
/// ultimate gain (LSB/N).
pub fn press_gains(
    s: &Scenario,
    axis: &AxisCfg,
    period_us: u32,
) -> Result<(PressGains, f64), ScenarioError> {
    let (approach, _) = position_gains(s, axis, Controller::Feedforward, period_us)?;
    let mut g = PressGains {
        kp_lsb_per_um: approach.kp_lsb_per_um,
        kv_lsb_per_um_s: approach.kv_pos_lsb_per_um_s,
        kp_lsb_per_n: 1e-4,
        ki_lsb_per_n_s: 0.0,
    };
    // The bisection runs in f64; each trial gain is the f32 the press law is given.
    let (mut lo, mut hi) = (0.0f64, 1e-4f64);
    while press_stable(s, axis, period_us, &g)? {
        lo = hi;
        hi *= 2.0;
        g.kp_lsb_per_n = hi as f32;
        if hi > 100.0 {
            break;
        }
    }
    if lo > 0.0 {
        for _ in 0..6 {
            let mid = (lo * hi).sqrt();
            g.kp_lsb_per_n = mid as f32;
            if press_stable(s, axis, period_us, &g)? {
                lo = mid;
            } else {
                hi = mid;
            }
        }
    }
    let ku = hi;
    let kc = axis.contact.as_ref().map_or(0.0, |c| c.stiffness_n_per_m);
    let kvel_m = velocity_gain(axis, s) * 1e-6; // m/s per LSB
    let kp = round2(ku / 2.0);
    g.kp_lsb_per_n = kp as f32;
    g.ki_lsb_per_n_s = round2(kp * kp * kc * kvel_m / 4.0) as f32;
    Ok((g, ku))
}

/// A full gain set for a controller at a period: every follower and force axis of the
/// scenario. Also returns the ultimate gains found, by axis name.
pub fn tune(
    s: &Scenario,
    controller: Controller,
    period_us: u32,
    margins: Margins,
) -> Result<(Tuning, Vec<(String, f64)>), ScenarioError> {
    let mut t = Tuning {
        controller,
        period_us,
        master_filter_hz: master_filter_hz(period_us),
        predictor: PredictorCfg::Eq4,
        axes: BTreeMap::new(),
        press: BTreeMap::new(),
    };
    let mut ku = Vec::new();
    for a in &s.axes {
        match a.role {
            Role::Follower => {
                let (g, k) = position_gains_with(s, a, controller, period_us, margins)?;
                t.axes.insert(a.name.clone(), g);
                ku.push((a.name.clone(), k));
            }
            Role::Force => {
                let (g, k) = press_gains(s, a, period_us)?;
                t.press.insert(a.name.clone(), g);
                ku.push((a.name.clone(), k));
            }
        }
    }
    if margins == Margins::Measured {
        for a in s.axes.iter().filter(|a| a.role == Role::Follower) {
            meet_measured_margins(s, &mut t, a)?;
        }
    }
    Ok((t, ku))
}

/// A number with at most 4 significant digits, without binary-float artefacts.
fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    let decimals = (3 - mag).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The TOML body of one gain set: flat structs of numbers always serialise.
fn gains_toml<T: serde::Serialize>(g: &T) -> String {
    toml::to_string(g).unwrap_or_else(|e| format!("# not serialisable: {e}\n"))
}

/// A gain set as the table `[path]`: core's struct as toml serialises it (f32 in its
/// shortest decimal form, which parses back to exactly the same f32), its nested tables
/// (`[backoff]`) moved under `path` (`[path.backoff]`).
pub fn gains_table<T: serde::Serialize>(path: &str, g: &T) -> String {
    let mut out = format!("[{path}]\n");
    for line in gains_toml(g).lines() {
        match line.strip_prefix('[') {
            Some(sub) if line.ends_with(']') => out.push_str(&format!("[{path}.{sub}")),
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

/// The TOML text of a gain set (what `--tune` prints).
pub fn to_toml(t: &Tuning) -> String {
    let mut s = format!(
        "[[tuning]]\ncontroller = \"{}\"\nperiod_us = {}\nmaster_filter_hz = {}\n",
        t.controller.name(),
        t.period_us,
        num(t.master_filter_hz)
    );
    for (name, g) in &t.axes {
        s.push_str(&gains_table(&format!("tuning.axes.{name}"), g));
    }
    for (name, g) in &t.press {
        s.push_str(&gains_table(&format!("tuning.press.{name}"), g));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The step test brackets the ultimate gain of the reference tangent axis at 1 ms:
    /// a decaying response at 1.5 LSB/µm, a sustained oscillation at 3 LSB/µm, for the
    /// positional and the incremental law alike.
    #[test]
    fn step_test_brackets_the_ultimate_gain() {
        let s = Scenario::default();
        let a = &s.axes[0];
        for mode in [ControlMode::Feedforward, ControlMode::Paper] {
            let ok = step_test(&s, a, mode, 1000, 1.5).unwrap();
            let bad = step_test(&s, a, mode, 1000, 3.0).unwrap();
            assert!(ok.stable() && ok.late_um < 5.0, "{mode:?} {ok:?}");
            assert!(!bad.stable() && bad.late_um > 500.0, "{mode:?} {bad:?}");
        }
    }

    /// The box's binding machine is the softest oil column (mass ×2, bulk modulus ×0.5:
    /// half the hydraulic frequency); the shipped 1 ms gains oscillate there, the box
    /// rule's do not.
    #[test]
    fn the_box_rule_holds_on_the_softest_machine_where_the_shipped_gains_oscillate() {
        let s = Scenario::default();
        let a = &s.axes[0];
        let nominal = ultimate_gain(&s, a, ControlMode::Feedforward, 1000).unwrap();
        let (ku, worst) = box_ultimate_gain(&s, a, ControlMode::Feedforward, 1000).unwrap();
        // docs/results.md's figures ("Robustness"): 0.49 in the box against 2.22
        // nominal (±2 %).
        assert!((ku / 0.4882 - 1.0).abs() < 0.02, "box K_u {ku}");
        assert!(
            (nominal / 2.2238 - 1.0).abs() < 0.02,
            "nominal K_u {nominal}"
        );
        assert!(worst.contains("mass×2 bulk×0.5"), "{worst}");
        let (g, _) =
            position_gains_with(&s, a, Controller::Feedforward, 1000, Margins::Box).unwrap();
        assert_eq!(g.i_limit_lsb, 630.0);
        let soft = crate::robust::Variant {
            mass: 2.0,
            bulk: 0.5,
            ..crate::robust::Variant::nominal(&s)
        };
        let table = s.load_table(None).unwrap();
        let mut shipped = soft.apply(&s);
        shipped.sim.duration_s = Some(8.0);
        // The shipped gains alone: without the gain backoff, which would hold them.
        for t in shipped.tuning.iter_mut() {
            for x in t.axes.values_mut() {
                x.osc_band_um = 0.0;
                x.ff_trim_tau_s = 0.0;
            }
        }
        let mut boxed = shipped.clone();
        for t in boxed.tuning.iter_mut() {
            if let Some(x) = t.axes.get_mut(&a.name) {
                *x = g;
            }
        }
        let run = |sc: &Scenario| {
            let spec = RunSpec {
                controller: Controller::Feedforward,
                period_us: 1000,
                trace_every_s: None,
            };
            simulate(sc, &table, &spec, &mut |_| {}).unwrap()
        };
        let excess = |r: &crate::sim::RunReport| {
            r.oscillation.iter().map(|o| o.excess()).sum::<u32>() + r.faults.len() as u32
        };
        assert!(excess(&run(&shipped)) > 10, "the shipped gains shake");
        assert_eq!(excess(&run(&boxed)), 0, "the box gains hold");
    }

    #[test]
    fn numbers_print_short() {
        assert_eq!(num(2.3000000000000003), "2.3");
        assert_eq!(num(0.013890000000000001), "0.01389");
        assert_eq!(num(4244.0), "4244");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(round2(0.000371234)), "0.00037");
    }

    /// `--margins measured`: the shipped 1 ms feed-forward set (K_u/2) measures a
    /// 5.3 dB gain margin with its PI and feed-forward (docs/results.md, "Robustness"); the rule
    /// lowers Kp until the probe measures ≥ 6 dB and ≥ 45°, and no further than one
    /// round past it.
    #[test]
    fn measured_margins_lower_the_shipped_gain_until_they_hold() {
        let s = Scenario::default();
        let a = &s.axes[0];
        let mut t = crate::scenario::reference_tuning()
            .into_iter()
            .find(|t| t.controller == Controller::Feedforward && t.period_us == 1000)
            .unwrap();
        let kp0 = t.axes[&a.name].kp_lsb_per_um;
        let m = meet_measured_margins(&s, &mut t, a).unwrap();
        let g = &t.axes[&a.name];
        let (gm, pm) = (m.gain_margin_db.unwrap(), m.phase_margin_deg.unwrap());
        assert!(
            gm >= MIN_GAIN_MARGIN_DB && pm >= MIN_PHASE_MARGIN_DEG,
            "{m:#?}"
        );
        assert!(
            g.kp_lsb_per_um < kp0 && g.kp_lsb_per_um > 0.8 * kp0,
            "{g:?}"
        );
        // Ki follows Kp² (the PI corner a quarter of the crossover).
        let ki = round2(f64::from(g.kp_lsb_per_um).powi(2) * velocity_gain(a, &s) / 4.0);
        assert_eq!(g.ki_lsb_per_um_s, ki as f32);
    }
}
