//! Gain and phase margins of a follower's position loop, measured on the simulated
//! machine: a sinusoidal probe at its valve ([`crate::sim::probe`]), one run per
//! frequency on a logarithmic grid, while the table moves at speed.
//!
//! ```text
//! L(f_i) = −U_ctrl/U_app           the loop broken at the sampled command (all of it:
//!                                  law, active damping, hold, delay, the plant)
//! gain crossover f_c: the first f where |L| falls through 1;     PM = 180° + ∠L(f_c)
//! phase crossover f_180: the first f above f_c where ∠L falls through −180° (mod 360°);
//!                                  GM = −20·log10|L(f_180)| dB
//! modulus margin: min_f |1 + L|    (the closest approach to −1; 1/M_s)
//! ```
//!
//! A lightly damped oil column can lift |L| above 1 again near its own frequency with
//! the phase already past −180° (a phase-stabilised resonance on the reference
//! machine's shipped set, docs/results.md, "Robustness"). The classic margins at the first
//! crossings do not see how close that loop passes to −1; the modulus margin does, and
//! the points show it. Around the grid point closest to −1 the sweep adds [`REFINE`]
//! frequencies across its two intervals (a sharp peak falls between grid points).
//! Between points |L| (dB) and ∠L are interpolated linearly in log f. The gain
//! backoff is off for the measurement (it would take the probe for an oscillation), and
//! so is the feed-forward trim (it moves the integrator's content, not the loop's gain):
//! the margins are the set gains'. A loop that oscillates on the machine has no margin to
//! measure: a loop that, without the probe, latches a fault or reverses more often than
//! its table, or latches a fault with it, is refused; so is a run without a finite
//! response (`NoResponse`). `margins_of` drops non-finite points.
//! The probe's amplitude is 2 % of the valve's opening — large against the sensors'
//! quantisation, small against the valve's and the oil's nonlinearity.

use crate::camfile::CamCsv;
use crate::scenario::{Controller, Role, Scenario, ScenarioError};
use crate::sim::probe::Probe;
use crate::sim::{run_probed, RunSpec};
use rayon::prelude::*;

/// The probe's amplitude, valve units (1 = full opening).
pub const PROBE_AMPLITUDE: f64 = 0.02;
/// Frequencies of the logarithmic grid.
pub const POINTS: usize = 64;
/// Frequencies added across the two grid intervals around the point closest to −1.
pub const REFINE: usize = 8;
/// The highest frequency, Hz (below 0.4 of the sampling rate at long periods).
pub const MAX_FREQ_HZ: f64 = 150.0;

/// One measured frequency.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Point {
    /// f, Hz.
    pub freq_hz: f64,
    /// |L|, dB.
    pub mag_db: f64,
    /// ∠L, degrees, unwrapped along f from the first point's value in (−360°, 0°].
    pub phase_deg: f64,
    /// |1 + L|.
    pub distance_to_minus_one: f64,
}

/// The margins of one follower's loop.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopMargins {
    /// The axis.
    pub axis: String,
    /// The frequency response, f ascending.
    pub points: Vec<Point>,
    /// f_c, Hz (`None`: |L| never falls through 1 in the measured range).
    pub gain_crossover_hz: Option<f64>,
    /// PM, degrees.
    pub phase_margin_deg: Option<f64>,
    /// f_180, Hz (`None`: ∠L does not reach −180° above f_c in the measured range).
    pub phase_crossover_hz: Option<f64>,
    /// GM, dB.
    pub gain_margin_db: Option<f64>,
    /// min |1 + L| over the points (1/M_s; 0.5 ⇔ M_s = 6 dB).
    pub modulus_margin: f64,
}

/// Why the margins cannot be measured.
#[derive(Debug, thiserror::Error)]
pub enum MarginError {
    /// The scenario cannot run.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// No follower of that name.
    #[error("no follower axis `{0}` in the scenario")]
    NoAxis(String),
    /// The loop is not stable on this machine.
    #[error(
        "the loop of `{axis}` oscillates on this machine ({why}): it has no margin to measure"
    )]
    Unstable {
        /// The axis.
        axis: String,
        /// A fault's name or the reversals counted, and in which run.
        why: String,
    },
    /// No finite response at a frequency (the valves were never enabled in that run).
    #[error("the probe at {freq_hz:.1} Hz met no response: the loop did not control the valve")]
    NoResponse {
        /// The probe's frequency.
        freq_hz: f64,
    },
    /// The table's travel at speed is shorter than the measurement.
    #[error("the master is at speed until {at_speed_s:.1} s, the measurement needs it until {needed_s:.1} s: a longer travel or a slower master")]
    TooShort {
        /// The end of the longest probe's run, s.
        needed_s: f64,
        /// The start of the master's stop ramp, s.
        at_speed_s: f64,
    },
}

/// The grid: `POINTS` frequencies from f_max/75 (at most 2 Hz) to f_max =
/// min(`MAX_FREQ_HZ`, 0.4/T), logarithmic.
pub fn grid(period_us: u32) -> Vec<f64> {
    let f_max = MAX_FREQ_HZ.min(0.4e6 / f64::from(period_us));
    let f_min = 2.0f64.min(f_max / 75.0);
    let r = (f_max / f_min).powf(1.0 / (POINTS - 1) as f64);
    (0..POINTS).map(|i| f_min * r.powi(i as i32)).collect()
}

/// Measures the margins of follower `axis` (`None`: the first) of `s` with `controller`
/// at `period_us`.
pub fn measure(
    s: &Scenario,
    table: &CamCsv,
    controller: Controller,
    period_us: u32,
    axis: Option<&str>,
) -> Result<LoopMargins, MarginError> {
    let followers: Vec<&str> = s
        .axes
        .iter()
        .filter(|a| a.role == Role::Follower)
        .map(|a| a.name.as_str())
        .collect();
    let name = axis.or(followers.first().copied()).unwrap_or("");
    let follower = followers
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| MarginError::NoAxis(name.to_string()))?;
    let mut sc = s.clone();
    for t in sc.tuning.iter_mut() {
        for g in t.axes.values_mut() {
            g.osc_band_um = 0.0;
            g.ff_trim_tau_s = 0.0;
        }
    }
    let spec = RunSpec {
        controller,
        period_us,
        trace_every_s: None,
    };
    // At speed: from 0.5 s after the start ramp to the start of the stop ramp.
    let m = &sc.master;
    let start_s = m.start_s + m.ramp_s + 0.5;
    let stop_s = sc.master_profile()?.stop_time_s() - m.ramp_s;
    let probe_at = |f: f64| Probe {
        follower,
        amplitude: PROBE_AMPLITUDE,
        freq_hz: f,
        start_s,
        settle_s: (3.0 / f).max(0.3),
        window_s: (8.0 / f).max(1.0),
    };
    let probes: Vec<Probe> = grid(period_us).into_iter().map(probe_at).collect();
    let end_s = probes.iter().map(Probe::end_s).fold(0.0, f64::max);
    if end_s > stop_s || !stop_s.is_finite() {
        return Err(MarginError::TooShort {
            needed_s: end_s,
            at_speed_s: stop_s,
        });
    }
    let unstable = |why: String| MarginError::Unstable {
        axis: name.to_string(),
        why,
    };
    // The loop alone first, as long as the longest probe's run: a loop that oscillates
    // by itself (a fault, or reversing more often than the table, as `robust` judges
    // it) has no margin. The probe's runs are then judged by their faults only — the
    // probe itself reverses the velocity of a slow table.
    let mut alone = sc.clone();
    alone.sim.duration_s = Some(end_s + 0.01);
    let r = run_probed(&alone, table, &spec, None, &mut |_| {})?;
    if let Some(fault) = r.faults.first() {
        return Err(unstable(format!("{} without the probe", fault.name)));
    }
    if let Some(o) = r.oscillation.get(follower).filter(|o| o.excess() > 0) {
        return Err(unstable(format!(
            "{} velocity reversals against the table's {}, without the probe",
            o.reversals, o.table_reversals
        )));
    }
    let sweep = |probes: Vec<Probe>| {
        probes
            .into_par_iter()
            .map(|probe| {
                let f = probe.freq_hz;
                let mut run_sc = sc.clone();
                run_sc.sim.duration_s = Some(probe.end_s() + 0.01);
                let r = run_probed(&run_sc, table, &spec, Some(&probe), &mut |_| {})?;
                if let Some(fault) = r.faults.first() {
                    return Err(unstable(format!(
                        "{} with the probe at {f:.1} Hz",
                        fault.name
                    )));
                }
                match r.loop_response {
                    Some(l) if l.re.is_finite() && l.im.is_finite() => Ok((f, l)),
                    _ => Err(MarginError::NoResponse { freq_hz: f }),
                }
            })
            .collect::<Result<Vec<_>, MarginError>>()
    };
    let mut responses = sweep(probes)?;
    // Where the loop passes −1 closest (a sharp oil-column peak falls between grid
    // points): REFINE more frequencies across the neighbouring intervals.
    let closest = responses
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 .1 + 1.0).norm().total_cmp(&(b.1 .1 + 1.0).norm()))
        .map(|(i, _)| i);
    if let Some(i) = closest {
        let lo = responses[i.saturating_sub(1)].0;
        let hi = responses[(i + 1).min(responses.len() - 1)].0;
        let r = (hi / lo).powf(1.0 / (REFINE + 1) as f64);
        let extra: Vec<Probe> = (1..=REFINE)
            .map(|k| lo * r.powi(k as i32))
            .filter(|f| (f / responses[i].0 - 1.0).abs() > 1e-6)
            .map(probe_at)
            .collect();
        responses.extend(sweep(extra)?);
        responses.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok(margins_of(name, &responses))
}

/// The margins from measured (f, L) pairs, f ascending.
pub fn margins_of(axis: &str, responses: &[(f64, nalgebra::Complex<f64>)]) -> LoopMargins {
    let mut points: Vec<Point> = Vec::with_capacity(responses.len());
    let finite = |&&(f, l): &&(f64, nalgebra::Complex<f64>)| {
        f.is_finite() && f > 0.0 && l.re.is_finite() && l.im.is_finite()
    };
    for &(f, l) in responses.iter().filter(finite) {
        let mut ph = l.arg().to_degrees();
        match points.last() {
            // Unwrapped: within 180° of the previous point.
            Some(p) => ph += 360.0 * ((p.phase_deg - ph) / 360.0).round(),
            None => {
                if ph > 0.0 {
                    ph -= 360.0;
                }
            }
        }
        points.push(Point {
            freq_hz: f,
            mag_db: 20.0 * l.norm().log10(),
            phase_deg: ph,
            distance_to_minus_one: (l + 1.0).norm(),
        });
    }
    // Where `g` falls through 0 between points i and i + 1: the fraction (0 … 1).
    let through = |a: f64, b: f64| (a > 0.0 && b <= 0.0).then(|| a / (a - b));
    let at = |i: usize, x: f64| {
        let (p, q) = (&points[i], &points[i + 1]);
        (
            p.freq_hz * (q.freq_hz / p.freq_hz).powf(x),
            p.mag_db + x * (q.mag_db - p.mag_db),
            p.phase_deg + x * (q.phase_deg - p.phase_deg),
        )
    };
    let crossover = (0..points.len().saturating_sub(1))
        .find_map(|i| through(points[i].mag_db, points[i + 1].mag_db).map(|x| (i, x, at(i, x))));
    let (gain_crossover_hz, phase_margin_deg) = match crossover {
        // PM in (−180°, 180°].
        Some((_, _, (f, _, ph))) => {
            let pm = (ph + 180.0).rem_euclid(360.0);
            (Some(f), Some(if pm > 180.0 { pm - 360.0 } else { pm }))
        }
        None => (None, None),
    };
    // ∠L − (−180° − 360°·m): its distance above the level −180° − 360°·m just below
    // ∠L(f_c); the first fall through 0 above f_c is the phase crossover.
    let phase_cross = crossover.and_then(|(i0, x0, (_, _, ph_c))| {
        let m = -((ph_c + 180.0) / 360.0).floor();
        let above = |i: usize| points[i].phase_deg + 180.0 + 360.0 * m;
        (i0..points.len().saturating_sub(1)).find_map(|i| {
            through(above(i), above(i + 1))
                .filter(|&x| i > i0 || x >= x0)
                .map(|x| at(i, x))
        })
    });
    LoopMargins {
        axis: axis.to_string(),
        modulus_margin: points
            .iter()
            .map(|p| p.distance_to_minus_one)
            .fold(f64::INFINITY, f64::min),
        points,
        gain_crossover_hz,
        phase_margin_deg,
        phase_crossover_hz: phase_cross.map(|(f, _, _)| f),
        gain_margin_db: phase_cross.map(|(_, m, _)| -m),
    }
}

#[cfg(test)]
mod tests;
