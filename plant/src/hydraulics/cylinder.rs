//! Single-rod cylinder with its chamber volumes, moving mass and the forces on it.
//!
//! `x` is the piston position (m): 0 fully retracted, `L` (stroke) fully extended; `+x`
//! extends. Side A is the piston side (area `A_A = π·D²/4`), side B the rod side
//! (`A_B = A_A − π·d²/4`).
//!
//! ```text
//! V_A = V_0A + A_A·x,   V_B = V_0B + A_B·(L − x)                                  [m³]
//! ṗ_A = E/V_A·(Q_A − A_A·v),   ṗ_B = E/V_B·(Q_B + A_B·v)                           [Pa/s]
//! m·v̇ = A_A·p_A − A_B·p_B − c·v − F_c·tanh(v/v_s) − F_load − F_spring + F_stop    [N]
//! ```
//!
//! * `F_load` — external load, N, positive pushes against extension.
//! * `F_spring = k_c·(x − x_c)` for `x > x_c`, else 0 — a spring contact (the workpiece
//!   under the side press), N.
//! * `F_stop` — the mechanical end stops, a stiff spring-damper that acts only while the
//!   piston is beyond `[0, L]` and only pushes back into the stroke:
//!   `F_stop = max(0, −k_s·x − c_s·v)` below 0, `min(0, −k_s·(x − L) − c_s·v)` beyond L.
//!   With the default `k_s` = 1e10 N/m the piston enters a stop by 8 µm under the full
//!   supply force on the 80 mm bore; `c_s` gives the stop a damping ratio of 1 against
//!   the moving mass (no bounce).

/// `tanh(z)` as `sgn(z)·(1 − e^{−2|z|})/(1 + e^{−2|z|})`, ±1 beyond |z| = 19.1 (where
/// `1 − tanh` is below half an ulp of 1). Absolute error within a few 1e−16 (one `exp`:
/// about a third of the cost of libm's `tanh`, which dominated the simulator's profile).
#[inline(always)]
pub fn tanh(z: f64) -> f64 {
    let a = z.abs();
    if a >= 19.1 {
        return z.signum();
    }
    let t = (-2.0 * a).exp();
    ((1.0 - t) / (1.0 + t)).copysign(z)
}

/// An optional spring contact beyond a position (the workpiece), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Piston position at which contact begins, m.
    pub position_m: f64,
    /// Contact stiffness, N/m.
    pub stiffness_n_per_m: f64,
}

/// Cylinder, moving mass and load parameters, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// Piston area A_A, m².
    pub area_a_m2: f64,
    /// Annulus (rod side) area A_B, m².
    pub area_b_m2: f64,
    /// Stroke L, m.
    pub stroke_m: f64,
    /// Dead volume on side A (valve, hoses, cushion) at x = 0, m³.
    pub dead_volume_a_m3: f64,
    /// Dead volume on side B at x = L, m³.
    pub dead_volume_b_m3: f64,
    /// Effective bulk modulus E (oil, hoses, air), Pa.
    pub bulk_modulus_pa: f64,
    /// Moving mass m (piston, rod, carried load), kg.
    pub mass_kg: f64,
    /// Viscous friction coefficient c, N·s/m.
    pub viscous_n_s_per_m: f64,
    /// Coulomb friction F_c, N.
    pub coulomb_n: f64,
    /// Smoothing speed v_s of `F_c·tanh(v/v_s)`, m/s.
    pub coulomb_smoothing_m_per_s: f64,
    /// External load F_load, N (positive opposes extension).
    pub load_n: f64,
    /// End-stop stiffness k_s, N/m.
    pub stop_stiffness_n_per_m: f64,
    /// End-stop damping c_s, N·s/m.
    pub stop_damping_n_s_per_m: f64,
    /// Optional spring contact.
    pub contact: Option<Contact>,
}

impl Cylinder {
    /// Chamber volumes `(V_A, V_B)` at position `x` (m), m³. Kept positive (≥ 1 % of the
    /// dead volume) even deep inside an end stop.
    #[inline(always)]
    pub fn volumes(&self, x: f64) -> (f64, f64) {
        let va = self.dead_volume_a_m3 + self.area_a_m2 * x;
        let vb = self.dead_volume_b_m3 + self.area_b_m2 * (self.stroke_m - x);
        (
            va.max(0.01 * self.dead_volume_a_m3),
            vb.max(0.01 * self.dead_volume_b_m3),
        )
    }

    /// Friction force `c·v + F_c·tanh(v/v_s)`, N (opposes the motion).
    #[inline(always)]
    pub fn friction_n(&self, v: f64) -> f64 {
        let coulomb = if self.coulomb_n == 0.0 {
            0.0
        } else {
            // v·(1/v_s): the reciprocal is hoisted out of the RK4 stages by the compiler.
            self.coulomb_n * tanh(v * (1.0 / self.coulomb_smoothing_m_per_s))
        };
        self.viscous_n_s_per_m * v + coulomb
    }

    /// Spring-contact force `k_c·(x − x_c)` beyond the contact, else 0, N (opposes extension).
    #[inline(always)]
    pub fn contact_n(&self, x: f64) -> f64 {
        match self.contact {
            Some(c) if x > c.position_m => c.stiffness_n_per_m * (x - c.position_m),
            _ => 0.0,
        }
    }

    /// End-stop force, N (positive pushes towards +x).
    #[inline(always)]
    pub fn stop_n(&self, x: f64, v: f64) -> f64 {
        if x < 0.0 {
            (-self.stop_stiffness_n_per_m * x - self.stop_damping_n_s_per_m * v).max(0.0)
        } else if x > self.stroke_m {
            (-self.stop_stiffness_n_per_m * (x - self.stroke_m) - self.stop_damping_n_s_per_m * v)
                .min(0.0)
        } else {
            0.0
        }
    }

    /// Hydraulic force `A_A·p_A − A_B·p_B`, N.
    #[inline(always)]
    pub fn hydraulic_n(&self, pa: f64, pb: f64) -> f64 {
        self.area_a_m2 * pa - self.area_b_m2 * pb
    }

    /// Piston acceleration `v̇`, m/s².
    #[inline(always)]
    pub fn accel(&self, x: f64, v: f64, pa: f64, pb: f64) -> f64 {
        (self.hydraulic_n(pa, pb) - self.friction_n(v) - self.load_n - self.contact_n(x)
            + self.stop_n(x, v))
            * (1.0 / self.mass_kg)
    }

    /// Hydraulic natural frequency at position `x` (m), Hz:
    /// `√(E·A_A²/(m·V_A) + E·A_B²/(m·V_B)) / 2π`.
    pub fn natural_frequency_hz(&self, x: f64) -> f64 {
        let (va, vb) = self.volumes(x);
        let e = self.bulk_modulus_pa;
        let m = self.mass_kg;
        let w2 = e * self.area_a_m2 * self.area_a_m2 / (m * va)
            + e * self.area_b_m2 * self.area_b_m2 / (m * vb);
        w2.sqrt() / (2.0 * std::f64::consts::PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_tanh_matches_libm() {
        let mut worst: f64 = 0.0;
        for i in -40_000..=40_000 {
            let z = f64::from(i) * 1e-3;
            worst = worst.max((tanh(z) - z.tanh()).abs());
        }
        assert!(worst < 1e-15, "{worst}");
        assert_eq!(tanh(0.0), 0.0);
        assert_eq!(tanh(1e3), 1.0);
        assert_eq!(tanh(-1e3), -1.0);
    }
}
