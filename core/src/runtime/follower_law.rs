//! The SPEC §A follower ([`Follower`]) as the runtime's control law.
//!
//! | runtime | follower |
//! |---|---|
//! | [`Controller::restart`] | [`Follower::restart`] + [`Follower::clear_faults`] (a new run starts clean: the runtime only restarts a law after Idle, i.e. after any fault was cleared) |
//! | [`Controller::tick`] | [`Follower::tick`]; `dac`, `error_um`, `end_of_table` pass through, `AxisFault::FollowingError` → [`LawFault::FollowingError`] |
//! | [`Controller::null_codes`] | [`Follower::safe_outputs`] (each axis' calibrated valve null) |
//! | [`Controller::master_span`] | the table's first and last master values |
//!
//! The follower's own period (`FollowerConfig::period_us`) must equal the runtime's
//! (`RuntimeConfig::period_us`); the board builds both from one constant. Its master-jump
//! flag is not mapped: the runtime's encoder plausibility check is stricter.

use super::controller::{ControlInputs, ControlOutputs, Controller, LawFault};
use crate::axis::PosRef;
use crate::follower::{AxisFault, Follower, FollowerInputs};
use crate::units::{DacCode, Master};

impl<const S: usize, const N: usize> Controller<S> for Follower<S, N> {
    fn restart(&mut self, _inputs: &ControlInputs<S>) {
        Follower::restart(self);
        self.clear_faults();
    }

    #[inline]
    fn tick(&mut self, inputs: &ControlInputs<S>) -> ControlOutputs<S> {
        let out = Follower::tick(
            self,
            &FollowerInputs {
                master: inputs.master,
                pos_um: inputs.pos_um,
                pressure_bar: inputs.pressure_bar,
            },
        );
        ControlOutputs {
            dac: out.dac,
            error_um: out.error_um,
            end_of_table: out.end_of_table,
            axis_fault: out.fault.map(|f| {
                f.map(|f| match f {
                    AxisFault::FollowingError => LawFault::FollowingError,
                })
            }),
        }
    }

    fn tick_manual(&mut self, inputs: &ControlInputs<S>, refs: &[PosRef; S]) -> ControlOutputs<S> {
        let out = Follower::tick_manual(self, &inputs.pos_um, &inputs.pressure_bar, refs);
        ControlOutputs {
            dac: out.dac,
            error_um: out.error_um,
            end_of_table: false,
            axis_fault: out
                .fault
                .map(|f| f.map(|AxisFault::FollowingError| LawFault::FollowingError)),
        }
    }

    fn table_position_um(&self, master: Master) -> Option<[crate::units::PosUm; S]> {
        (!self.table().is_empty()).then(|| Follower::table_position_um(self, master))
    }

    fn null_codes(&self) -> [DacCode; S] {
        self.safe_outputs()
    }

    fn master_span(&self) -> Option<(Master, Master)> {
        Some((self.table().master_first(), self.table().master_last()))
    }

    fn following_error_limit_um(&self, axis: usize) -> Option<crate::units::PosUm> {
        Follower::following_error_limit_um(self, axis)
    }

    fn learned(&self, axis: usize) -> super::Learned {
        super::Learned {
            backoff_level: Follower::backoff_level(self, axis),
            ff_trim_q16: Follower::ff_trim_q16(self, axis),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use crate::axis::{AxisConfig, PositionGains};
    use crate::follower::{Follower, FollowerConfig};
    use crate::table::{AxisLimits, CamTable, Node, TableLimits};
    use crate::units::{Counts, Master, MasterRate, PosUm, PressureBar, VelUmPerS};
    use crate::valve::ValveCal;
    use std::vec::Vec;

    /// x = 20 mm + 5 µm per master count over 0 … 10 000 counts (one slave).
    fn follower() -> Follower<1, 16> {
        let nodes: Vec<Node<1>> = (0..=10)
            .map(|j| Node {
                master: Master::from_num(j * 1000),
                slave_um: [PosUm::from_num(20_000 + j * 5000)],
            })
            .collect();
        let limits = TableLimits {
            master_speed_per_s: MasterRate::from_num(10_000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(0),
                max_um: PosUm::from_num(500_000),
                max_speed_um_per_s: VelUmPerS::from_num(100_000),
            }],
        };
        let table = CamTable::try_from_nodes(&nodes, &limits).unwrap();
        let cfg = FollowerConfig {
            axes: [AxisConfig {
                gains: PositionGains {
                    kp_lsb_per_um: 0.5,
                    following_error_um: 3000.0,
                    ..PositionGains::default()
                },
                valve: ValveCal {
                    null_lsb: -12.0,
                    ..ValveCal::default()
                },
                ..AxisConfig::default()
            }],
            ..FollowerConfig::default()
        };
        Follower::new(&cfg, table).unwrap()
    }

    fn sample(master: i32, slave: i32) -> Sample<1, 0> {
        Sample {
            enc: EncoderSample {
                master: Counts(master),
                slaves: [Counts(slave)],
                master_edges: None,
            },
            pressure_bar: [PressureBar::ZERO; 0],
            estop: false,
            overrun: false,
        }
    }

    #[test]
    fn runs_the_follower_to_the_end_of_the_table() {
        let cfg = RuntimeConfig::<1>::default().build().unwrap();
        let mut r: Runtime<Follower<1, 16>, 1, 0> =
            Runtime::new(cfg, Some(follower()), BootCause::Normal);
        assert_eq!(r.null_codes()[0].get(), -12);
        let out = r.step(&sample(0, 20_000), None);
        assert_eq!(out.dac[0].get(), -12, "idle writes the calibrated null");
        // Integrating plant, 1 µm per 4 LSB above null per tick; master 2 counts/tick.
        let mut x = 20_000i64;
        let mut cmd = Some(Command::Start);
        let mut worst = 0i64;
        for k in 0..6000i64 {
            let m = (k * 2).min(10_500);
            let out = r.step(&sample(m as i32, x as i32), cmd.take());
            x += i64::from(out.dac[0].get() + 12) / 4;
            if (200..5000).contains(&k) {
                let target = 20_000 + 5 * m.min(10_000);
                worst = worst.max((target - x).abs());
            }
        }
        assert_eq!(
            r.state(),
            State::Holding(HoldReason::EndOfTable),
            "{:?}",
            r.fault()
        );
        assert!(worst < 100, "worst error {worst} µm");
        assert!((x - 70_000).abs() < 30, "held at {x}");
        // Standing still at the end for longer than the stall timeout: no fault.
        for _ in 0..3000 {
            r.step(&sample(10_500, x as i32), None);
        }
        assert_eq!(r.state(), State::Holding(HoldReason::EndOfTable));
    }

    /// The runtime hands slave 0 its chamber pressures (inputs 0 and 1) and the law's
    /// active damping acts on them: a rise of p_A lowers the command by k·A_A·Δp, the
    /// high-pass then lets it fade; the same run without damping ignores the pressures.
    #[test]
    fn pressures_reach_the_active_damping() {
        use crate::axis::PistonAreas;
        let run = |dp_gain: f32, jump_bar: f64| {
            let mut f = follower();
            let mut cfg = FollowerConfig::<1>::default();
            cfg.axes[0] = AxisConfig {
                gains: PositionGains {
                    kp_lsb_per_um: 0.5,
                    following_error_um: 3000.0,
                    dp_gain_lsb_per_kn: dp_gain,
                    dp_corner_hz: 5.0,
                    ..PositionGains::default()
                },
                areas: PistonAreas {
                    area_a_mm2: 5000.0,
                    area_b_mm2: 2500.0,
                },
                ..AxisConfig::default()
            };
            f.configure(&cfg).unwrap();
            let rc = RuntimeConfig::<1>::default().build().unwrap();
            let mut r: Runtime<Follower<1, 16>, 1, 2> =
                Runtime::new(rc, Some(f), BootCause::Normal);
            let s = |p_a: f64| Sample {
                enc: EncoderSample {
                    master: Counts(0),
                    slaves: [Counts(20_000)],
                    master_edges: None,
                },
                pressure_bar: [PressureBar::from_num(p_a), PressureBar::from_num(40)],
                estop: false,
                overrun: false,
            };
            r.step(&s(80.0), Some(Command::Start));
            r.step(&s(80.0), None);
            let before = r.step(&s(80.0), None).dac[0].get();
            let after = r.step(&s(80.0 + jump_bar), None).dac[0].get();
            (before, after)
        };
        let (b0, a0) = run(0.0, 10.0);
        assert_eq!(b0, a0, "no damping: the pressures are not used");
        // 16 LSB/kN · 5000 mm² · 10 bar = 80 LSB, times α = 0.97 on its first tick.
        let (b, a) = run(16.0, 10.0);
        assert_eq!(b, b0, "a steady pressure gives no correction");
        assert!(((b - a) - 78).abs() <= 1, "{b} → {a}");
    }

    #[test]
    fn the_followers_own_limit_latches_a_following_error() {
        let cfg = RuntimeConfig::<1> {
            following_error_limit_um: [1.0e6],
            ..Default::default()
        };
        let mut r: Runtime<Follower<1, 16>, 1, 0> =
            Runtime::new(cfg.build().unwrap(), Some(follower()), BootCause::Normal);
        r.step(&sample(0, 20_000), Some(Command::Start));
        // Slave 4 mm off (follower limit 3 mm), moving 1000 counts a tick (plausible).
        for (k, x) in [21_000, 22_000, 23_000, 24_000].iter().enumerate() {
            r.step(&sample(0, *x), None);
            if k < 2 {
                assert_eq!(r.state(), State::Following);
            }
        }
        let rec = r.fault().unwrap();
        assert_eq!(rec.fault, Fault::FollowingError { axis: 0 });
        assert_eq!(r.status().dac[0].get(), -12);
        // The history names the follower's 3 mm limit, not the runtime's 1 000 mm.
        let ev = *r.fault_history().recent().unwrap();
        assert_eq!(ev.limit, 3000 << 8);
        assert!(ev.value.unsigned_abs() > 3000 << 8, "{ev:?}");
        // Clear, restart: the follower's latched axis fault is cleared too.
        r.step(&sample(0, 20_000), None);
        assert_eq!(
            r.step(&sample(0, 20_000), Some(Command::ClearFault)).reply,
            Some(Ok(()))
        );
        r.step(&sample(0, 20_000), Some(Command::Start));
        r.step(&sample(0, 20_000), None);
        assert_eq!(r.state(), State::Following);
    }
}
