//! A straight line in N axes, jerk-limited along the path (SPEC §B, "two or more axes").
//!
//! The limits V, A, J apply to the path (the Euclidean motion of the point). The
//! leader is the axis with the largest |Δ| (the first one on a tie); its displacement
//! `s(t)` follows a [`Profile`] planned for D = |Δ_leader| with the path limits scaled
//! by ρ = D / L (L the path length), which is the same time-optimal motion. Every axis
//! follows the leader with its fixed ratio γ_i = Δ_i / Δ_leader:
//!
//! ```text
//! x_i(k) = from_i + round(g_i · s(k)),   g_i = Δ_i / D  (= γ_i·sign(Δ_leader))
//! ```
//!
//! `g_i` is stored in Q1.62 (`i64`, rounded to nearest: error ≤ 2^-63), the product is
//! formed with [`crate::fixed_point::mulhi`] in Q.22 LSB and rounded once. So for every tick:
//!
//! * the leader is exactly `from_L ± s(k)` (g_L = ±2^62 exactly);
//! * every other axis is within ½ LSB + 2^-21 LSB of the line through the leader's
//!   point: |x_i − from_i − γ_i·(x_L − from_L)| ≤ ½ LSB, so the point's distance from
//!   the line is ≤ ½·√(N − 1) LSB (≤ 1 LSB for N ≤ 5);
//! * all axes leave at k = 0 and arrive at `end_tick` together, at their targets
//!   exactly (g_i·D rounds to Δ_i).
//!
//! Positions are `PosUm` (I24F8 µm): the line's ends are representable by type, so
//! |Δ_i| < 2^32 LSB < [`super::MAX_DISTANCE_LSB`].

use super::cursor::Cursor;
use super::plan::{Limits, Plan};
use super::profile::Profile;
use super::ScurveError;
use crate::fixed_point::mulhi;
use crate::fixed_point::sat_i32;
use crate::units::PosUm;

/// LSB of `PosUm` per µm (I24F8).
const LSB_PER_UM: f64 = 256.0;

/// Limits of the path (the Euclidean motion of the point), µm per second^n.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PathLimits {
    /// Path velocity limit V, µm/s (> 0).
    pub vel_um_per_s: f64,
    /// Path acceleration limit A, µm/s² (> 0).
    pub acc_um_per_s2: f64,
    /// Path jerk limit J, µm/s³ (> 0).
    pub jerk_um_per_s3: f64,
}

/// A planned straight-line move of N axes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LineMove<const N: usize> {
    profile: Profile,
    from: [PosUm; N],
    to: [PosUm; N],
    /// g_i = Δ_i / D, Q1.62.
    gain_q62: [i64; N],
    leader: usize,
    /// Path length L, µm.
    path_um: f64,
}

impl<const N: usize> LineMove<N> {
    /// Plans the line `from → to` under path `limits` for a period of `period_s`.
    ///
    /// Errors: a bad limit or period ([`ScurveError`] names it), a move lasting 2^32 − 2
    /// periods or more. `from == to` is the valid empty move (all samples = `from`).
    pub fn plan(
        from: [PosUm; N],
        to: [PosUm; N],
        limits: &PathLimits,
        period_s: f64,
    ) -> Result<Self, ScurveError> {
        let mut delta = [0i64; N];
        for ((d, f), t) in delta.iter_mut().zip(&from).zip(&to) {
            *d = i64::from(t.to_bits()).wrapping_sub(i64::from(f.to_bits()));
        }
        // Leader: the first axis with the largest |Δ|.
        let mut leader = 0usize;
        let mut dist = 0u64;
        for (i, d) in delta.iter().enumerate() {
            if d.unsigned_abs() > dist {
                dist = d.unsigned_abs();
                leader = i;
            }
        }
        let len_lsb = libm::sqrt(delta.iter().map(|&d| (d as f64) * (d as f64)).sum::<f64>());
        // ρ = D / L ∈ [1/√N, 1]; 1 for the empty move (limits still validated).
        let rho = if dist == 0 {
            1.0
        } else {
            dist as f64 / len_lsb
        };
        let lim = Limits {
            vel_lsb_per_s: limits.vel_um_per_s * LSB_PER_UM * rho,
            acc_lsb_per_s2: limits.acc_um_per_s2 * LSB_PER_UM * rho,
            jerk_lsb_per_s3: limits.jerk_um_per_s3 * LSB_PER_UM * rho,
        };
        let profile = Profile::new(&Plan::new(dist, &lim)?, period_s)?;
        let mut gain_q62 = [0i64; N];
        if dist > 0 {
            let den = i128::from(dist);
            for (g, &d) in gain_q62.iter_mut().zip(&delta) {
                // |Δ_i| ≤ D: |Δ_i·2^62| < 2^95, the quotient ≤ 2^62. Round to nearest.
                let num = i128::from(d).wrapping_shl(62);
                let half = den.wrapping_shr(1);
                let half = if d < 0 { half.wrapping_neg() } else { half };
                let q = num.wrapping_add(half).checked_div(den).unwrap_or(0);
                *g = i64::try_from(q).map_err(|_| ScurveError::DistanceTooLong)?;
            }
        }
        Ok(LineMove {
            profile,
            from,
            to,
            gain_q62,
            leader,
            path_um: len_lsb / LSB_PER_UM,
        })
    }

    /// The leader's profile (displacement along the leader axis, LSB = 1/256 µm).
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// Index of the leader axis.
    pub fn leader(&self) -> usize {
        self.leader
    }

    /// Start point.
    pub fn from(&self) -> &[PosUm; N] {
        &self.from
    }

    /// End point.
    pub fn to(&self) -> &[PosUm; N] {
        &self.to
    }

    /// Path length L, µm.
    pub fn path_length_um(&self) -> f64 {
        self.path_um
    }

    /// γ_i = Δ_i / Δ_leader of axis `i` (reporting; 0 for the empty move or a bad index).
    pub fn ratio(&self, i: usize) -> f64 {
        let g = self.gain_q62.get(i).copied().unwrap_or(0) as f64 / 4.611_686_018_427_388e18;
        let s = self
            .gain_q62
            .get(self.leader)
            .map_or(1.0, |&gl| if gl < 0 { -1.0 } else { 1.0 });
        g * s
    }

    /// Path position (µm) of a leader displacement `s_lsb` (reporting): L·s/D, exactly L
    /// at the end.
    pub fn path_um(&self, s_lsb: i64) -> f64 {
        let d = self.profile.distance_lsb();
        if d == 0 {
            0.0
        } else {
            self.path_um * (s_lsb as f64 / d as f64)
        }
    }

    /// Path quantity per leader quantity, L/D (≥ 1; 1 for the empty move).
    pub fn path_per_leader(&self) -> f64 {
        let d = self.profile.distance_lsb();
        if d == 0 {
            1.0
        } else {
            self.path_um * LSB_PER_UM / d as f64
        }
    }

    /// Axis positions for a leader displacement `s_lsb ∈ [0, D]` (hot path: one
    /// `mulhi` per axis).
    #[inline]
    pub fn axes_at(&self, s_lsb: i64) -> [PosUm; N] {
        // s ≤ D < 2^33: s·2^24 < 2^57 fits a u64.
        let su = (s_lsb.max(0) as u64).wrapping_shl(24);
        let mut out = [PosUm::ZERO; N];
        for ((o, f), &g) in out.iter_mut().zip(&self.from).zip(&self.gain_q62) {
            // g·s·2^24 / 2^64 = (g / 2^62)·s in Q.22 LSB; round to nearest once.
            let off = mulhi(g, su).wrapping_add(1 << 21).wrapping_shr(22);
            *o = PosUm::from_bits(sat_i32(i64::from(f.to_bits()).wrapping_add(off)));
        }
        out
    }

    /// Axis positions at tick `k` (pure; see [`Profile::position_at`]).
    #[inline]
    pub fn axes_at_tick(&self, k: u32) -> [PosUm; N] {
        self.axes_at(self.profile.position_at(k))
    }

    /// Axis positions of the cursor's tick, then advances it (monotone stream).
    #[inline]
    pub fn next(&self, cursor: &mut Cursor) -> [PosUm; N] {
        self.axes_at(cursor.next(&self.profile))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn um(x: f64) -> PosUm {
        PosUm::from_num(x)
    }

    const LIM: PathLimits = PathLimits {
        vel_um_per_s: 100_000.0,
        acc_um_per_s2: 500_000.0,
        jerk_um_per_s3: 5_000_000.0,
    };

    #[test]
    fn three_axes_straight_and_together() {
        let from = [um(-1000.0), um(250.5), um(7.0)];
        let to = [um(40_000.0), um(-12_345.678), um(7.0)];
        let mv = LineMove::plan(from, to, &LIM, 0.001).unwrap();
        assert_eq!(mv.leader(), 0);
        let d: std::vec::Vec<f64> = (0..3)
            .map(|i| f64::from(to[i].to_bits()) - f64::from(from[i].to_bits()))
            .collect();
        let mut c = Cursor::new();
        let mut k = 0;
        while !c.done(mv.profile()) {
            let x = mv.next(&mut c);
            let sl = f64::from(x[0].to_bits() - from[0].to_bits());
            for i in 1..3 {
                let xi = f64::from(x[i].to_bits() - from[i].to_bits());
                assert!(
                    (xi - d[i] / d[0] * sl).abs() <= 0.5 + 1e-6,
                    "k {k} axis {i}"
                );
            }
            k += 1;
        }
        assert_eq!(k, mv.profile().end_tick() + 1);
        assert_eq!(mv.axes_at_tick(mv.profile().end_tick()), to);
        assert_eq!(mv.axes_at_tick(0), from);
        assert!((mv.ratio(1) - d[1] / d[0]).abs() < 1e-15);
        // Path limits are scaled to the leader: path peak velocity is V.
        let vp_path = mv.profile().plan().peak_vel * mv.path_per_leader() / 256.0;
        assert!((vp_path - LIM.vel_um_per_s).abs() < 1e-6);
    }

    #[test]
    fn empty_move_is_valid() {
        let p = [um(1.0), um(2.0)];
        let mv = LineMove::plan(p, p, &LIM, 0.001).unwrap();
        assert_eq!(mv.profile().end_tick(), 0);
        assert_eq!(mv.axes_at_tick(0), p);
        assert_eq!(mv.axes_at_tick(5), p);
        let bad = PathLimits {
            vel_um_per_s: 0.0,
            ..LIM
        };
        assert_eq!(
            LineMove::plan(p, p, &bad, 0.001),
            Err(ScurveError::Velocity)
        );
    }

    #[test]
    fn full_range_move_is_exact() {
        let from = [PosUm::MIN, PosUm::MAX];
        let to = [PosUm::MAX, PosUm::MIN];
        let fast = PathLimits {
            vel_um_per_s: 2e6,
            acc_um_per_s2: 2e7,
            jerk_um_per_s3: 2e8,
        };
        let mv = LineMove::plan(from, to, &fast, 0.001).unwrap();
        assert_eq!(mv.axes_at_tick(mv.profile().end_tick()), to);
        assert_eq!(mv.axes_at_tick(0), from);
    }
}
