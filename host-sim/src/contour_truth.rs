//! Ground truth for contour-error estimation (SPEC §C): the exact signed distance from
//! a point to a path, in `f64`.
//!
//! Method: sample |P − r(u)|² at 4096 evenly spaced parameters, keep every local minimum
//! of the samples (and both ends of the path), refine each inside its bracket
//! [u_{i−1}, u_{i+1}] by safeguarded Newton iteration on
//!
//! ```text
//! g(u) = (r(u) − P)·r′(u) = 0,      g′(u) = |r′|² + (r(u) − P)·r″(u)
//! ```
//!
//! (bisection on the sign of g whenever a Newton step leaves the bracket), and take the
//! nearest. The foot point F = r(u*), the distance |P − F|, and the sign the estimator
//! uses: ε = |P − F|·sgn((P − F)·n_R), n_R the right-hand normal (t_y, −t_x) of the path
//! at F — positive when P lies to the right of the direction of travel. Accuracy: the
//! f64 rounding of µm coordinates below 10 m, about 10⁻⁹ µm.
//!
//! The paths are built from the same specification structs as `hydra_xy::contour`,
//! with their exact (unquantised) parameters.

use hydra_xy::contour::{ArcSpec, LineSpec, ParabolaSpec};

/// A path in `f64`, with the parameterisation of its `hydra_core` counterpart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TruthPath {
    /// r = o + u·a, u ∈ [0, L] (arc length, µm).
    Line {
        /// Start point, µm.
        o: [f64; 2],
        /// Unit direction.
        a: [f64; 2],
        /// Length, µm.
        len: f64,
    },
    /// r = c + R·(cos φ, sin φ), φ = φ0 + σ·u/R, u ∈ [0, R·|sweep|] (arc length, µm).
    Arc {
        /// Centre, µm.
        c: [f64; 2],
        /// Radius, µm.
        r: f64,
        /// Start angle, rad.
        phi0: f64,
        /// +1 counter-clockwise, −1 clockwise.
        sigma: f64,
        /// Arc length, µm.
        len: f64,
    },
    /// r = v + u·a + u²/(2p)·b, u ∈ [x0, x1] µm.
    Parabola {
        /// Vertex, µm.
        v: [f64; 2],
        /// Axis direction (cos θ, sin θ).
        a: [f64; 2],
        /// p, µm.
        p: f64,
        /// Parameter range, µm.
        x0: f64,
        /// Parameter range, µm.
        x1: f64,
    },
}

/// The nearest point of a path to P.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Parameter of the foot point.
    pub u: f64,
    /// Foot point, µm.
    pub foot: [f64; 2],
    /// |P − F|, µm.
    pub dist: f64,
    /// Signed distance ε, µm (> 0: P right of the direction of travel).
    pub eps: f64,
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

const SAMPLES: usize = 4096;

impl TruthPath {
    /// The line of a [`LineSpec`].
    pub fn line(s: &LineSpec) -> Self {
        let d = sub(s.end_um, s.start_um);
        let len = d[0].hypot(d[1]);
        TruthPath::Line {
            o: s.start_um,
            a: [d[0] / len, d[1] / len],
            len,
        }
    }

    /// The arc of an [`ArcSpec`].
    pub fn arc(s: &ArcSpec) -> Self {
        TruthPath::Arc {
            c: s.center_um,
            r: s.radius_um,
            phi0: s.start_deg.to_radians(),
            sigma: s.sweep_deg.signum(),
            len: s.radius_um * s.sweep_deg.abs().to_radians(),
        }
    }

    /// The parabola of a [`ParabolaSpec`].
    pub fn parabola(s: &ParabolaSpec) -> Self {
        let th = s.axis_deg.to_radians();
        TruthPath::Parabola {
            v: s.vertex_um,
            a: [th.cos(), th.sin()],
            p: s.p_um,
            x0: s.x_start_um,
            x1: s.x_end_um,
        }
    }

    /// Parameter range [u_start, u_end].
    pub fn domain(&self) -> (f64, f64) {
        match *self {
            TruthPath::Line { len, .. } | TruthPath::Arc { len, .. } => (0.0, len),
            TruthPath::Parabola { x0, x1, .. } => (x0, x1),
        }
    }

    /// (r, r′, r″) at u.
    pub fn eval(&self, u: f64) -> [[f64; 2]; 3] {
        match *self {
            TruthPath::Line { o, a, .. } => [[o[0] + u * a[0], o[1] + u * a[1]], a, [0.0, 0.0]],
            TruthPath::Arc {
                c, r, phi0, sigma, ..
            } => {
                let (s, co) = (phi0 + sigma * u / r).sin_cos();
                [
                    [c[0] + r * co, c[1] + r * s],
                    [-sigma * s, sigma * co],
                    [-co / r, -s / r],
                ]
            }
            TruthPath::Parabola { v, a, p, .. } => {
                let b = [-a[1], a[0]];
                let (xl, yl) = (u, u * u / (2.0 * p));
                let (d1y, d2y) = (u / p, 1.0 / p);
                [
                    [v[0] + xl * a[0] + yl * b[0], v[1] + xl * a[1] + yl * b[1]],
                    [a[0] + d1y * b[0], a[1] + d1y * b[1]],
                    [d2y * b[0], d2y * b[1]],
                ]
            }
        }
    }

    /// Position at u, µm.
    pub fn r(&self, u: f64) -> [f64; 2] {
        self.eval(u)[0]
    }

    /// Unit tangent (direction of travel) at u.
    pub fn tangent(&self, u: f64) -> [f64; 2] {
        let d = self.eval(u)[1];
        let l = d[0].hypot(d[1]);
        [d[0] / l, d[1] / l]
    }

    /// Left-hand unit normal (tangent turned +90°) at u.
    pub fn left_normal(&self, u: f64) -> [f64; 2] {
        let t = self.tangent(u);
        [-t[1], t[0]]
    }

    /// Unsigned curvature at u, 1/µm.
    pub fn curvature(&self, u: f64) -> f64 {
        let [_, d1, d2] = self.eval(u);
        (d1[0] * d2[1] - d1[1] * d2[0]).abs() / d1[0].hypot(d1[1]).powi(3)
    }

    /// Largest curvature over the domain, 1/µm.
    pub fn max_curvature(&self) -> f64 {
        match *self {
            TruthPath::Line { .. } => 0.0,
            TruthPath::Arc { r, .. } => 1.0 / r,
            TruthPath::Parabola { p, x0, x1, .. } => {
                let xm = if x0 <= 0.0 && x1 >= 0.0 {
                    0.0
                } else {
                    x0.abs().min(x1.abs())
                };
                1.0 / p.abs() / (1.0 + (xm / p).powi(2)).powf(1.5)
            }
        }
    }

    /// Arc length from the start of the domain to u, µm (closed forms).
    pub fn arc_length(&self, u: f64) -> f64 {
        match *self {
            TruthPath::Line { .. } | TruthPath::Arc { .. } => u,
            TruthPath::Parabola { p, x0, .. } => {
                let pa = p.abs();
                let s = |x: f64| {
                    0.5 * x * (1.0 + (x / pa).powi(2)).sqrt() + 0.5 * pa * (x / pa).asinh()
                };
                s(u) - s(x0)
            }
        }
    }

    /// The parameter of the point `lag_um` of arc length behind u (clamped to the start).
    pub fn u_behind(&self, u: f64, lag_um: f64) -> f64 {
        let (u0, _) = self.domain();
        let target = self.arc_length(u) - lag_um;
        if target <= 0.0 {
            return u0;
        }
        let mut x = u;
        for _ in 0..60 {
            let d1 = self.eval(x)[1];
            let step = (self.arc_length(x) - target) / d1[0].hypot(d1[1]);
            x = (x - step).clamp(u0, u);
            if step.abs() < 1e-12 * (1.0 + x.abs()) {
                break;
            }
        }
        x
    }

    /// g(u) = (r − P)·r′ and g′(u).
    fn g(&self, p: [f64; 2], u: f64) -> (f64, f64) {
        let [r, d1, d2] = self.eval(u);
        let e = sub(r, p);
        (dot(e, d1), dot(d1, d1) + dot(e, d2))
    }

    /// Minimises |P − r(u)|² on [lo, hi] (safeguarded Newton on g).
    fn refine(&self, p: [f64; 2], lo: f64, hi: f64, start: f64) -> f64 {
        let (mut lo, mut hi) = (lo, hi);
        let (glo, _) = self.g(p, lo);
        let (ghi, _) = self.g(p, hi);
        if glo > 0.0 {
            // Increasing distance from lo on: the minimum is at lo (or a bracket end).
            return lo;
        }
        if ghi < 0.0 {
            return hi;
        }
        let mut u = start.clamp(lo, hi);
        for _ in 0..200 {
            let (g, dg) = self.g(p, u);
            if g == 0.0 {
                return u;
            }
            if g < 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            let newton = if dg > 0.0 { u - g / dg } else { f64::NAN };
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - u).abs() <= 1e-13 * (1.0 + u.abs()) || hi - lo <= 1e-13 * (1.0 + u.abs()) {
                return next;
            }
            u = next;
        }
        u
    }

    /// The exact nearest point of the path to `p` (µm) and its signed distance.
    ///
    /// An arc in closed form: the foot is on the ray from the centre through `p`,
    /// u = R·((σ·(atan2(p − c) − φ0)) mod 2π), or the nearer end when that angle is
    /// beyond the sweep. Every other path: a dense sampling of the whole path and a
    /// refinement of each local minimum ([`Self::nearest_sampled`]).
    pub fn nearest(&self, p: [f64; 2]) -> Nearest {
        match *self {
            TruthPath::Arc {
                c,
                r,
                phi0,
                sigma,
                len,
            } => {
                let q = sub(p, c);
                let turn = std::f64::consts::TAU;
                let u = (sigma * (q[1].atan2(q[0]) - phi0)).rem_euclid(turn) * r;
                let u = if u <= len {
                    u
                } else {
                    // Beyond the sweep: the nearer end.
                    let d = |u: f64| {
                        let e = sub(self.r(u), p);
                        dot(e, e)
                    };
                    if d(0.0) <= d(len) {
                        0.0
                    } else {
                        len
                    }
                };
                self.nearest_at(p, u)
            }
            _ => self.nearest_sampled(p),
        }
    }

    /// The foot at parameter `u` and the signed distance of `p` from it.
    fn nearest_at(&self, p: [f64; 2], u: f64) -> Nearest {
        let foot = self.r(u);
        let e = sub(p, foot);
        let dist = e[0].hypot(e[1]);
        let t = self.tangent(u);
        let side = dot(e, [t[1], -t[0]]);
        Nearest {
            u,
            foot,
            dist,
            eps: if side < 0.0 { -dist } else { dist },
        }
    }

    /// [`Self::nearest`] by search: the squared distance at 4 097 samples of the domain,
    /// each local minimum refined, the ends considered.
    pub fn nearest_sampled(&self, p: [f64; 2]) -> Nearest {
        let (u0, u1) = self.domain();
        let h = (u1 - u0) / SAMPLES as f64;
        let ui = |i: usize| if i == SAMPLES { u1 } else { u0 + h * i as f64 };
        let d2: Vec<f64> = (0..=SAMPLES)
            .map(|i| {
                let e = sub(self.r(ui(i)), p);
                dot(e, e)
            })
            .collect();
        let mut best: Option<(f64, f64)> = None;
        let mut consider = |u: f64| {
            let e = sub(self.r(u), p);
            let d = dot(e, e);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, u));
            }
        };
        consider(u0);
        consider(u1);
        for i in 0..=SAMPLES {
            let left = if i == 0 { f64::INFINITY } else { d2[i - 1] };
            let right = if i == SAMPLES {
                f64::INFINITY
            } else {
                d2[i + 1]
            };
            if d2[i] <= left && d2[i] <= right {
                let lo = ui(i.saturating_sub(1));
                let hi = ui((i + 1).min(SAMPLES));
                consider(self.refine(p, lo, hi, ui(i)));
            }
        }
        let u = best.map_or(u0, |b| b.1);
        self.nearest_at(p, u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arc's closed form is the search's answer: inside, outside, beyond either end
    /// of a part arc, both directions, a full circle.
    #[test]
    fn the_arcs_closed_form_agrees_with_the_search() {
        for (start, sweep) in [(-90.0, 360.0), (30.0, 120.0), (200.0, -75.0)] {
            let a = TruthPath::arc(&ArcSpec {
                center_um: [1_000.0, -2_000.0],
                radius_um: 50_000.0,
                start_deg: start,
                sweep_deg: sweep,
            });
            for k in 0..200 {
                let th = f64::from(k) * 0.0317 * std::f64::consts::TAU;
                let rad = 50_000.0 + 30_000.0 * (f64::from(k) * 0.71).sin();
                let p = [1_000.0 + rad * th.cos(), -2_000.0 + rad * th.sin()];
                let (f, s) = (a.nearest(p), a.nearest_sampled(p));
                assert!(
                    (f.dist - s.dist).abs() < 1e-6 && (f.eps - s.eps).abs() < 1e-6,
                    "arc {start}/{sweep}, point {p:?}: closed {f:?} search {s:?}"
                );
            }
        }
    }

    #[test]
    fn circle_distance_is_radial() {
        let c = TruthPath::arc(&ArcSpec {
            center_um: [0.0, 10_000.0],
            radius_um: 10_000.0,
            start_deg: -90.0,
            sweep_deg: 360.0,
        });
        // Inside a counter-clockwise circle is on the left: negative.
        let n = c.nearest([3000.0, 10_000.0]);
        assert!((n.eps + 7000.0).abs() < 1e-9, "{n:?}");
        let n = c.nearest([0.0, -50.0]);
        assert!((n.eps - 50.0).abs() < 1e-9, "{n:?}");
        assert!(n.u.abs() < 1e-6 || (n.u - c.domain().1).abs() < 1e-6);
    }

    #[test]
    fn parabola_nearest_is_perpendicular_and_arc_length_inverts() {
        let par = TruthPath::parabola(&ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 10_000.0,
            axis_deg: 0.0,
            x_start_um: -20_000.0,
            x_end_um: 20_000.0,
        });
        for &x in &[-15_000.0, -300.0, 0.0, 4321.0, 19_000.0] {
            let n_l = par.left_normal(x);
            let r = par.r(x);
            for e in [-50.0, 50.0] {
                let p = [r[0] + e * n_l[0], r[1] + e * n_l[1]];
                let n = par.nearest(p);
                assert!((n.u - x).abs() < 1e-6, "x={x} e={e} {n:?}");
                assert!((n.eps + e).abs() < 1e-9, "x={x} e={e} {n:?}");
            }
            let s = par.arc_length(x);
            let back = par.u_behind(x, 1234.5);
            assert!((s - par.arc_length(back) - 1234.5).abs() < 1e-8);
        }
        // Whole parabola: 2·[10·√5 + 5·asinh 2] mm = 59.15771 mm.
        let l = par.arc_length(20_000.0);
        assert!((l - 59_157.714).abs() < 0.001, "{l}");
    }
}
