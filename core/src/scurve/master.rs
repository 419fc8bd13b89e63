//! A planned S-curve move as the master variable of the follower (SPEC §A, time master).
//!
//! SPEC §A lets the master be time itself; a smooth time-based master is better than a
//! raw clock: a cam table is then run against a jerk-limited virtual master that starts
//! and stops at rest, with no master encoder. [`MasterMove`] plans θ(t) from one master
//! position to another (limits in master counts/s, /s², /s³) and [`ScurveMaster`] yields
//! one [`Master`] (I48F16 counts) per control period.
//!
//! Format: the profile's LSB is `Master`'s raw unit (2^-16 count), so one move spans at
//! most [`super::MAX_DISTANCE_LSB`] = 2^40 LSB = 2^24 counts (16.7 M counts, e.g.
//! 46 turns of a table counted in mdeg). The master value is `from ± s(k)` exactly,
//! with s(k) within 0.5 + 2^-8 LSB (7.7e-6 count) of the exact profile, non-decreasing
//! in the direction of motion, and exactly `to` from the last tick on.

use super::cursor::Cursor;
use super::plan::{Limits, Plan};
use super::profile::Profile;
use super::ScurveError;
use crate::units::Master;

/// LSB of `Master` per count (I48F16).
const LSB_PER_COUNT: f64 = 65536.0;

/// Limits of a master move, master counts per second^n.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterLimits {
    /// Velocity limit, counts/s (> 0).
    pub vel_counts_per_s: f64,
    /// Acceleration limit, counts/s² (> 0).
    pub acc_counts_per_s2: f64,
    /// Jerk limit, counts/s³ (> 0).
    pub jerk_counts_per_s3: f64,
}

/// A planned master move `from → to`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterMove {
    profile: Profile,
    from: Master,
    negative: bool,
}

impl MasterMove {
    /// Plans the master move. Errors: a bad limit or period, a distance above 2^24
    /// counts ([`ScurveError::DistanceTooLong`]), too many periods.
    pub fn plan(
        from: Master,
        to: Master,
        limits: &MasterLimits,
        period_s: f64,
    ) -> Result<Self, ScurveError> {
        let delta = i128::from(to.to_bits()).wrapping_sub(i128::from(from.to_bits()));
        let dist = u64::try_from(delta.unsigned_abs()).map_err(|_| ScurveError::DistanceTooLong)?;
        let lim = Limits {
            vel_lsb_per_s: limits.vel_counts_per_s * LSB_PER_COUNT,
            acc_lsb_per_s2: limits.acc_counts_per_s2 * LSB_PER_COUNT,
            jerk_lsb_per_s3: limits.jerk_counts_per_s3 * LSB_PER_COUNT,
        };
        let profile = Profile::new(&Plan::new(dist, &lim)?, period_s)?;
        Ok(MasterMove {
            profile,
            from,
            negative: delta < 0,
        })
    }

    /// The profile (LSB = 2^-16 count).
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The master for a displacement `s_lsb ∈ [0, D]` along the move.
    #[inline]
    pub fn master_of(&self, s_lsb: i64) -> Master {
        let step = Master::from_bits(s_lsb);
        if self.negative {
            self.from.saturating_sub(step)
        } else {
            self.from.saturating_add(step)
        }
    }

    /// The master at tick `k` (pure).
    #[inline]
    pub fn master_at(&self, k: u32) -> Master {
        self.master_of(self.profile.position_at(k))
    }
}

/// A time-based master driven by a planned move: call [`ScurveMaster::tick`] once per
/// control period.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScurveMaster {
    mv: MasterMove,
    cursor: Cursor,
}

impl ScurveMaster {
    /// A master at the start of `mv`.
    pub fn new(mv: MasterMove) -> Self {
        ScurveMaster {
            mv,
            cursor: Cursor::new(),
        }
    }

    /// The master of this period (then advances one period); after the move it holds
    /// the target.
    #[inline]
    pub fn tick(&mut self) -> Master {
        self.mv.master_of(self.cursor.next(&self.mv.profile))
    }

    /// `true` once the target has been produced.
    pub fn done(&self) -> bool {
        self.cursor.done(&self.mv.profile)
    }

    /// The planned move.
    pub fn planned(&self) -> &MasterMove {
        &self.mv
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn master_runs_down_smoothly_to_target() {
        let from = Master::from_num(360_000); // mdeg
        let to = Master::from_num(90_000.5);
        let lim = MasterLimits {
            vel_counts_per_s: 30_000.0,
            acc_counts_per_s2: 60_000.0,
            jerk_counts_per_s3: 400_000.0,
        };
        let mv = MasterMove::plan(from, to, &lim, 0.001).unwrap();
        let mut m = ScurveMaster::new(mv);
        let mut prev = m.tick();
        assert_eq!(prev, from);
        let mut n = 1u32;
        while !m.done() {
            let x = m.tick();
            assert!(x <= prev);
            // Never faster than 30 counts per 1 ms period (+ one LSB).
            assert!((prev - x).to_num::<f64>() <= 30.0 + 2.0 / 65536.0);
            prev = x;
            n += 1;
        }
        assert_eq!(prev, to);
        assert_eq!(m.tick(), to);
        assert_eq!(n, mv.profile().end_tick() + 1);
    }

    #[test]
    fn too_long_and_bad_limits() {
        let lim = MasterLimits {
            vel_counts_per_s: 1.0,
            acc_counts_per_s2: 1.0,
            jerk_counts_per_s3: 1.0,
        };
        let far = Master::from_num(1i64 << 25);
        assert_eq!(
            MasterMove::plan(Master::ZERO, far, &lim, 0.001),
            Err(ScurveError::DistanceTooLong)
        );
        assert_eq!(
            MasterMove::plan(Master::MIN, Master::MAX, &lim, 0.001),
            Err(ScurveError::DistanceTooLong)
        );
        let bad = MasterLimits {
            jerk_counts_per_s3: 0.0,
            ..lim
        };
        assert_eq!(
            MasterMove::plan(Master::ZERO, Master::from_num(1), &bad, 0.001),
            Err(ScurveError::Jerk)
        );
    }

    /// The S-curve as the follower's master (SPEC §A, time-based master): a cam table
    /// x = 20 mm + 10 mm·sin(πθ/20 000) over θ = 0 … 90 000 counts is run against a
    /// jerk-limited virtual master; the follower's target follows the table at the
    /// S-curve master, its master filter never flags a jump, and the slave ends on the
    /// table's last node.
    #[test]
    fn drives_the_follower() {
        use crate::axis::{AxisConfig, ControlMode, PositionGains};
        use crate::follower::{Follower, FollowerConfig, FollowerInputs};
        use crate::table::{AxisLimits, CamTable, Node, TableLimits};
        use crate::units::{MasterRate, PosUm, VelUmPerS};
        use std::vec::Vec;

        let x_of = |m: f64| 20_000.0 + 10_000.0 * (m / 20_000.0 * core::f64::consts::PI).sin();
        let nodes: Vec<Node<1>> = (0..=180)
            .map(|j| {
                let m = f64::from(j) * 500.0;
                Node {
                    master: Master::from_num(m),
                    slave_um: [PosUm::from_num(x_of(m))],
                }
            })
            .collect();
        // The table's chord interpolation, f64 (500-count segments).
        let chord = |m: f64| {
            let j = (m / 500.0).floor().clamp(0.0, 179.0);
            let (m0, m1) = (j * 500.0, j * 500.0 + 500.0);
            let (x0, x1) = (
                PosUm::from_num(x_of(m0)).to_num::<f64>(),
                PosUm::from_num(x_of(m1)).to_num::<f64>(),
            );
            x0 + (x1 - x0) * (m - m0) / 500.0
        };
        let limits = TableLimits {
            master_speed_per_s: MasterRate::from_num(3000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(-1_000_000),
                max_um: PosUm::from_num(1_000_000),
                max_speed_um_per_s: VelUmPerS::from_num(200_000),
            }],
        };
        let table = CamTable::<1, 256>::try_from_nodes(&nodes, &limits).unwrap();
        let cfg = FollowerConfig {
            axes: [AxisConfig {
                gains: PositionGains {
                    kp_lsb_per_um: 0.4,
                    following_error_um: 5000.0,
                    ..PositionGains::default()
                },
                mode: ControlMode::Feedforward,
                ..AxisConfig::default()
            }],
            ..FollowerConfig::default()
        };
        let mut f = Follower::new(&cfg, table).unwrap();
        let lim = MasterLimits {
            vel_counts_per_s: 3000.0,
            acc_counts_per_s2: 6000.0,
            jerk_counts_per_s3: 40_000.0,
        };
        let mv = MasterMove::plan(Master::ZERO, Master::from_num(90_000), &lim, 0.001).unwrap();
        let mut sm = ScurveMaster::new(mv);
        let mut x = PosUm::from_num(x_of(0.0));
        let mut worst = 0.0f64;
        // The move, then one second at rest.
        for _ in 0..=(mv.profile().end_tick() + 1000) {
            let m = sm.tick();
            let o = f.tick(&FollowerInputs {
                master: m,
                pos_um: [x],
                pressure_bar: [[crate::units::PressureBar::ZERO; 2]; 1],
            });
            assert!(!o.master_jump);
            assert_eq!(o.fault[0], None);
            let want = chord(m.to_num::<f64>());
            worst = worst.max((o.target_um[0].to_num::<f64>() - want).abs());
            // An ideal slave: at its target one period later.
            x = o.target_um[0];
        }
        assert!(sm.done());
        assert_eq!(sm.tick(), Master::from_num(90_000));
        // The filter tracks the smooth master closely (measured: 0.45 µm at most).
        assert!(
            worst < 1.0,
            "target off the table at the S-curve master by {worst} µm"
        );
        let last = nodes[180].slave_um[0].to_num::<f64>();
        assert!(
            (x.to_num::<f64>() - last).abs() < 0.05,
            "ends at {x}, table end {last}"
        );
    }
}
