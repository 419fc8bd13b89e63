//! Identification of one valve-cylinder axis from an open-loop recording.
//!
//! The cylinder's geometry (bore, rod, stroke, dead volumes) and the supply are known
//! from the scenario; what a machine hides is fitted, each by linear least squares on
//! the equations of the plant model (`crate::plant`, PLANT.md) — an *equation-error* fit
//! on the recorded signals, one regression per physical law, each parameter with the
//! standard error of its coefficient from the fit's residual (σ̂²·(XᵀX)⁻¹: how well the
//! law fits the data, not a bound on the bias — the residuals are not white):
//!
//! 1. **Valve dynamics** (spool `x_v` recorded, 1 = full opening; `ẍ_v = ω_v²·(u − x_v)
//!    − 2ζ_v·ω_v·ẋ_v`): sampled every T with the command held, exactly `x_{k+1} =
//!    a₁x_k + a₂x_{k−1} + b₁u_k + b₂u_{k−1}`; the poles z of `z² − a₁z − a₂` give
//!    `s = ln z / T` → bandwidth `|s|/2π` Hz and damping `−Re s/|s|`.
//! 2. **Valve flow and oil** (both chambers' continuity, rows of A and B together):
//!    `A_A·v = K⁺·g_A⁺ + K⁻·g_A⁻ − (1/β)·V_A(x)·ṗ_A` and `−A_B·v = K⁺·g_B⁺ + K⁻·g_B⁻ −
//!    (1/β)·V_B(x)·ṗ_B`, `g` the orifice terms `x̃_v·√Δp` of the opening direction (+:
//!    extending, P→A / B→T), `x̃_v = sign(x_v)·max(|x_v| − d, 0)` with the overlap `d`
//!    found by a scan (the smallest residual) → flow gain per direction `K±` (reported as
//!    the rated flow at 35 bar, l/min) and bulk modulus β.
//! 3. **Motion** (force balance): `A_A·p_A − A_B·p_B = m·a + c·v + F_c·tanh(v/v_s) +
//!    F_0` → moving mass, viscous and Coulomb friction (`v_s` the scenario's smoothing),
//!    and a constant load `F_0`.
//! 4. Derived: the hydraulic natural frequency at mid-stroke `ω_h = √(β·(A_A²/V_A +
//!    A_B²/V_B)/m)` and its damping from the viscous friction `c/(2√(k_h·m))`.
//!
//! Derivatives are five-point central differences of the samples; samples at a spool or
//! pressure clamp, near an end stop (within 5 % of the stroke), against a contact, and
//! the first and last are left out. The signals are used as recorded (host-sim's true
//! plant signals, `open-loop`'s output); validated on host-sim's plant (`tests`): a
//! machine with mass, bulk modulus, valve flow and friction off nominal is recovered
//! within 4 %. The board's quantised readings without a spool signal are [`spoolless`]'s.

use crate::plant::HydraulicAxis;
use nalgebra::{DMatrix, DVector};

/// One recording sample (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// Valve command, normalised −1 … 1.
    pub u: f64,
    /// Piston position, m.
    pub x_m: f64,
    /// Piston speed, m/s.
    pub v_m_s: f64,
    /// Chamber pressures, Pa.
    pub pa_pa: f64,
    /// Chamber B pressure, Pa.
    pub pb_pa: f64,
    /// Spool position, normalised.
    pub spool: f64,
}

/// One fitted parameter.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Param {
    /// Its name (`mass_kg`, …: the unit is in the name).
    pub name: &'static str,
    /// The estimate.
    pub value: f64,
    /// Its standard error from the fit's residual (σ̂·√((XᵀX)⁻¹)ⱼⱼ), same unit: how well
    /// the equation fits, not a bound on the estimate's bias (the residuals are not
    /// white: finite differences and, on a real machine, sensor noise).
    pub std: f64,
}

/// What could not be identified.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IdentifyError {
    /// Too few usable samples for a regression.
    #[error("{law}: only {usable} usable samples (need ≥ {need}); excite the axis longer or with larger commands")]
    TooFewSamples {
        /// Which regression.
        law: &'static str,
        /// Usable samples.
        usable: usize,
        /// Needed.
        need: usize,
    },
    /// The regressors are (nearly) dependent: the recording does not excite a parameter.
    #[error("{law}: the recording does not separate the parameters (move both ways, vary speed and acceleration)")]
    NotExcited {
        /// Which regression.
        law: &'static str,
    },
    /// A fitted value is not physical.
    #[error("{name} fitted as {value}, not physical: the recording does not fit the model")]
    Unphysical {
        /// The parameter.
        name: &'static str,
        /// Its estimate.
        value: f64,
    },
}

/// Least squares `y ≈ X·θ`: θ and its standard errors.
fn lstsq(
    law: &'static str,
    rows: &[Vec<f64>],
    y: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), IdentifyError> {
    let n = rows.len();
    let k = rows.first().map_or(0, Vec::len);
    if n < 10 * k.max(1) {
        return Err(IdentifyError::TooFewSamples {
            law,
            usable: n,
            need: 10 * k.max(1),
        });
    }
    // Columns scaled to unit RMS so the conditioning test means something.
    let mut scale = vec![0.0; k];
    for r in rows {
        for (s, x) in scale.iter_mut().zip(r) {
            *s += x * x;
        }
    }
    for s in &mut scale {
        *s = (*s / n as f64).sqrt();
        if *s == 0.0 || !s.is_finite() {
            return Err(IdentifyError::NotExcited { law });
        }
    }
    let x = DMatrix::from_fn(n, k, |i, j| rows[i][j] / scale[j]);
    let yv = DVector::from_column_slice(y);
    let xtx = x.transpose() * &x;
    let svd = xtx.clone().svd(false, false);
    let (smax, smin) = (svd.singular_values.max(), svd.singular_values.min());
    if smin.is_nan() || smin <= 1e-9 * smax {
        return Err(IdentifyError::NotExcited { law });
    }
    let inv = xtx.try_inverse().ok_or(IdentifyError::NotExcited { law })?;
    let theta = &inv * (x.transpose() * &yv);
    let resid = &yv - &x * &theta;
    let dof = (n - k).max(1) as f64;
    let sigma2 = resid.norm_squared() / dof;
    let th: Vec<f64> = (0..k).map(|j| theta[j] / scale[j]).collect();
    let sd: Vec<f64> = (0..k)
        .map(|j| (sigma2 * inv[(j, j)]).max(0.0).sqrt() / scale[j])
        .collect();
    Ok((th, sd))
}

/// Five-point central differences of `f` (`(−f₊₂ + 8f₊₁ − 8f₋₁ + f₋₂)/12T`, error
/// O(T⁴): the 3-point form is (ωT)²/6 low, ≈ 0.9 % at a 37 Hz oil column sampled at
/// 1 kHz); `None` near the ends and where the sampling is not uniform.
fn derivative(s: &[Sample], f: impl Fn(&Sample) -> f64) -> Vec<Option<f64>> {
    (0..s.len())
        .map(|i| {
            let w = s.get(i.checked_sub(2)?..i + 3)?;
            let h = w[2].t - w[1].t;
            // Uniform within 0.1 % (timestamps with µs jitter or printed to 0.1 ms pass).
            let uniform = w
                .windows(2)
                .all(|p| ((p[1].t - p[0].t) - h).abs() <= 1e-3 * h.abs());
            (h > 0.0 && uniform)
                .then(|| (f(&w[0]) - 8.0 * f(&w[1]) + 8.0 * f(&w[3]) - f(&w[4])) / (12.0 * h))
        })
        .collect()
}

/// The identified axis.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Identified {
    /// Every fitted and derived parameter, in the order of the module docs.
    pub params: Vec<Param>,
    /// Samples the fits used (of the recording's).
    pub used_samples: usize,
    /// Samples in the recording.
    pub samples: usize,
}

impl Identified {
    /// A parameter by name.
    pub fn get(&self, name: &str) -> Option<&Param> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// Fits the axis `known` (its geometry, supply and friction smoothing are taken as
/// known; its valve, oil, mass and friction values are ignored) to the recording.
pub fn identify(known: &HydraulicAxis, rec: &[Sample]) -> Result<Identified, IdentifyError> {
    let c = &known.cylinder;
    let sup = &known.supply;
    let (aa, ab) = (c.area_a_m2, c.area_b_m2);
    let acc = derivative(rec, |s| s.v_m_s);
    let dpa = derivative(rec, |s| s.pa_pa);
    let dpb = derivative(rec, |s| s.pb_pa);
    let margin = 0.05 * c.stroke_m;
    let pmax = sup.max_pa;
    let usable = |i: usize| -> bool {
        let s = &rec[i];
        i >= 2
            && i + 2 < rec.len()
            && s.spool.abs() < 0.999
            && s.x_m > margin
            && s.x_m < c.stroke_m - margin
            && s.pa_pa > 0.01 * pmax
            && s.pa_pa < 0.99 * pmax
            && s.pb_pa > 0.01 * pmax
            && s.pb_pa < 0.99 * pmax
            && c.contact_n(s.x_m) == 0.0
    };
    let idx: Vec<usize> = (0..rec.len()).filter(|&i| usable(i)).collect();
    let mut params = Vec::new();

    // 1. Valve dynamics: the sampled second-order spool with the command held between
    //    samples is exactly x_{k+1} = a1·x_k + a2·x_{k−1} + b1·u_k + b2·u_{k−1}; its poles
    //    z give s = ln(z)/T, ω_v = |s|, ζ_v = −Re(s)/|s|.
    let period = {
        let mut d: Vec<f64> = rec.windows(2).map(|w| w[1].t - w[0].t).collect();
        d.sort_by(f64::total_cmp);
        d.get(d.len() / 2).copied().unwrap_or(0.0)
    };
    let (mut rows, mut y) = (Vec::new(), Vec::new());
    for k in 1..rec.len().saturating_sub(1) {
        let (p, s, n) = (&rec[k - 1], &rec[k], &rec[k + 1]);
        let clamp = [p, s, n].iter().any(|q| q.spool.abs() >= 0.999);
        let tol = 1e-3 * period;
        let uniform = ((n.t - s.t) - period).abs() <= tol && ((s.t - p.t) - period).abs() <= tol;
        if !clamp && uniform {
            rows.push(vec![s.spool, p.spool, s.u, p.u]);
            y.push(n.spool);
        }
    }
    let (th, sd) = lstsq("valve dynamics", &rows, &y)?;
    let poles = |a1: f64, a2: f64| -> Option<(f64, f64)> {
        let disc = a1 * a1 + 4.0 * a2;
        let (w, z) = if disc < 0.0 {
            let r = (-a2).sqrt();
            let ang = (0.5 * (-disc).sqrt()).atan2(0.5 * a1);
            let (re, im) = (r.ln() / period, ang / period);
            let w = re.hypot(im);
            (w, -re / w)
        } else {
            let (z1, z2) = (0.5 * (a1 + disc.sqrt()), 0.5 * (a1 - disc.sqrt()));
            if z1 <= 0.0 || z2 <= 0.0 {
                return None;
            }
            let (s1, s2) = (z1.ln() / period, z2.ln() / period);
            let w = (s1 * s2).sqrt();
            (w, -(s1 + s2) / (2.0 * w))
        };
        (w.is_finite() && w > 0.0 && z.is_finite()).then_some((w, z))
    };
    let Some((w, zeta)) = poles(th[0], th[1]) else {
        return Err(IdentifyError::Unphysical {
            name: "valve_pole_a1",
            value: th[0],
        });
    };
    if w * period > std::f64::consts::FRAC_PI_2 {
        // The valve is too fast for the sampling: its poles alias.
        return Err(IdentifyError::Unphysical {
            name: "valve_bandwidth_hz",
            value: w / std::f64::consts::TAU,
        });
    }
    // 1σ: each coefficient moved by its standard error, the effects added in quadrature.
    let (mut sw, mut sz) = (0.0f64, 0.0f64);
    for (da1, da2) in [(sd[0], 0.0), (0.0, sd[1])] {
        if let Some((w2, z2)) = poles(th[0] + da1, th[1] + da2) {
            sw = sw.hypot(w2 - w);
            sz = sz.hypot(z2 - zeta);
        }
    }
    let tau = std::f64::consts::TAU;
    params.push(Param {
        name: "valve_bandwidth_hz",
        value: w / tau,
        std: sw / tau,
    });
    params.push(Param {
        name: "valve_damping",
        value: zeta,
        std: sz,
    });

    // 2. Flow gain per direction and bulk modulus; overlap by a scan.
    let flow_fit = |d: f64| -> Result<(Vec<f64>, Vec<f64>, f64), IdentifyError> {
        let (mut rows, mut y) = (Vec::new(), Vec::new());
        for &i in &idx {
            let s = &rec[i];
            let (Some(pa), Some(pb)) = (dpa[i], dpb[i]) else {
                continue;
            };
            let g = orifice_terms(known, s.spool, d, s.pa_pa, s.pb_pa);
            push_continuity(
                known,
                &mut rows,
                &mut y,
                s.x_m,
                s.v_m_s,
                [s.pa_pa, s.pb_pa],
                [pa, pb],
                g,
            );
        }
        let (th, sd) = lstsq("valve flow and oil", &rows, &y)?;
        let ss = residual_ss(&rows, &y, &th);
        Ok((th, sd, ss))
    };
    let mut best: Option<(f64, Vec<f64>, Vec<f64>, f64)> = None;
    let mut first_error = None;
    for k in 0..=20 {
        let d = f64::from(k) * 0.0025; // 0 … 5 % of the spool travel
        match flow_fit(d) {
            Ok((th, sd, ss)) => {
                if best.as_ref().is_none_or(|b| ss < b.3) {
                    best = Some((d, th, sd, ss));
                }
            }
            // A large overlap can leave the small commands without any flow: skip it.
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    let Some((overlap, th, sd, _)) = best else {
        return Err(first_error.unwrap_or(IdentifyError::NotExcited {
            law: "valve flow and oil",
        }));
    };
    if th[2].is_nan() || th[2] <= 0.0 {
        return Err(IdentifyError::Unphysical {
            name: "bulk_modulus_pa",
            value: th[2],
        });
    }
    push_flow_params(&mut params, &th, &sd, overlap);

    // 3. Force balance.
    let (mut rows, mut y) = (Vec::new(), Vec::new());
    for &i in &idx {
        let s = &rec[i];
        let Some(a) = acc[i] else { continue };
        let vs = c.coulomb_smoothing_m_per_s.max(1e-9);
        rows.push(vec![a, s.v_m_s, (s.v_m_s / vs).tanh(), 1.0]);
        y.push(aa * s.pa_pa - ab * s.pb_pa);
    }
    let (th, sd) = lstsq("motion", &rows, &y)?;
    push_force_params(&mut params, &th, &sd)?;

    push_derived(&mut params, known);
    Ok(Identified {
        params,
        used_samples: idx.len(),
        samples: rec.len(),
    })
}

/// The orifice terms `x̃_v·φ(Δp)` of the flow regression (module docs, law 2) for a spool
/// at `spool` (normalised) with overlap `overlap`: `[g_A⁺, g_A⁻, g_B⁺, g_B⁻]`, the
/// plant's regularised signed root (a chamber above supply flows back).
fn orifice_terms(known: &HydraulicAxis, spool: f64, overlap: f64, pa: f64, pb: f64) -> [f64; 4] {
    let sup = &known.supply;
    let sq = |x: f64| crate::plant::valve::signed_sqrt(x, known.valve.dp_transition_pa);
    let open = spool.signum() * (spool.abs() - overlap).max(0.0);
    if open >= 0.0 {
        [
            open * sq(sup.supply_pa - pa),
            0.0,
            -open * sq(pb - sup.tank_pa),
            0.0,
        ]
    } else {
        [
            0.0,
            open * sq(pa - sup.tank_pa),
            0.0,
            -open * sq(sup.supply_pa - pb),
        ]
    }
}

/// The two continuity rows of one sample (module docs, law 2): regressors `[g_A⁺, g_A⁻,
/// −V_A·ṗ_A]` and `[g_B⁺, g_B⁻, −V_B·ṗ_B]` against `A_A·v` and `−A_B·v`, the known laminar
/// leakage moved to the right-hand side. `x` m, `v` m/s, `p` Pa, `dp` Pa/s, `g` from
/// [`orifice_terms`].
#[allow(clippy::too_many_arguments)]
fn push_continuity(
    known: &HydraulicAxis,
    rows: &mut Vec<Vec<f64>>,
    y: &mut Vec<f64>,
    x: f64,
    v: f64,
    p: [f64; 2],
    dp: [f64; 2],
    g: [f64; 4],
) {
    let (c, sup) = (&known.cylinder, &known.supply);
    let (va, vb) = c.volumes(x);
    let cl = known.valve.leak_m3_per_s_pa;
    let leak = |p: f64| cl * (sup.supply_pa - p) - cl * (p - sup.tank_pa);
    rows.push(vec![g[0], g[1], -va * dp[0]]);
    y.push(c.area_a_m2 * v - leak(p[0]));
    rows.push(vec![g[2], g[3], -vb * dp[1]]);
    y.push(-c.area_b_m2 * v - leak(p[1]));
}

/// The residual sum of squares of `y ≈ rows·θ`.
fn residual_ss(rows: &[Vec<f64>], y: &[f64], th: &[f64]) -> f64 {
    rows.iter()
        .zip(y)
        .map(|(r, y)| (y - r.iter().zip(th).map(|(a, b)| a * b).sum::<f64>()).powi(2))
        .sum()
}

/// The flow-and-oil fit's parameters: the coefficients (K⁺, K⁻, 1/β) with their σ, and
/// the overlap found by the scan.
fn push_flow_params(params: &mut Vec<Param>, th: &[f64], sd: &[f64], overlap: f64) {
    // Rated flow at 35 bar: K·√(35e5) m³/s → l/min.
    let rated = (35e5f64).sqrt() * 60_000.0;
    params.push(Param {
        name: "rated_flow_extend_l_per_min",
        value: th[0] * rated,
        std: sd[0] * rated,
    });
    params.push(Param {
        name: "rated_flow_retract_l_per_min",
        value: th[1] * rated,
        std: sd[1] * rated,
    });
    let beta = th[2].recip();
    params.push(Param {
        name: "bulk_modulus_pa",
        value: beta,
        std: sd[2] * beta * beta,
    });
    params.push(Param {
        name: "overlap",
        value: overlap,
        std: 0.0025,
    });
}

/// The force balance's parameters (m, c, F_c, F_0 with their σ); a non-physical mass or
/// a clearly negative friction is an error.
fn push_force_params(params: &mut Vec<Param>, th: &[f64], sd: &[f64]) -> Result<(), IdentifyError> {
    for (j, name) in [(0, "mass_kg"), (1, "viscous_n_s_per_m"), (2, "coulomb_n")] {
        // Mass must be positive; friction may be 0 within its scatter, not clearly negative.
        let bad = if j == 0 {
            th[j].is_nan() || th[j] <= 0.0
        } else {
            th[j].is_nan() || th[j] < -3.0 * sd[j]
        };
        if bad {
            return Err(IdentifyError::Unphysical { name, value: th[j] });
        }
    }
    for (j, name) in ["mass_kg", "viscous_n_s_per_m", "coulomb_n", "load_n"]
        .into_iter()
        .enumerate()
    {
        params.push(Param {
            name,
            value: th[j],
            std: sd[j],
        });
    }

    Ok(())
}

/// The oil column at mid-stroke from the fitted mass and bulk modulus.
fn push_derived(params: &mut Vec<Param>, known: &HydraulicAxis) {
    let tau = std::f64::consts::TAU;
    let c = &known.cylinder;
    let (aa, ab) = (c.area_a_m2, c.area_b_m2);
    let get = |n: &str| {
        params
            .iter()
            .find(|p| p.name == n)
            .map(|p| (p.value, p.std))
    };
    let (Some((beta, sb)), Some((m, sm)), Some((visc, sv))) = (
        get("bulk_modulus_pa"),
        get("mass_kg"),
        get("viscous_n_s_per_m"),
    ) else {
        return;
    };
    let (va, vb) = c.volumes(0.5 * c.stroke_m);
    let k_h = beta * (aa * aa / va + ab * ab / vb);
    let w_h = (k_h / m).sqrt();
    let rel = (sm / m).hypot(sb / beta);
    params.push(Param {
        name: "hydraulic_frequency_hz",
        value: w_h / tau,
        std: 0.5 * rel * w_h / tau,
    });
    params.push(Param {
        name: "hydraulic_damping",
        value: visc / (2.0 * (k_h * m).sqrt()),
        std: sv / (2.0 * (k_h * m).sqrt()),
    });
}

pub mod spoolless;

#[cfg(test)]
mod tests;
