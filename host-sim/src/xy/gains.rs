//! Gains of the four X–Y controllers (defaults = the tuned values of `docs/npid.md`).

use anyhow::{anyhow, Result};
use hydra_xy::npid::{
    FalConfig, FhanConfig, NpidCoeffs, NpidConfig, PidCoeffs, PidConfig, VelocityFfCoeffs,
    VelocityFfConfig, XyCoeffs,
};
use serde::{Deserialize, Serialize};

/// Linear PID gains (per axis or contour).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinGains {
    /// kp, LSB/µm.
    pub kp: f64,
    /// ki, LSB/(µm·s).
    pub ki: f64,
    /// kd, LSB/(µm/s).
    pub kd: f64,
}

/// Nonlinear PID gains (per axis or contour); α and δ per term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NlGains {
    /// β0 (integral), LSB/(µm·s)^α0.
    pub beta0: f64,
    /// β1 (proportional), LSB/µm^α1.
    pub beta1: f64,
    /// β2 (derivative), LSB/(µm/s)^α2.
    pub beta2: f64,
    /// α0, α1, α2.
    pub alpha: [f64; 3],
    /// δ0 (µm·s), δ1 (µm), δ2 (µm/s).
    pub delta: [f64; 3],
    /// TD speed factor r, µm/s².
    pub td_r: f64,
    /// TD filter factor h0, s.
    pub td_h0: f64,
}

/// Velocity feed-forward of both axes (used by all four controllers alike).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FfGains {
    /// X: command per speed extending / retracting, LSB/(mm/s).
    pub x_lsb_per_mm_s: [f64; 2],
    /// Y: command per speed extending / retracting, LSB/(mm/s).
    pub y_lsb_per_mm_s: [f64; 2],
    /// Lead time T_lead, s.
    pub lead_s: f64,
    /// Fraction of the identified gains applied (0 = no feed-forward, 1 = full).
    pub scale: f64,
    /// Friction compensation: oil-column deflection under Coulomb friction D_c = F_c/k_h,
    /// µm, `[X, Y]` (0 = off; see `hydra_xy::npid::feedforward`).
    #[serde(default)]
    pub friction_um: [f64; 2],
    /// Reversal speed band v_s of the friction compensation, mm/s.
    #[serde(default = "default_friction_speed")]
    pub friction_speed_mm_s: f64,
}

fn default_friction_speed() -> f64 {
    1.0
}

/// Every gain of the scenario (a TOML file for `--gains`; missing tables keep the
/// defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Gains {
    /// Linear PID of each axis in `independent` (tuned on its own).
    pub axis_independent: LinGains,
    /// Linear PID of each axis in `ccc`.
    pub axis_linear: LinGains,
    /// Linear PID on ε (`ccc`).
    pub contour_linear: LinGains,
    /// Nonlinear PID of each axis (`nccc`).
    pub axis_nonlinear: NlGains,
    /// Nonlinear PID on ε (`nccc`).
    pub contour_nonlinear: NlGains,
    /// Nonlinear PID of each axis in `nccc-est` (tuned on its own: the estimator's ε
    /// has a different lag and noise than the model's).
    pub axis_estimated: NlGains,
    /// Nonlinear PID on the estimated ε (`nccc-est`).
    pub contour_estimated: NlGains,
    /// Velocity feed-forward (all controllers).
    pub feedforward: FfGains,
}

impl Default for Gains {
    fn default() -> Self {
        Self {
            axis_independent: LinGains {
                kp: 1.2,
                ki: 15.0,
                kd: 0.0,
            },
            // `--tune` step 3b: kp 0.8, ki 15, kc 0.4 (cost 16.9 µm, tied with kc = 0,
            // i.e. the independent setting). `independent`: step 3a (16.9 µm).
            axis_linear: LinGains {
                kp: 0.8,
                ki: 15.0,
                kd: 0.0,
            },
            contour_linear: LinGains {
                kp: 0.4,
                ki: 0.0,
                kd: 0.0,
            },
            // `--tune` step 3c/3d (cost includes the parabola): `nccc` and `nccc-est`
            // choose the same setting: axis kp 0.8 (fal α1 1, i.e. linear), ki 15, TD
            // h0 1 ms; contour kc 0.4 (α1 1), no integral, no β2.
            axis_nonlinear: TUNED_NL_AXIS,
            contour_nonlinear: TUNED_NL_CONTOUR,
            axis_estimated: TUNED_NL_AXIS,
            contour_estimated: TUNED_NL_CONTOUR,
            // Identified by `host-sim xy --tune` (steps 1 and 1b); lead and friction
            // band: step 2 (lead 2 ms: 16.6 µm vs 16.7 at 0; v_s 4 mm/s: 12.5 µm vs
            // 16.6 without friction compensation).
            feedforward: FfGains {
                x_lsb_per_mm_s: [13.713, 16.766],
                y_lsb_per_mm_s: [19.410, 23.818],
                lead_s: 0.002,
                scale: 1.0,
                friction_um: [10.732, 10.683],
                friction_speed_mm_s: 4.0,
            },
        }
    }
}

/// Tuned axis NPID of `nccc` / `nccc-est`: kp 0.8 LSB/µm with fal α1 = 1 (linear,
/// β1 = kp), β0 = ki = 15 LSB/(µm·s), no β2, TD h0 1 ms.
const TUNED_NL_AXIS: NlGains = NlGains {
    beta0: 15.0,
    beta1: 0.8,
    beta2: 0.0,
    alpha: [1.0, 1.0, 1.0],
    delta: [1.0, 1.0, 1.0],
    td_r: 5e7,
    td_h0: 1e-3,
};

/// Tuned contour NPID of `nccc` / `nccc-est`: kc 0.4 LSB/µm with fal α1 = 1 (linear),
/// no integral (β0 = 0), no β2, TD h0 1 ms.
const TUNED_NL_CONTOUR: NlGains = NlGains {
    beta0: 0.0,
    beta1: 0.4,
    beta2: 0.0,
    alpha: [1.0, 1.0, 1.0],
    delta: [1.0, 1.0, 1.0],
    td_r: 5e7,
    td_h0: 1e-3,
};

/// Output limit of every law, LSB.
const OUT_LIMIT: f64 = 2047.0;

fn lin(g: &LinGains) -> Result<PidCoeffs> {
    PidConfig {
        period_s: 1e-3,
        kp_lsb_per_um: g.kp,
        ki_lsb_per_um_s: g.ki,
        kd_lsb_s_per_um: g.kd,
        derivative_filter_s: 2e-3,
        integral_limit_lsb: 1000.0,
        output_limit_lsb: OUT_LIMIT,
    }
    .build()
    .map_err(|e| anyhow!("linear PID gains: {e}"))
}

fn nl(g: &NlGains) -> Result<NpidCoeffs> {
    let td = FhanConfig {
        r_um_per_s2: g.td_r,
        h0_s: g.td_h0,
    };
    let fal = |i: usize| FalConfig {
        alpha: g.alpha[i],
        delta: g.delta[i],
    };
    NpidConfig {
        period_s: 1e-3,
        td_reference: td,
        td_measurement: td,
        beta0: g.beta0,
        beta1: g.beta1,
        beta2: g.beta2,
        fal0: fal(0),
        fal1: fal(1),
        fal2: fal(2),
        // |β0·e0| ≤ 1000 LSB.
        integral_limit_um_s: if g.beta0 > 0.0 {
            (1000.0 / g.beta0).min(1e6)
        } else {
            0.0
        },
        output_limit_lsb: OUT_LIMIT,
    }
    .build()
    .map_err(|e| anyhow!("nonlinear PID gains: {e}"))
}

fn ff(k: [f64; 2], friction_um: f64, g: &FfGains) -> Result<VelocityFfCoeffs> {
    VelocityFfConfig {
        period_s: 1e-3,
        extend_lsb_per_mm_s: k[0] * g.scale,
        retract_lsb_per_mm_s: k[1] * g.scale,
        lead_s: g.lead_s,
        friction_deflection_um: friction_um,
        friction_speed_mm_s: g.friction_speed_mm_s,
    }
    .build()
    .map_err(|e| anyhow!("feed-forward gains: {e}"))
}

impl Gains {
    /// Feed-forward coefficients `[X, Y]`.
    pub fn ff_coeffs(&self) -> Result<[VelocityFfCoeffs; 2]> {
        let g = &self.feedforward;
        Ok([
            ff(g.x_lsb_per_mm_s, g.friction_um[0], g)?,
            ff(g.y_lsb_per_mm_s, g.friction_um[1], g)?,
        ])
    }

    /// Coefficients of `independent` / `ccc`.
    /// `independent` = true: the axes use `axis_independent` (no contour law acts).
    pub fn linear_coeffs(&self, independent: bool) -> Result<XyCoeffs<PidCoeffs>> {
        let a = lin(if independent {
            &self.axis_independent
        } else {
            &self.axis_linear
        })?;
        Ok(XyCoeffs {
            x: a,
            y: a,
            contour: lin(&self.contour_linear)?,
        })
    }

    /// Coefficients of `nccc` (`estimated` = false) or `nccc-est` (true).
    pub fn nonlinear_coeffs(&self, estimated: bool) -> Result<XyCoeffs<NpidCoeffs>> {
        let (axis, contour) = if estimated {
            (&self.axis_estimated, &self.contour_estimated)
        } else {
            (&self.axis_nonlinear, &self.contour_nonlinear)
        };
        let a = nl(axis)?;
        Ok(XyCoeffs {
            x: a,
            y: a,
            contour: nl(contour)?,
        })
    }
}
