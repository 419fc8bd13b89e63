//! Proportional 4/3 valve: a 2nd-order spool and four metering lands.
//!
//! **Spool.** The normalised spool position `x_v` follows the command `u ∈ [−1, 1]`
//! through a 2nd-order lag:
//!
//! ```text
//! ẍ_v = ω_v²·(u − x_v) − 2·ζ_v·ω_v·ẋ_v            [1/s²]
//! ```
//!
//! and the metering opening is `sat(x_v) ∈ [−1, 1]` (the spool's mechanical travel; the
//! state itself is stopped at ±1 by [`crate::hydraulics::HydraulicAxis`] after every step).
//!
//! **Lands.** Critically lapped, turbulent orifice flow per land
//!
//! ```text
//! Q = K_v · |x_v| · φ(Δp),   K_v = Q_n / √Δp_n        [m³/s, K_v in m³/(s·√Pa)]
//! x_v ≥ 0:  Q_A = +K_v·x_v·φ(p_s − p_A),   Q_B = −K_v·x_v·φ(p_B − p_T)   (P→A, B→T)
//! x_v < 0:  Q_A = −K_v·|x_v|·φ(p_A − p_T), Q_B = +K_v·|x_v|·φ(p_s − p_B)  (A→T, P→B)
//! ```
//!
//! plus laminar leakage `C_L·Δp` across each of the four lands (it keeps both chamber
//! pressures defined at `x_v = 0`):
//!
//! ```text
//! Q_A += C_L·(p_s − p_A) − C_L·(p_A − p_T),   Q_B += C_L·(p_s − p_B) − C_L·(p_B − p_T)
//! ```
//!
//! `φ` is the signed square root `sgn(Δp)·√|Δp|`, exact for `|Δp| ≥ p_tr` and linear
//! below (laminar transition, continuous at `p_tr`):
//!
//! ```text
//! φ(Δp) = Δp / √max(|Δp|, p_tr)                                      [√Pa]
//! ```
//!
//! The linear part removes the infinite slope of `√` at `Δp = 0`, which would otherwise
//! make the pressure equations arbitrarily stiff for the fixed-step integrator near a
//! closed chamber. Default `p_tr` = 0.01 bar: the largest linearised stiffness of a
//! chamber, `E/V_0·K_v/√p_tr` = 3.2e4 1/s on the reference machine, is 0.3/h at the 10 µs
//! step, well inside RK4's stability region (2.8/h).

/// Valve parameters in SI units (built and validated from a scenario).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Valve {
    /// Spool natural frequency ω_v, rad/s (PLANT.md: 2π·60).
    pub omega_rad_s: f64,
    /// Spool damping ratio ζ_v (PLANT.md: 0.8).
    pub zeta: f64,
    /// Flow coefficient per land at full opening, `K_v = Q_n/√Δp_n`, m³/(s·√Pa).
    pub kv: f64,
    /// Laminar leakage per land, m³/(s·Pa) (PLANT.md: 1e−13).
    pub leak_m3_per_s_pa: f64,
    /// Transition pressure of the regularised square root, Pa.
    pub dp_transition_pa: f64,
}

/// Signed square root with a laminar transition, `φ(Δp) = Δp / √max(|Δp|, p_tr)`, √Pa
/// (`p_tr` in Pa).
#[inline(always)]
pub fn signed_sqrt(dp_pa: f64, p_tr: f64) -> f64 {
    let a = dp_pa.abs();
    // √a above the transition, a·(1/√p_tr) below it: the reciprocal is the same for every
    // call of a step, so the compiler hoists it and no division is left here.
    let r = if a >= p_tr {
        a.sqrt()
    } else {
        a * p_tr.sqrt().recip()
    };
    r.copysign(dp_pa)
}

impl Valve {
    /// Flow coefficient `K_v = Q_n/√Δp_n` from the rated flow `q_n` (m³/s) at the rated
    /// pressure drop per land `dp_n` (Pa).
    pub fn kv_from_rating(q_n_m3_s: f64, dp_n_pa: f64) -> f64 {
        q_n_m3_s / dp_n_pa.sqrt()
    }

    /// Spool acceleration `ẍ_v` (1/s²) for command `u`, position `x_v` and speed `ẋ_v` (1/s).
    #[inline(always)]
    pub fn spool_accel(&self, u: f64, xv: f64, vv: f64) -> f64 {
        let w = self.omega_rad_s;
        w * w * (u - xv) - 2.0 * self.zeta * w * vv
    }

    /// Flows into chamber A and chamber B, m³/s, for spool position `x_v` (saturated to
    /// ±1 here), chamber pressures `p_a`, `p_b`, supply `p_s` and tank `p_t` (Pa).
    #[inline(always)]
    pub fn flows(&self, xv: f64, pa: f64, pb: f64, ps: f64, pt: f64) -> (f64, f64) {
        let open = xv.clamp(-1.0, 1.0);
        let tr = self.dp_transition_pa;
        let k = self.kv * open;
        let (qa, qb) = if open >= 0.0 {
            (k * signed_sqrt(ps - pa, tr), -k * signed_sqrt(pb - pt, tr))
        } else {
            (k * signed_sqrt(pa - pt, tr), -k * signed_sqrt(ps - pb, tr))
        };
        let cl = self.leak_m3_per_s_pa;
        (
            qa + cl * (ps - pa) - cl * (pa - pt),
            qb + cl * (ps - pb) - cl * (pb - pt),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn valve() -> Valve {
        Valve {
            omega_rad_s: 2.0 * std::f64::consts::PI * 60.0,
            zeta: 0.8,
            kv: Valve::kv_from_rating(24e-3 / 60.0, 35e5),
            leak_m3_per_s_pa: 1e-13,
            dp_transition_pa: 1e3,
        }
    }

    #[test]
    fn rated_flow_at_rated_drop() {
        let v = valve();
        // Full opening, A at p_s − 35 bar: Q_A = Q_n minus the net leakage
        // C_L·(35 − 125) bar = −0.9 cm³/s.
        let (qa, _) = v.flows(1.0, 125e5, 35e5, 160e5, 0.0);
        let want = 24e-3 / 60.0 + 1e-13 * (35e5 - 125e5);
        assert!((qa / want - 1.0).abs() < 1e-6, "qa = {qa}");
    }

    #[test]
    fn direction_logic() {
        let v = valve();
        let (qa, qb) = v.flows(0.5, 80e5, 80e5, 160e5, 0.0);
        assert!(qa > 0.0 && qb < 0.0);
        let (qa, qb) = v.flows(-0.5, 80e5, 80e5, 160e5, 0.0);
        assert!(qa < 0.0 && qb > 0.0);
        // Saturated opening: 2 gives the same flow as 1.
        assert_eq!(
            v.flows(2.0, 1e5, 1e5, 160e5, 0.0),
            v.flows(1.0, 1e5, 1e5, 160e5, 0.0)
        );
    }

    #[test]
    fn centred_spool_only_leaks_towards_mid_pressure() {
        let v = valve();
        let (qa, qb) = v.flows(0.0, 80e5, 80e5, 160e5, 0.0);
        assert!(qa.abs() < 1e-20 && qb.abs() < 1e-20);
        let (qa, _) = v.flows(0.0, 100e5, 80e5, 160e5, 0.0);
        assert!((qa - 1e-13 * (60e5 - 100e5)).abs() < 1e-15);
    }

    #[test]
    fn regularised_root_is_sqrt_above_transition() {
        let tr = 1e3;
        for dp in [1e3, 1e4, 1e5, 35e5, 160e5] {
            let r = signed_sqrt(dp, tr) / dp.sqrt();
            assert!((r - 1.0).abs() < 1e-15, "dp={dp}: {r}");
            assert_eq!(signed_sqrt(-dp, tr), -signed_sqrt(dp, tr));
        }
        assert_eq!(signed_sqrt(0.0, tr), 0.0);
        assert!((signed_sqrt(500.0, tr) - 500.0 / tr.sqrt()).abs() < 1e-12);
    }
}
