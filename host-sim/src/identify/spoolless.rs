//! Identification without a spool signal, from sensor readings: the board's capture of a
//! test move (`host-sim motion test`) — the valve command as written, the encoder's
//! position (1 µm counts) and the two pressure transducers (12-bit ADC) every tick.
//!
//! **Both sides filtered alike.** The position must be differentiated twice and the
//! pressures once; quantisation makes raw differences useless (1 µm / (1 ms)² is
//! 1 m/s²). Every equation is linear in its signals, so it still holds, with the same
//! parameters, after every term is passed through one linear filter `h`: a derivative
//! moves onto the kernel, `h*ẋ = h'*x`. `h` is a Gaussian of σ = [`SMOOTH_S`] (−3 dB at
//! 0.133/σ ≈ 53 Hz, zero phase), `h'` and `h''` its sampled derivatives, each normalised
//! so a ramp (a parabola) gives exactly its slope (its curvature). The products that are
//! not linear in the signals — the orifice terms `x̃_v·√Δp`, the chamber volume times
//! the pressure's rate, the Coulomb term — are formed per sample and then filtered
//! (orifice), or formed from the filtered signals (volume, Coulomb): a second-order
//! error, small where the volume changes little over σ.
//!
//! **The spool is modelled.** `ẍ_v = ω_v²·(u(t − d) − x_v) − 2ζ_v·ω_v·ẋ_v`, the command held
//! per tick and delayed `d` (0 … 2 ticks in eighths: the board writes its valve within
//! the tick, the simulator a period later), integrated by RK4 in 8 sub-steps per tick. For
//! each candidate `(ω_v, ζ_v, d)` the flow-and-oil regression of the parent module is
//! solved; the candidate with the smallest residual is the valve's (a grid, then a
//! finer one around its best), then the overlap is scanned the same way. The force
//! balance is the parent's, on the filtered signals. Each value's 1σ is the fit's:
//! for the valve's, the half-width of the grid values whose residual is within one
//! σ̂² (Δχ² = 1) of the best. Bandwidth, damping and delay trade against each other (a
//! slower valve with less delay has almost the same phase below the oil column); their
//! low-frequency lag `2ζ/ω_v + d` (`valve_lag_ms`) is what a recording pins down best.
//!
//! **The pressures' timing.** A board may convert its pressures over part of the tick,
//! not at the instant it latches the encoder; a skew `τ` between them shows in the force
//! balance as a viscous term `τ·m·ω²`. On the release ELF in board-emu the viscous
//! friction came out +4 … +10 % (the virtual board, which reads both at the tick: +1.3 %),
//! and a scan of the skew moved it ≈ 18 % per 50 µs. The residual cannot find τ itself
//! (such a scan picked noise), so it is given: `pressure_skew_s`, positive when the
//! pressures were sampled after the position (`identify --pressure-skew-ms`, default 0);
//! the force balance reads the pressures through the Gaussian delayed by `τ` (a recorded
//! `p(t)` is the true `p(t + τ)`). The flow equations absorb it in the spool's fitted
//! delay.
//!
//! **Uncertainty.** The filtered rows are correlated over the Gaussian's equivalent width
//! `2√π·σ` (≈ 8.9 rows at 1 ms): every σ of this fit is the regression's σ̂·√((XᵀX)⁻¹)
//! scaled by the square root of that width, and the valve's Δχ² = 1 interval counts σ̂²
//! per independent sample. Unpowered ticks (the capture's `valve_power` 0, or a state
//! other than manual, following or holding) are commanded 0 and not fitted; a sample is
//! fitted only when every sample within the kernel's half-width may be.
//!
//! The chamber volumes need the piston's position in the cylinder (0 = retracted): the
//! capture's position plus `offset` (`identify --position-offset-mm`, when the board's
//! frame is not the cylinder's).

use super::{lstsq, orifice_terms, push_continuity, residual_ss, Identified, IdentifyError, Param};
use crate::plant::HydraulicAxis;

/// The smoothing filter's σ, s.
pub const SMOOTH_S: f64 = 2.5e-3;

/// One recording: a capture of one slave, sampled every `period_s`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// Sample period, s.
    pub period_s: f64,
    /// Valve command per tick, normalised −1 … 1 (the DAC code / 2047).
    pub u: Vec<f64>,
    /// Position, m.
    pub x_m: Vec<f64>,
    /// Chamber A pressure, Pa.
    pub pa_pa: Vec<f64>,
    /// Chamber B pressure, Pa.
    pub pb_pa: Vec<f64>,
    /// Whether the valve was driven in the tick (powered, in control); an unpowered tick's
    /// command is taken as 0 and it is not fitted. Empty: every tick.
    pub driven: Vec<bool>,
}

impl Recording {
    /// Whether tick `i` was driven (see [`Recording::driven`]).
    fn driven(&self, i: usize) -> bool {
        self.driven.get(i).copied().unwrap_or(true)
    }
}

/// A Gaussian kernel (`order` 0), or its first or second derivative, over ±4σ,
/// normalised (module docs); `kernel[L + j]` weights `x[i − j]`.
fn kernel(order: u8, sigma_ticks: f64) -> Vec<f64> {
    let l = (4.0 * sigma_ticks).ceil().max(2.0) as i64;
    let g = |j: f64| (-0.5 * (j / sigma_ticks).powi(2)).exp();
    let mut raw: Vec<f64> = (-l..=l)
        .map(|j| {
            let j = j as f64;
            match order {
                0 => g(j),
                1 => -j * g(j),
                _ => (j * j / sigma_ticks.powi(2) - 1.0) * g(j),
            }
        })
        .collect();
    if order == 2 {
        // The sampled, truncated second derivative does not sum to exactly 0: a constant
        // (a position of 0.1 m) would leak into the acceleration (7 m/s² at 1 ms,
        // measured before this correction). Remove its sum in proportion to the
        // Gaussian's weights (the odd first derivative sums to 0 by symmetry).
        let sum: f64 = raw.iter().sum();
        let g0: f64 = (-l..=l).map(|j| g(j as f64)).sum();
        for (w, j) in raw.iter_mut().zip(-l..=l) {
            *w -= sum * g(j as f64) / g0;
        }
    }
    // Normalise on the polynomial it must pass: 1, t, t²/2 (t in ticks).
    let poly = |j: f64| match order {
        0 => 1.0,
        1 => -j,
        _ => 0.5 * j * j,
    };
    let s: f64 = raw
        .iter()
        .enumerate()
        .map(|(k, w)| w * poly((k as i64 - l) as f64))
        .sum();
    raw.iter().map(|w| w / s).collect()
}

/// The Gaussian smoothing kernel delayed by `delay` ticks (fractional): `h * x` is then
/// the smoothed `x(t − delay)`.
fn shifted(sigma_ticks: f64, delay: f64) -> Vec<f64> {
    let l = (4.0 * sigma_ticks).ceil().max(2.0) as i64 + 1;
    let raw: Vec<f64> = (-l..=l)
        .map(|j| (-0.5 * ((j as f64 - delay) / sigma_ticks).powi(2)).exp())
        .collect();
    let s: f64 = raw.iter().sum();
    raw.iter().map(|w| w / s).collect()
}

/// `h * x` at every sample with full support (`None` near the ends), in units per tick^order
/// (divide by T^order).
fn filter(h: &[f64], x: &[f64]) -> Vec<Option<f64>> {
    let l = h.len() / 2;
    (0..x.len())
        .map(|i| {
            if i < l || i + l >= x.len() {
                return None;
            }
            Some(
                h.iter()
                    .enumerate()
                    .map(|(k, w)| w * x[i + l - k])
                    .sum::<f64>(),
            )
        })
        .collect()
}

/// The filtered signals of one recording.
struct Filtered {
    x: Vec<Option<f64>>,
    v: Vec<Option<f64>>,
    a: Vec<Option<f64>>,
    pa: Vec<Option<f64>>,
    pb: Vec<Option<f64>>,
    dpa: Vec<Option<f64>>,
    dpb: Vec<Option<f64>>,
}

impl Filtered {
    fn of(r: &Recording, h: &[Vec<f64>; 3]) -> Self {
        let t = r.period_s;
        let scale = |v: Vec<Option<f64>>, k: f64| v.into_iter().map(|x| x.map(|x| x * k)).collect();
        Self {
            x: filter(&h[0], &r.x_m),
            v: scale(filter(&h[1], &r.x_m), 1.0 / t),
            a: scale(filter(&h[2], &r.x_m), 1.0 / (t * t)),
            pa: filter(&h[0], &r.pa_pa),
            pb: filter(&h[0], &r.pb_pa),
            dpa: scale(filter(&h[1], &r.pa_pa), 1.0 / t),
            dpb: scale(filter(&h[1], &r.pb_pa), 1.0 / t),
        }
    }
}

/// Sub-steps per tick of the spool's integration (and the delay's resolution).
const SUB: usize = 8;

/// The spool of a command held per tick, delayed `delay` sub-steps (1/[`SUB`] tick;
/// module docs).
fn spool(u: &[f64], period_s: f64, w: f64, zeta: f64, delay: usize) -> Vec<f64> {
    let h = period_s / SUB as f64;
    let f = |x: f64, v: f64, u: f64| (v, w * w * (u - x) - 2.0 * zeta * w * v);
    // At rest at the first command (the recording starts from a holding axis).
    let (mut x, mut v) = (u.first().copied().unwrap_or(0.0), 0.0f64);
    let mut out = Vec::with_capacity(u.len());
    for k in 0..u.len() {
        out.push(x);
        for sub in 0..SUB {
            // Before the recording's first command: that command (the law held it).
            let uk = u[(k * SUB + sub).saturating_sub(delay) / SUB];
            let (k1x, k1v) = f(x, v, uk);
            let (k2x, k2v) = f(x + 0.5 * h * k1x, v + 0.5 * h * k1v, uk);
            let (k3x, k3v) = f(x + 0.5 * h * k2x, v + 0.5 * h * k2v, uk);
            let (k4x, k4v) = f(x + h * k3x, v + h * k3v, uk);
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            if x.abs() >= 1.0 {
                x = x.clamp(-1.0, 1.0);
                if x * v > 0.0 {
                    v = 0.0;
                }
            }
        }
    }
    out
}

/// A valve candidate.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Valve {
    w: f64,
    zeta: f64,
    delay: usize,
    overlap: f64,
}

/// The flow-and-oil fit of one candidate: coefficients (K⁺, K⁻, 1/β), their σ, the
/// residual sum of squares and the degrees of freedom.
type FlowFit = (Vec<f64>, Vec<f64>, f64, usize);

/// What the fit needs of the recordings, computed once.
struct Prepared<'a> {
    known: &'a HydraulicAxis,
    recs: &'a [Recording],
    filt: Vec<Filtered>,
    /// Usable samples per recording.
    usable: Vec<Vec<usize>>,
    h0: Vec<f64>,
}

impl Prepared<'_> {
    fn flow(&self, c: Valve) -> Result<FlowFit, IdentifyError> {
        let k = self.known;
        let (mut rows, mut y) = (Vec::new(), Vec::new());
        for ((r, f), idx) in self.recs.iter().zip(&self.filt).zip(&self.usable) {
            let u: Vec<f64> = (0..r.u.len())
                .map(|i| if r.driven(i) { r.u[i] } else { 0.0 })
                .collect();
            let xv = spool(&u, r.period_s, c.w, c.zeta, c.delay);
            // The orifice terms per sample (module docs of the parent), then filtered.
            let mut g = [
                vec![0.0; xv.len()],
                vec![0.0; xv.len()],
                vec![0.0; xv.len()],
                vec![0.0; xv.len()],
            ];
            for (i, &s) in xv.iter().enumerate() {
                let t = orifice_terms(k, s, c.overlap, r.pa_pa[i], r.pb_pa[i]);
                for (col, v) in g.iter_mut().zip(t) {
                    col[i] = v;
                }
            }
            let gf: Vec<Vec<Option<f64>>> = g.iter().map(|c| filter(&self.h0, c)).collect();
            for &i in idx {
                let (Some(x), Some(v), Some(pa), Some(pb), Some(dpa), Some(dpb)) =
                    (f.x[i], f.v[i], f.pa[i], f.pb[i], f.dpa[i], f.dpb[i])
                else {
                    continue;
                };
                let (Some(g0), Some(g1), Some(g2), Some(g3)) =
                    (gf[0][i], gf[1][i], gf[2][i], gf[3][i])
                else {
                    continue;
                };
                push_continuity(
                    k,
                    &mut rows,
                    &mut y,
                    x,
                    v,
                    [pa, pb],
                    [dpa, dpb],
                    [g0, g1, g2, g3],
                );
            }
        }
        let (th, sd) = lstsq("valve flow and oil", &rows, &y)?;
        let ss = residual_ss(&rows, &y, &th);
        let dof = rows.len().saturating_sub(3).max(1);
        Ok((th, sd, ss, dof))
    }
}

/// The outcome of a search: the best candidate, its fit, and every candidate's residual.
type Search = (Valve, FlowFit, Vec<(Valve, f64)>);

/// The best candidate over `cands` (the first error if none fits).
fn best_of(p: &Prepared<'_>, cands: impl Iterator<Item = Valve>) -> Result<Search, IdentifyError> {
    let mut best: Option<(Valve, FlowFit)> = None;
    let mut first_error = None;
    let mut all = Vec::new();
    for c in cands {
        match p.flow(c) {
            Ok(fit) => {
                all.push((c, fit.2));
                if best.as_ref().is_none_or(|b| fit.2 < b.1 .2) {
                    best = Some((c, fit));
                }
            }
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    match best {
        Some((c, f)) => Ok((c, f, all)),
        None => Err(first_error.unwrap_or(IdentifyError::NotExcited {
            law: "valve flow and oil",
        })),
    }
}

/// The half-width of the values `key` takes among the candidates of one search whose
/// residual is within one σ̂² of that search's best (Δχ² = 1), σ̂² counted per
/// independent sample: the filtered rows are correlated over ≈ `corr` rows
/// ([`correlated_rows`]).
fn spread(all: &[(Valve, f64)], dof: usize, corr: f64, key: impl Fn(&Valve) -> f64) -> f64 {
    let best_ss = all.iter().map(|(_, s)| *s).fold(f64::INFINITY, f64::min);
    let lim = best_ss * (1.0 + corr / dof as f64);
    let vals: Vec<f64> = all
        .iter()
        .filter(|(_, s)| *s <= lim)
        .map(|(c, _)| key(c))
        .collect();
    let (lo, hi) = vals
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    if lo.is_finite() {
        0.5 * (hi - lo)
    } else {
        0.0
    }
}

/// Rows of the filtered regressions that one independent sample spreads over: the
/// Gaussian's equivalent width `2√π·σ` in ticks (its residuals are correlated over it, so
/// the fits' σ from σ̂²·(XᵀX)⁻¹ are scaled by the square root of this).
fn correlated_rows(sigma_ticks: f64) -> f64 {
    (2.0 * std::f64::consts::PI.sqrt() * sigma_ticks).max(1.0)
}

/// A candidate's low-frequency lag `2ζ/ω_v + d`, ms.
fn lag_ms(c: &Valve, period_s: f64) -> f64 {
    (2.0 * c.zeta / c.w + c.delay as f64 / SUB as f64 * period_s) * 1e3
}

/// Fits the axis `known` (geometry, supply, leakage and Coulomb smoothing known) to the
/// recordings (module docs).
pub fn identify_spoolless(
    known: &HydraulicAxis,
    recs: &[Recording],
    pressure_skew_s: f64,
) -> Result<Identified, IdentifyError> {
    let tau = std::f64::consts::TAU;
    let period = recs.first().map_or(1e-3, |r| r.period_s);
    for r in recs {
        // One period for all (the filter is built once), above 0.
        if !(r.period_s > 0.0 && r.period_s.is_finite())
            || (r.period_s - period).abs() > 1e-3 * period
        {
            return Err(IdentifyError::Unphysical {
                name: "period_s",
                value: r.period_s,
            });
        }
        let n = r.u.len();
        if r.x_m.len() != n || r.pa_pa.len() != n || r.pb_pa.len() != n {
            return Err(IdentifyError::Unphysical {
                name: "recording_columns_of_unequal_length",
                value: n as f64,
            });
        }
    }
    let sigma_ticks = SMOOTH_S / period;
    // The shifted kernel is one sample wider than the others: a skew up to one period.
    if pressure_skew_s.is_nan() || pressure_skew_s.abs() > period {
        return Err(IdentifyError::Unphysical {
            name: "pressure_skew_s",
            value: pressure_skew_s,
        });
    }
    let h: [Vec<f64>; 3] = [
        kernel(0, sigma_ticks),
        kernel(1, sigma_ticks),
        kernel(2, sigma_ticks),
    ];
    let c = &known.cylinder;
    let pmax = known.supply.max_pa;
    let margin = 0.05 * c.stroke_m;
    let filt: Vec<Filtered> = recs.iter().map(|r| Filtered::of(r, &h)).collect();
    let samples: usize = recs.iter().map(|r| r.u.len()).sum();
    // A filtered equation holds where it holds over the whole kernel: a sample is used
    // only when every sample within the kernel's half-width is.
    let half = h[0].len() / 2;
    let usable: Vec<Vec<usize>> = recs
        .iter()
        .map(|r| {
            let ok: Vec<bool> = (0..r.u.len())
                .map(|i| {
                    let (x, pa, pb) = (r.x_m[i], r.pa_pa[i], r.pb_pa[i]);
                    r.driven(i)
                        && r.u[i].abs() < 0.999
                        && x > margin
                        && x < c.stroke_m - margin
                        && pa > 0.01 * pmax
                        && pa < 0.99 * pmax
                        && pb > 0.01 * pmax
                        && pb < 0.99 * pmax
                        && c.contact_n(x) == 0.0
                })
                .collect();
            (0..ok.len())
                .filter(|&i| {
                    let lo = i.saturating_sub(half);
                    let hi = (i + half + 1).min(ok.len());
                    ok[lo..hi].iter().all(|&b| b)
                })
                .collect()
        })
        .collect();
    let corr = correlated_rows(sigma_ticks);
    let p = Prepared {
        known,
        recs,
        filt,
        usable,
        h0: h[0].clone(),
    };

    // The valve: a coarse grid, then a fine one around its best; then the overlap.
    let coarse = (0..20).flat_map(|i| {
        let f = 15.0 * 1.16f64.powi(i);
        (0..9).flat_map(move |j| {
            (0..=4).map(move |d| Valve {
                w: tau * f,
                zeta: 0.3 + 0.15 * f64::from(j),
                delay: d * SUB / 2,
                overlap: 0.0,
            })
        })
    });
    let (b, _, _) = best_of(&p, coarse)?;
    let fine = (-8..=8).flat_map(|i| {
        (-6..=6).flat_map(move |j| {
            (-2..=2).filter_map(move |d: i64| {
                Some(Valve {
                    w: b.w * 1.02f64.powi(i),
                    zeta: (b.zeta + 0.025 * f64::from(j)).max(0.05),
                    delay: usize::try_from(b.delay as i64 + d).ok()?,
                    ..b
                })
            })
        })
    });
    let (b, _, all_valve) = best_of(&p, fine)?;
    let (b, fit, _) = best_of(
        &p,
        (0..=20).map(|k| Valve {
            overlap: f64::from(k) * 0.0025,
            ..b
        }),
    )?;
    let (th, sd, _, dof) = fit;
    let sd: Vec<f64> = sd.iter().map(|x| x * corr.sqrt()).collect();
    if th[2].is_nan() || th[2] <= 0.0 {
        return Err(IdentifyError::Unphysical {
            name: "bulk_modulus_pa",
            value: th[2],
        });
    }
    let mut params = vec![
        Param {
            name: "valve_bandwidth_hz",
            value: b.w / tau,
            std: spread(&all_valve, dof, corr, |c| c.w / tau).max(0.01 * b.w / tau),
        },
        Param {
            name: "valve_damping",
            value: b.zeta,
            std: spread(&all_valve, dof, corr, |c| c.zeta).max(0.0125),
        },
        Param {
            name: "valve_delay_ms",
            value: b.delay as f64 / SUB as f64 * period * 1e3,
            std: spread(&all_valve, dof, corr, |c| {
                c.delay as f64 / SUB as f64 * period * 1e3
            })
            .max(0.5 / SUB as f64 * period * 1e3),
        },
        Param {
            // What the three trade against each other and the recording determines best:
            // the low-frequency lag 2ζ/ω_v + d.
            name: "valve_lag_ms",
            value: lag_ms(&b, period),
            std: spread(&all_valve, dof, corr, |c| lag_ms(c, period)).max(0.01),
        },
    ];
    super::push_flow_params(&mut params, &th, &sd, b.overlap);

    // The force balance on the filtered signals, the pressures moved to the position's
    // instant (module docs).
    let vs = c.coulomb_smoothing_m_per_s.max(1e-9);
    let (aa, ab) = (c.area_a_m2, c.area_b_m2);
    let coulomb: Vec<Vec<Option<f64>>> = recs
        .iter()
        .map(|r| {
            // The Coulomb term is not linear in the signals: formed from a lightly smoothed
            // velocity (a central difference over ±2 ticks: 1 µm counts give 0.25 mm/s at
            // 1 ms), then filtered like the rest.
            let n = r.x_m.len();
            let sign: Vec<f64> = (0..n)
                .map(|i| {
                    let (lo, hi) = (i.saturating_sub(2), (i + 2).min(n - 1));
                    let v = (r.x_m[hi] - r.x_m[lo]) / ((hi - lo).max(1) as f64 * r.period_s);
                    (v / vs).tanh()
                })
                .collect();
            filter(&p.h0, &sign)
        })
        .collect();
    let force_rows = |skew: f64| {
        let h = shifted(sigma_ticks, skew);
        let (mut rows, mut y) = (Vec::new(), Vec::new());
        for (((f, idx), r), fc) in p.filt.iter().zip(&p.usable).zip(recs).zip(&coulomb) {
            let (pa, pb) = (filter(&h, &r.pa_pa), filter(&h, &r.pb_pa));
            for &i in idx {
                let (Some(a), Some(v), Some(pa), Some(pb), Some(fc)) =
                    (f.a[i], f.v[i], pa[i], pb[i], fc[i])
                else {
                    continue;
                };
                rows.push(vec![a, v, fc, 1.0]);
                y.push(aa * pa - ab * pb);
            }
        }
        (rows, y)
    };
    // Recorded p(t) = true p(t + τ): read through the Gaussian delayed by τ.
    let skew = pressure_skew_s / period;
    let (rows, y) = force_rows(skew);
    let (th, sd) = lstsq("motion", &rows, &y)?;
    let sd: Vec<f64> = sd.iter().map(|x| x * corr.sqrt()).collect();
    super::push_force_params(&mut params, &th, &sd)?;
    super::push_derived(&mut params, known);
    Ok(Identified {
        params,
        used_samples: p.usable.iter().map(Vec::len).sum(),
        samples,
    })
}

#[cfg(test)]
mod tests;
