//! Parametric interpolation with adaptive extra points (SPEC §C, step 1).
//!
//! Each servo period Ts at feed v the parameter advances by the 2nd-order Taylor step
//! of u(s) (derivatives at u_j):
//!
//! ```text
//! ΔS = v·Ts
//! u_{j+1} = u_j + ΔS/|r′| − ΔS²·(r′·r″)/(2|r′|⁴)
//!         = u_j + a − a²·(û·r″)/(2|r′|),        a = ΔS/|r′|, û = r′/|r′|
//! ```
//!
//! r(u_{j+1}) is the **ordinary point**, the motion command. Between u_j and u_{j+1} the
//! **extra points**, only for the estimator, sit at the arc lengths k·ΔS/(h_j + 1),
//! k = 1 … h_j, on the same expansion:
//!
//! ```text
//! u_k = u_j + a_k − a_k²·(û·r″)/(2|r′|),     a_k = k·ΔS/((h_j + 1)·|r′|)
//! ```
//!
//! This is the interpolator run with ΔS/(h_j + 1) (the seed's step 1) with the
//! derivatives taken once per period at u_j rather than re-evaluated at every extra
//! point: the points lie exactly on the path (only their spacing carries the O(ΔS³)
//! truncation of the expansion, as the ordinary step does), and an extra point costs one
//! position evaluation and two products instead of a full evaluation, a normalisation
//! and a Taylor step (measured on a Cortex-M4: half the cost for a circle). The number
//! of extra points is
//!
//! ```text
//! h_j = min(⌊Q·κ_j·v_j⌋, h_max, H)       κ_j = |r′ × r″|/|r′|³ at u_j, Q in s
//! ```
//!
//! With h_j + 1 > Q·κ·v the extra chords are shorter than Ts/(Q·κ), so their sagitta
//! L²κ/8 stays below max(v·Ts²/(8Q), ΔS²κ/(8(H+1)²)) whatever the curvature: the
//! estimator's chord error has that bound (see `docs/contour.md`).
//!
//! Formats: v is [`VelUmPerS`] (`I24F8` µm/s, negative feed is treated as 0: the path
//! is run forward only); Ts is kept in seconds as Q24.40 (`i64`, exact to 10⁻¹² s);
//! Q in seconds as Q16.16; ΔS in µm as Q32.32, capped at 65 536 µm per period; u in
//! [`super::Param`]. No float and no allocation per period; the window is written in
//! place.
//!
//! Work per period: one full path evaluation, one normalisation of r′ (of the new point,
//! kept for the next period's step), one curvature, one division by h + 1 (four 32-bit
//! `udiv`s, [`hydra_core::fixed_point`]'s `div_small`, only when h > 0), and per extra point one
//! position evaluation ([`ParametricPath::position`]) and two `i64×i32` products (the
//! `i128` form only for a curvature term beyond 2^31); h ≤ min(h_max, H). Every product
//! of the Taylor step and of κ takes a one-`smull` path when its operand fits 32 bits.
//! Measured on a Cortex-M4 (`./bench-m4.sh`): about 70 instructions per extra point on
//! the patent parabola, more on a circle (sin/cos), so h_max is also the CPU-budget knob.
//! A tick that does not advance (feed 0, path finished) leaves the window unchanged.

use super::geom::rel;
use super::path::{curvature_q32_per_um, deriv_frame, DerivFrame, ParametricPath, PathPoint};
use super::window::{clamp_pos, ContourWindow, OrdinaryPoint};
use super::{Param, PosFine, UnitQ30, Xy};
use hydra_core::fixed_point::{
    div_small, mul_shr30_round_i32_i64, mul_shr32_round_i64_i32, mul_shr_round_i64_by_u32, sat_i64,
};
use hydra_core::units::{PosUm, VelUmPerS};

/// Largest advance per period, Q32.32 µm (65 536 µm).
const MAX_STEP_Q32: i64 = 1 << 48;

/// Interpolator settings, engineering units (validated by [`InterpConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterpConfig {
    /// Servo period Ts, µs (10 … 1 000 000).
    pub period_us: u32,
    /// Q of h = ⌊Q·κ·v⌋, seconds (0 … 1000; 0 = no extra points). The seed used 1 s.
    pub q_s: f32,
    /// Cap on the extra points per period (≤ 4096; the window's `H` caps it too).
    pub h_max: u16,
}

impl Default for InterpConfig {
    fn default() -> Self {
        Self {
            period_us: 1000,
            q_s: 1.0,
            h_max: 63,
        }
    }
}

/// An interpolator setting out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InterpConfigError {
    /// `period_us` not in 10 … 1 000 000.
    Period,
    /// `q_s` negative, above 1000 or not finite.
    Q,
    /// `h_max` above 4096.
    HMax,
}

/// Validated interpolator coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InterpCoeffs {
    /// Ts in seconds, Q24.40.
    ts_q40: i64,
    /// Q in seconds, Q16.16.
    q_q16: i64,
    h_max: u16,
}

impl InterpConfig {
    /// Validates the settings.
    pub fn build(&self) -> Result<InterpCoeffs, InterpConfigError> {
        if !(10..=1_000_000).contains(&self.period_us) {
            return Err(InterpConfigError::Period);
        }
        if !self.q_s.is_finite() || self.q_s < 0.0 || self.q_s > 1000.0 {
            return Err(InterpConfigError::Q);
        }
        if self.h_max > 4096 {
            return Err(InterpConfigError::HMax);
        }
        // Ts·2^40 / 10⁶, rounded (integer arithmetic, exact inputs).
        let ts = (u128::from(self.period_us) << 40).saturating_add(500_000) / 1_000_000;
        Ok(InterpCoeffs {
            ts_q40: ts as i64,
            q_q16: (f64::from(self.q_s) * 65_536.0 + 0.5) as i64,
            h_max: self.h_max,
        })
    }
}

impl InterpCoeffs {
    /// Advance per period ΔS = v·Ts for a feed, Q32.32 µm raw (capped).
    ///
    /// v (Q8, 0 … 2^31) · Ts (Q40, ≤ 2^40) → Q48 → Q32, rounded, without an `i128`:
    /// Ts = T_h·2^32 + T_l, v·Ts/2^16 = v·T_h·2^16 + (v·T_l + 2^15)/2^16 exactly
    /// (v·T_h < 2^39, v·T_l < 2^63).
    pub(crate) fn step_q32(&self, feed: VelUmPerS) -> i64 {
        let v = feed.to_bits().max(0) as u32;
        let (th, tl) = ((self.ts_q40 >> 32) as u32, self.ts_q40 as u32);
        let hi = u64::from(v).wrapping_mul(u64::from(th)) << 16;
        let lo = u64::from(v)
            .wrapping_mul(u64::from(tl))
            .wrapping_add(1 << 15)
            >> 16;
        (hi.wrapping_add(lo) as i64).min(MAX_STEP_Q32)
    }

    /// Q·v, µm in Q8 raw: Q (Q16, ≤ 1000·2^16 < 2^26) · v (Q8, < 2^31) < 2^57, one
    /// `u32×u32→u64` product, rounded.
    fn qv_q8(&self, feed: VelUmPerS) -> i64 {
        let v = u64::from(feed.to_bits().max(0) as u32);
        let q = u64::from(self.q_q16.clamp(0, i64::from(u32::MAX)) as u32);
        (q.wrapping_mul(v).wrapping_add(1 << 15) >> 16) as i64
    }

    /// h = min(⌊Q·κ·v⌋, h_max, cap) for a curvature in 1/µm (Q32 raw).
    pub(crate) fn extra_count(&self, kappa_q32: i64, feed: VelUmPerS, cap: usize) -> usize {
        // κ (Q32) · Qv (Q8) → Q40 → integer, floored. Both below 2^32 (a radius above
        // 1 µm, Q·v below 16.7 m): one `umull`; otherwise the exact `i128` product.
        let (k, qv) = (kappa_q32.saturating_abs(), self.qv_q8(feed));
        let h = if k <= i64::from(u32::MAX) && (0..=i64::from(u32::MAX)).contains(&qv) {
            ((k as u64).wrapping_mul(qv as u64) >> 40) as i64
        } else {
            sat_i64((k as i128).wrapping_mul(qv as i128) >> 40)
        };
        let cap = cap.min(usize::from(self.h_max)) as i64;
        h.clamp(0, cap) as usize
    }
}

/// The 2nd-order Taylor expansion of u(s) at one point of the path:
///
/// ```text
/// u(u_j, s) = u_j + a − a²·c,   a = s/|r′|,   c = (û·r″)/(2|r′|)
/// ```
///
/// (= u_j + s/|r′| − s²·(r′·r″)/(2|r′|⁴)). `inv_q30` is 1/|r′| (Q30, units of u per µm),
/// `c_q32` is c (Q32, per unit of u).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Taylor {
    inv_q30: i64,
    c_q32: i64,
}

impl Taylor {
    /// The expansion at a point (one normalisation of r′, three products).
    #[inline(always)]
    pub(crate) fn at(p: &PathPoint, f: &DerivFrame) -> Self {
        let tdot = mul_shr30_round_i32_i64(f.ux, p.d2.x.to_bits())
            .saturating_add(mul_shr30_round_i32_i64(f.uy, p.d2.y.to_bits()));
        Taylor {
            inv_q30: f.inv_q30,
            // (û·r″)(Q32)·(1/|r′|)(Q30)/2 → Q32.
            c_q32: mul_shr_round_i64_by_u32(tdot, f.inv_q30, 31),
        }
    }

    /// a = s/|r′| for an arc length `s` (Q32 µm), Q32 units of u.
    pub(crate) fn first(&self, s: i64) -> i64 {
        mul_shr_round_i64_by_u32(s, self.inv_q30, 30)
    }

    /// Δu = a − a²·c for a first-order step `a` (Q32). Where the second-order term would
    /// reverse the step (an arc longer than the radius of curvature) the first-order step
    /// is used.
    pub(crate) fn du(&self, a: i64) -> i64 {
        // Two `i64 × i32` products (`mul_shr32_round_i64_i32`): |c| < 2^31 for any path within
        // the contract (c ≤ |r″|/(2|r′|)), and a·c/2^32 = Δu's relative curvature term,
        // far below 2^31 for a step shorter than the radius of curvature; the exact
        // `i128` form otherwise.
        let ac = mul_shr32_round_i64_i32(a, self.c_q32);
        let du = a.saturating_sub(mul_shr32_round_i64_i32(a, ac));
        if du > 0 {
            du
        } else {
            a
        }
    }
}

/// What one period of interpolation produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reference {
    /// The ordinary point: the motion command for this period (position, tangent, u).
    pub point: OrdinaryPoint,
    /// Extra points placed between the previous ordinary point and this one.
    pub extra_points: u16,
    /// Did the path advance this period (a new point was pushed into the window)?
    pub advanced: bool,
    /// Has the path reached its end (`u = u_end`)?
    pub finished: bool,
}

impl Reference {
    /// The command position in the axes' format (`PosUm`, rounded to 3.9 nm).
    pub fn pos_um(&self) -> Xy<PosUm> {
        self.point.pos.map(|v| {
            PosUm::from_bits(hydra_core::fixed_point::clamp_to_i32(
                hydra_core::fixed_point::shr_round_i64(v.to_bits(), 4),
                i32::MAX,
            ))
        })
    }
}

/// The interpolator's state: where on the path it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interpolator {
    u: i64,
    cur: PathPoint,
    /// û, |r′|, 1/|r′| at `cur` (computed once when the point is reached: the next
    /// period's Taylor step reuses it); `None` where r′ = 0.
    frame: Option<DerivFrame>,
    tangent: Xy<i32>,
    finished: bool,
}

impl Interpolator {
    /// Starts at `u_start`: clears the window and pushes the first ordinary point S_0.
    pub fn start<P: ParametricPath, const N: usize, const H: usize>(
        path: &P,
        window: &mut ContourWindow<N, H>,
    ) -> Self {
        let u = path.u_start();
        let cur = path.eval(u);
        let frame = deriv_frame(&cur);
        let tangent = frame.map_or(Xy::new(0, 0), |f| Xy::new(f.ux, f.uy));
        let s = Self {
            u: u.to_bits(),
            cur,
            frame,
            tangent,
            finished: u >= path.u_end(),
        };
        window.clear();
        window.push_with(s.ordinary(), |_| 0);
        s
    }

    fn ordinary(&self) -> OrdinaryPoint {
        OrdinaryPoint {
            pos: self.cur.pos,
            tangent: self.tangent.map(UnitQ30::from_bits),
            u: Param::from_bits(self.u),
        }
    }

    fn hold(&self) -> Reference {
        Reference {
            point: self.ordinary(),
            extra_points: 0,
            advanced: false,
            finished: self.finished,
        }
    }

    /// Current parameter.
    pub fn u(&self) -> Param {
        Param::from_bits(self.u)
    }

    /// Has the path reached its end?
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// One servo period at feed `feed` (µm/s): advances u by the Taylor step, pushes the
    /// new ordinary point and its segment's extra points into `window` (which must be
    /// the window given to [`Interpolator::start`]), and returns the motion command.
    pub fn step<P: ParametricPath, const N: usize, const H: usize>(
        &mut self,
        coeffs: &InterpCoeffs,
        path: &P,
        feed: VelUmPerS,
        window: &mut ContourWindow<N, H>,
    ) -> Reference {
        if self.finished {
            return self.hold();
        }
        let ds = coeffs.step_q32(feed);
        let Some(frame) = self.frame else {
            // r′ = 0 violates the path contract: stop rather than guess a direction.
            self.finished = true;
            return self.hold();
        };
        let taylor = Taylor::at(&self.cur, &frame);
        let u_end = path.u_end().to_bits();
        // First-order step a = ΔS/|r′| (units of u).
        let a = taylor.first(ds);
        let u1 = self.u.saturating_add(taylor.du(a)).min(u_end);
        if ds <= 0 || u1 <= self.u {
            return self.hold();
        }
        let kappa = curvature_q32_per_um(&self.cur, &frame);
        let h = coeffs.extra_count(kappa, feed, H);
        // First-order step of one sub-interval, a_e = (ΔS/(h + 1))/|r′| (the division
        // only when there are extra points to place: a ≥ 0 and h + 1 ≤ 4097, so it is
        // `div_small`'s four 32-bit divisions, not a 64-bit one).
        let a_e = if h == 0 {
            0
        } else {
            let n = h.wrapping_add(1);
            match u32::try_from(n).ok().and_then(|n| div_small(a, n)) {
                Some(q) => q,
                None => a.checked_div(n as i64).unwrap_or(0),
            }
        };
        let next = path.eval(Param::from_bits(u1));
        let (u0, start_pos) = (self.u, self.cur.pos.map(PosFine::to_bits));
        self.u = u1;
        self.cur = next;
        self.frame = deriv_frame(&next);
        if let Some(f) = self.frame {
            self.tangent = Xy::new(f.ux, f.uy);
        }
        self.finished = u1 >= u_end;
        let point = self.ordinary();
        // Both ends of the relative vectors saturated to ±2^40 (as in the window): the
        // differences are exact `i64`s, clamped to ±2^30 as `rel_sat` would.
        let start_pos = clamp_pos(start_pos);
        let n = window.push_with(point, |buf| {
            let mut n = 0usize;
            let mut a = 0i64;
            for slot in buf.iter_mut().take(h) {
                // Extra point k at arc length k·ΔS/(h + 1) on the same expansion
                // (k·a_e ≤ a ≤ 2^52: no wrap).
                a = a.wrapping_add(a_e);
                let ue = u0.saturating_add(taylor.du(a));
                if ue >= u1 {
                    break;
                }
                let pos = path.position(Param::from_bits(ue));
                *slot = rel(clamp_pos(pos.map(PosFine::to_bits)), start_pos).0;
                n = n.wrapping_add(1);
            }
            n
        });
        Reference {
            point,
            extra_points: n.min(usize::from(u16::MAX)) as u16,
            advanced: true,
            finished: self.finished,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::arc::ArcSpec;
    use super::super::parabola::ParabolaSpec;
    use super::super::path::LineSpec;
    use super::*;

    fn coeffs(q: f32) -> InterpCoeffs {
        InterpConfig {
            period_us: 1000,
            q_s: q,
            h_max: 63,
        }
        .build()
        .unwrap()
    }

    #[test]
    fn config_validation() {
        let c = InterpConfig::default();
        assert!(c.build().is_ok());
        let bad = |f: &dyn Fn(&mut InterpConfig)| {
            let mut s = c;
            f(&mut s);
            s.build().unwrap_err()
        };
        assert_eq!(bad(&|s| s.period_us = 5), InterpConfigError::Period);
        assert_eq!(bad(&|s| s.q_s = -1.0), InterpConfigError::Q);
        assert_eq!(bad(&|s| s.q_s = f32::NAN), InterpConfigError::Q);
        assert_eq!(bad(&|s| s.h_max = 5000), InterpConfigError::HMax);
        // 200 mm/s · 1 ms = 200 µm.
        let ds = c.build().unwrap().step_q32(VelUmPerS::from_num(200_000));
        assert!((ds as f64 / 4_294_967_296.0 - 200.0).abs() < 1e-6);
        // The split products equal the exact i128 forms over the whole feed range.
        for (period_us, q_s) in [(10, 0.0), (1000, 1.0), (250, 0.25), (1_000_000, 1000.0)] {
            let k = InterpConfig {
                period_us,
                q_s,
                h_max: 63,
            }
            .build()
            .unwrap();
            for v in [0, 1, 255, 256_000, 51_200_000, 1 << 30, i32::MAX, -5] {
                let f = VelUmPerS::from_bits(v);
                let vb = i128::from(v.max(0));
                let exact = ((vb * i128::from(k.ts_q40) + (1 << 15)) >> 16) as i64;
                assert_eq!(k.step_q32(f), exact.min(MAX_STEP_Q32), "{period_us} {v}");
                let qv = ((vb * i128::from(k.q_q16) + (1 << 15)) >> 16) as i64;
                assert_eq!(k.qv_q8(f), qv, "{q_s} {v}");
            }
        }
    }

    #[test]
    fn arc_length_steps_and_extra_counts() {
        // Circle R = 10 mm at 200 mm/s, Q = 1 s: κ·Q·v = 20 extra points, steps of
        // exactly 200 µm of arc (arc-length parameter: the Taylor step is exact).
        let arc = ArcSpec {
            center_um: [0.0, 10_000.0],
            radius_um: 10_000.0,
            start_deg: -90.0,
            sweep_deg: 90.0,
        }
        .build()
        .unwrap();
        let mut w: ContourWindow<8, 63> = ContourWindow::new();
        let mut it = Interpolator::start(&arc, &mut w);
        let c = coeffs(1.0);
        let feed = VelUmPerS::from_num(200_000);
        let r = it.step(&c, &arc, feed, &mut w);
        assert!(r.advanced && !r.finished);
        assert!((r.point.u.to_num::<f64>() - 200.0).abs() < 1e-6);
        // κ = 1e-4/µm exactly in theory; the fixed-point κ may round just below 20.
        assert!((19..=20).contains(&r.extra_points), "{}", r.extra_points);
        let n = usize::from(r.extra_points);
        let last = w.extra(1, n - 1).unwrap();
        let last = last.x.to_num::<f64>().hypot(last.y.to_num::<f64>());
        let spacing = 200.0 / (n as f64 + 1.0);
        assert!((last - spacing * n as f64).abs() < 0.05, "{last}");
        // Runs to the end and stops there.
        let mut steps = 1;
        loop {
            steps += 1;
            if it.step(&c, &arc, feed, &mut w).finished {
                break;
            }
            assert!(steps < 100);
        }
        assert_eq!(steps, 79); // ⌈15708/200⌉ = 79 periods.
        assert!(!it.step(&c, &arc, feed, &mut w).advanced);
    }

    #[test]
    fn parabola_taylor_step_keeps_the_feed() {
        let par = ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 10_000.0,
            axis_deg: 0.0,
            x_start_um: -20_000.0,
            x_end_um: 20_000.0,
        }
        .build()
        .unwrap();
        let mut w: ContourWindow<4, 63> = ContourWindow::new();
        let mut it = Interpolator::start(&par, &mut w);
        let c = coeffs(1.0);
        let feed = VelUmPerS::from_num(500_000);
        let mut prev = w.newest().unwrap().pos;
        for _ in 0..150 {
            let r = it.step(&c, &par, feed, &mut w);
            if r.finished {
                break;
            }
            let p = r.point.pos;
            let chord = (p.x - prev.x)
                .to_num::<f64>()
                .hypot((p.y - prev.y).to_num::<f64>());
            // The chord of a 500 µm arc is shorter by at most ΔS³κ²/24 = 0.05 µm; the
            // Taylor step's own error is O(ΔS³) as well.
            assert!((chord - 500.0).abs() < 0.2, "chord {chord}");
            prev = p;
        }
    }

    #[test]
    fn zero_feed_holds_and_line_has_no_extras() {
        let line = LineSpec {
            start_um: [0.0, 0.0],
            end_um: [1000.0, 0.0],
        }
        .build()
        .unwrap();
        let mut w: ContourWindow<4, 8> = ContourWindow::new();
        let mut it = Interpolator::start(&line, &mut w);
        let c = coeffs(1.0);
        let r = it.step(&c, &line, VelUmPerS::ZERO, &mut w);
        assert!(!r.advanced);
        assert_eq!(w.len(), 1);
        let r = it.step(&c, &line, VelUmPerS::from_num(-5), &mut w);
        assert!(!r.advanced);
        let r = it.step(&c, &line, VelUmPerS::from_num(300_000), &mut w);
        assert!(r.advanced);
        assert_eq!(r.extra_points, 0);
        assert_eq!(r.pos_um().x, PosUm::from_num(300));
    }
}
