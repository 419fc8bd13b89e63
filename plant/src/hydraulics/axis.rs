//! One hydraulic axis (valve + cylinder + load) and its fixed-step RK4 integration.
//!
//! State `s = [x, v, p_A, p_B, x_v, ẋ_v]` (m, m/s, Pa, Pa, 1, 1/s), input `u ∈ [−1, 1]`
//! held constant over a step. The derivative is the valve ([`super::valve`]) and
//! cylinder ([`super::cylinder`]) equations; the pressure clamps `[0, k·p_s]` and the
//! spool travel `[−1, 1]` are constraints:
//!
//! * in the derivative, a pressure at a clamp does not move further out of it
//!   (`ṗ := 0` when `p ≤ 0 ∧ ṗ < 0` or `p ≥ p_max ∧ ṗ > 0`);
//! * after each step the state is projected back inside (`p := clamp(p, 0, p_max)`,
//!   `x_v := clamp(x_v, −1, 1)` with the spool speed zeroed if it points outwards).
//!
//! One step of the classic 4-stage Runge–Kutta method with step `h` (s):
//!
//! ```text
//! k1 = f(s),  k2 = f(s + h/2·k1),  k3 = f(s + h/2·k2),  k4 = f(s + h·k3)
//! s ← s + h/6·(k1 + 2·k2 + 2·k3 + k4)
//! ```
//!
//! Everything is `f64` and allocation-free.

use super::cylinder::Cylinder;
use super::valve::Valve;

/// Hydraulic supply (an ideal constant-pressure source and tank), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Supply {
    /// Supply pressure p_s, Pa.
    pub supply_pa: f64,
    /// Tank pressure p_T, Pa.
    pub tank_pa: f64,
    /// Upper pressure clamp p_max (PLANT.md: 1.1·p_s), Pa. The lower clamp is 0.
    pub max_pa: f64,
}

/// Index of the piston position `x` (m) in the state vector.
pub const X: usize = 0;
/// Index of the piston speed `v` (m/s).
pub const V: usize = 1;
/// Index of the chamber-A pressure `p_A` (Pa).
pub const PA: usize = 2;
/// Index of the chamber-B pressure `p_B` (Pa).
pub const PB: usize = 3;
/// Index of the normalised spool position `x_v`.
pub const XV: usize = 4;
/// Index of the spool speed `ẋ_v` (1/s).
pub const VV: usize = 5;

/// The state vector `[x, v, p_A, p_B, x_v, ẋ_v]`.
pub type State = [f64; 6];

/// A hydraulic axis: parameters and state.
#[derive(Clone, Debug, PartialEq)]
pub struct HydraulicAxis {
    /// The valve.
    pub valve: Valve,
    /// The cylinder and its load.
    pub cylinder: Cylinder,
    /// The supply.
    pub supply: Supply,
    /// The state `[x, v, p_A, p_B, x_v, ẋ_v]`.
    pub state: State,
}

impl HydraulicAxis {
    /// An axis at rest at `x0_m` in the initial state of PLANT.md: spool centred, piston at
    /// rest, pressures in leakage and force balance ([`HydraulicAxis::rest_pressures`]).
    pub fn at_rest(valve: Valve, cylinder: Cylinder, supply: Supply, x0_m: f64) -> Self {
        let mut axis = Self {
            valve,
            cylinder,
            supply,
            state: [x0_m, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        let (pa, pb) = axis.rest_pressures(x0_m);
        axis.state[PA] = pa;
        axis.state[PB] = pb;
        axis
    }

    /// Chamber pressures (Pa) with the spool centred and the piston at rest at `x` (m).
    ///
    /// With the spool centred only the four leakage paths feed the chambers. The
    /// pressures are those at which (a) the two leakage flows are those of one rigid
    /// piston moving at some creep speed `v*`,
    /// `C_L·(p_s + p_T − 2p_A) = A_A·v*` and `C_L·(p_s + p_T − 2p_B) = −A_B·v*`, and (b)
    /// the forces on the piston at rest balance, `A_A·p_A − A_B·p_B = F_load + F_spring(x)`.
    /// This is linear in `v*`:
    ///
    /// ```text
    /// v* = ((A_A − A_B)·(p_s + p_T)/2 − F) / ((A_A² + A_B²)/(2·C_L))
    /// p_A = (p_s + p_T − A_A·v*/C_L)/2,   p_B = (p_s + p_T + A_B·v*/C_L)/2
    /// ```
    ///
    /// clamped to `[0, p_max]`. The piston then accelerates from rest towards `v*` (on the
    /// reference machine 69 µm/s — a centred, critically lapped valve does not hold a
    /// single-rod cylinder; the controller does).
    pub fn rest_pressures(&self, x: f64) -> (f64, f64) {
        let c = &self.cylinder;
        let s = &self.supply;
        let cl = self.valve.leak_m3_per_s_pa;
        let sum = s.supply_pa + s.tank_pa;
        let f = c.load_n + c.contact_n(x) - c.stop_n(x, 0.0);
        let (aa, ab) = (c.area_a_m2, c.area_b_m2);
        let v_creep = ((aa - ab) * sum / 2.0 - f) / ((aa * aa + ab * ab) / (2.0 * cl));
        let pa = (sum - aa * v_creep / cl) / 2.0;
        let pb = (sum + ab * v_creep / cl) / 2.0;
        (pa.clamp(0.0, s.max_pa), pb.clamp(0.0, s.max_pa))
    }

    /// Steady full-opening speed with no external load, m/s (positive), closed form.
    ///
    /// At steady speed the two metering lands pass `A_A·v` and `A_B·v`, so (extending)
    /// `p_A = p_s − (A_A·v/K_v)²`, `p_B = p_T + (A_B·v/K_v)²`, and the force balance
    /// `A_A·p_A − A_B·p_B = F_f(v)` gives (retracting mirrored)
    ///
    /// ```text
    /// extend:   v² = K_v²·(A_A·p_s − A_B·p_T − F_f(v)) / (A_A³ + A_B³)
    /// retract:  v² = K_v²·(A_B·p_s − A_A·p_T − F_f(v)) / (A_A³ + A_B³)
    /// ```
    ///
    /// with the friction `F_f(v) = c·v + F_c·tanh(v/v_s)` solved by fixed-point iteration.
    /// The leakage (about 0.1 % of the flow) is left out.
    pub fn no_load_speed_m_per_s(&self, extend: bool) -> f64 {
        let c = &self.cylinder;
        let (aa, ab) = (c.area_a_m2, c.area_b_m2);
        let (ps, pt) = (self.supply.supply_pa, self.supply.tank_pa);
        let drive = if extend {
            aa * ps - ab * pt
        } else {
            ab * ps - aa * pt
        };
        let kv = self.valve.kv;
        let mut v = 0.0;
        for _ in 0..60 {
            v = kv * ((drive - c.friction_n(v)).max(0.0) / (aa.powi(3) + ab.powi(3))).sqrt();
        }
        v
    }

    /// The state derivative `ṡ = f(s, u)`.
    #[inline(always)]
    pub fn derivative(&self, s: &State, u: f64) -> State {
        let c = &self.cylinder;
        let sup = &self.supply;
        let (x, v, pa, pb, xv, vv) = (s[X], s[V], s[PA], s[PB], s[XV], s[VV]);
        let (qa, qb) = self.valve.flows(xv, pa, pb, sup.supply_pa, sup.tank_pa);
        let (va, vb) = c.volumes(x);
        // E/V_A and E/V_B with one division.
        let e_vv = c.bulk_modulus_pa / (va * vb);
        let dpa = clamp_rate(pa, e_vv * vb * (qa - c.area_a_m2 * v), sup.max_pa);
        let dpb = clamp_rate(pb, e_vv * va * (qb + c.area_b_m2 * v), sup.max_pa);
        [
            v,
            c.accel(x, v, pa, pb),
            dpa,
            dpb,
            vv,
            self.valve.spool_accel(u, xv, vv),
        ]
    }

    /// Advances the state by one RK4 step of `h` seconds with the valve command `u`.
    #[inline]
    pub fn step(&mut self, u: f64, h: f64) {
        let s = self.state;
        let k1 = self.derivative(&s, u);
        let k2 = self.derivative(&axpy(&s, 0.5 * h, &k1), u);
        let k3 = self.derivative(&axpy(&s, 0.5 * h, &k2), u);
        let k4 = self.derivative(&axpy(&s, h, &k3), u);
        let mut n = s;
        for i in 0..6 {
            n[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        n[PA] = n[PA].clamp(0.0, self.supply.max_pa);
        n[PB] = n[PB].clamp(0.0, self.supply.max_pa);
        if n[XV] > 1.0 {
            n[XV] = 1.0;
            n[VV] = n[VV].min(0.0);
        } else if n[XV] < -1.0 {
            n[XV] = -1.0;
            n[VV] = n[VV].max(0.0);
        }
        self.state = n;
    }

    /// Piston position, m.
    pub fn x_m(&self) -> f64 {
        self.state[X]
    }

    /// Piston speed, m/s.
    pub fn v_m_per_s(&self) -> f64 {
        self.state[V]
    }

    /// Chamber pressures `(p_A, p_B)`, Pa.
    pub fn pressures_pa(&self) -> (f64, f64) {
        (self.state[PA], self.state[PB])
    }

    /// Normalised spool position `x_v`.
    pub fn spool(&self) -> f64 {
        self.state[XV]
    }

    /// Hydraulic force `A_A·p_A − A_B·p_B`, N.
    pub fn force_n(&self) -> f64 {
        self.cylinder.hydraulic_n(self.state[PA], self.state[PB])
    }
}

/// `s + a·k`.
#[inline(always)]
fn axpy(s: &State, a: f64, k: &State) -> State {
    let mut r = *s;
    for i in 0..6 {
        r[i] += a * k[i];
    }
    r
}

/// A pressure rate that does not push a clamped pressure further out of `[0, max]`.
#[inline(always)]
fn clamp_rate(p: f64, dp: f64, max: f64) -> f64 {
    if (p <= 0.0 && dp < 0.0) || (p >= max && dp > 0.0) {
        0.0
    } else {
        dp
    }
}
