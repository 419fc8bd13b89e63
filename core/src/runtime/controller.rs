//! The control law as the runtime sees it: one call per tick, master and slave positions
//! in, valve codes and following errors out.
//!
//! The runtime owns states, faults and the valve enable; the law behind this trait owns
//! the maths (prediction, table interpolation, PID, valve calibration). The follower of
//! SPEC §A implements it (`runtime::follower_law`); tests use a mock. The runtime calls
//! [`Controller::restart`] whenever control begins (Idle → Following/Holding), so the law
//! can clear its history and integrators and start bumplessly from the measured state.

use crate::axis::PosRef;
use crate::units::{DacCode, Master, PosUm, PressureBar};

/// What the law gets each tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlInputs<const S: usize> {
    /// Master position, master counts (frozen while holding).
    pub master: Master,
    /// Measured slave positions latched at the period start, µm.
    pub pos_um: [PosUm; S],
    /// Per slave, chamber A and B pressures read this period, bar
    /// ([`super::io::chamber_pressures`]).
    pub pressure_bar: [[PressureBar; 2]; S],
}

/// What the law returns each tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlOutputs<const S: usize> {
    /// Calibrated valve codes to write this tick (0 = the DAC's mid-scale, *not*
    /// necessarily the valve null: see [`Controller::null_codes`]).
    pub dac: [DacCode; S],
    /// Following error target − position per slave, µm (the target the law is chasing).
    pub error_um: [PosUm; S],
    /// The master has passed the end of the table: the slaves hold the final position.
    pub end_of_table: bool,
    /// A slave the law itself considers faulted (the runtime latches the fault).
    pub axis_fault: [Option<LawFault>; S],
}

/// A fault the law reports on one slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LawFault {
    /// The law's own following-error limit (latched as `Fault::FollowingError`).
    FollowingError,
    /// Anything else (latched as `Fault::Controller`).
    Other,
}

impl<const S: usize> ControlOutputs<S> {
    /// Outputs with every code at `dac`, no error and no fault.
    pub const fn at(dac: [DacCode; S]) -> Self {
        Self {
            dac,
            error_um: [PosUm::ZERO; S],
            end_of_table: false,
            axis_fault: [None; S],
        }
    }
}

/// A control law the runtime can run (see the module docs).
pub trait Controller<const S: usize> {
    /// Re-arms the law for control starting from `inputs` (history, integrators and
    /// output state reset). Called before the first [`Controller::tick`] of a run.
    fn restart(&mut self, inputs: &ControlInputs<S>);

    /// One control period. Must not fail or panic for any input.
    fn tick(&mut self, inputs: &ControlInputs<S>) -> ControlOutputs<S>;

    /// One period of manual control (`super::manual`): each slave's position law toward
    /// `refs` (position, velocity and acceleration feed-forward) instead of the table.
    /// `end_of_table` is false. Must not fail or panic for any input.
    fn tick_manual(&mut self, inputs: &ControlInputs<S>, refs: &[PosRef; S]) -> ControlOutputs<S>;

    /// Every slave's table position at `master` (the approach's targets), if the law has
    /// a table.
    fn table_position_um(&self, _master: Master) -> Option<[PosUm; S]> {
        None
    }

    /// The code that puts each slave's valve spool at its null (the calibrated safe
    /// output written in Idle and Fault).
    fn null_codes(&self) -> [DacCode; S];

    /// The master range the law covers (first, last), if it has one: a master standing
    /// still within `stall_end_window_counts` of either end is not a stall.
    fn master_span(&self) -> Option<(Master, Master)> {
        None
    }

    /// The law's own following-error limit of slave `axis`, if it has one (the limit a
    /// [`LawFault::FollowingError`] exceeded, for the fault history).
    fn following_error_limit_um(&self, _axis: usize) -> Option<PosUm> {
        None
    }

    /// What the law has learned about slave `axis` while running: its supervisors'
    /// state ([`Learned`]). Read for the status report, not by the tick.
    fn learned(&self, _axis: usize) -> Learned {
        Learned::NONE
    }
}

/// What a law learned about one slave while running, beside its set gains: the gain
/// backoff's level (`crate::axis::backoff`) and the feed-forward trim's ratios
/// (`crate::axis::ff_trim`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Learned {
    /// The gain backoff's level: 0 = the set gain (also for a law without one).
    pub backoff_level: u8,
    /// The feed-forward trim's ratios, `[negative, positive]` feed-forward, Q16 (65 536 =
    /// the calibrated gain, also for a law without the trim).
    pub ff_trim_q16: [i32; 2],
}

impl Learned {
    /// Nothing learned: the set gain, the calibrated feed-forward.
    pub const NONE: Self = Self {
        backoff_level: 0,
        ff_trim_q16: [65_536; 2],
    };
}

/// `Controller` for a pointer type `$p<C>` to a law `C`, forwarding every call.
macro_rules! forward_controller {
    ($(#[$m:meta])* $p:ty) => {
        $(#[$m])*
        impl<const S: usize, C: Controller<S> + ?Sized> Controller<S> for $p {
            fn restart(&mut self, inputs: &ControlInputs<S>) {
                (**self).restart(inputs);
            }

            fn tick(&mut self, inputs: &ControlInputs<S>) -> ControlOutputs<S> {
                (**self).tick(inputs)
            }

            fn tick_manual(
                &mut self,
                inputs: &ControlInputs<S>,
                refs: &[PosRef; S],
            ) -> ControlOutputs<S> {
                (**self).tick_manual(inputs, refs)
            }

            fn table_position_um(&self, master: Master) -> Option<[PosUm; S]> {
                (**self).table_position_um(master)
            }

            fn null_codes(&self) -> [DacCode; S] {
                (**self).null_codes()
            }

            fn master_span(&self) -> Option<(Master, Master)> {
                (**self).master_span()
            }

            fn following_error_limit_um(&self, axis: usize) -> Option<PosUm> {
                (**self).following_error_limit_um(axis)
            }

            fn learned(&self, axis: usize) -> Learned {
                (**self).learned(axis)
            }
        }
    };
}

forward_controller!(
    /// A law held by reference: the runtime can run a law that lives elsewhere (a static
    /// buffer on the board), so installing one swaps a pointer instead of moving the law —
    /// `Follower<2, 256>` by value is ≈ 119 000 instructions of copying inside the tick's
    /// critical section (bench-m4 `runtime_install_law`, docs/firmware.md).
    &mut C
);

forward_controller!(
    /// A law on the heap (host builds): the host's laws with large tables are built in
    /// place in a `Box` (never on the stack) and installed by moving the pointer.
    #[cfg(any(test, feature = "std"))]
    std::boxed::Box<C>
);

#[cfg(test)]
pub(crate) mod mock {
    //! A mock law: a proportional controller toward `target_um` (or a table-free
    //! "target = master · ratio"), with injectable faults and end of table.
    use super::*;

    /// A scripted controller for the runtime tests.
    #[derive(Clone, Debug)]
    pub struct MockLaw<const S: usize> {
        /// µm of target per master count.
        pub ratio: i32,
        /// Code per µm of error.
        pub gain: i32,
        /// Master value past which `end_of_table` is reported.
        pub end_master: i64,
        /// Slaves reported as faulted.
        pub axis_fault: [Option<LawFault>; S],
        /// Valve nulls.
        pub nulls: [DacCode; S],
        /// How many times `restart` was called.
        pub restarts: u32,
        /// The chamber pressures of the last tick.
        pub pressures: [[crate::units::PressureBar; 2]; S],
    }

    impl<const S: usize> MockLaw<S> {
        pub fn new() -> Self {
            Self {
                ratio: 1,
                gain: 2,
                end_master: 1 << 40,
                axis_fault: [None; S],
                nulls: [DacCode::new_clamped(7); S],
                restarts: 0,
                pressures: [[crate::units::PressureBar::ZERO; 2]; S],
            }
        }

        pub fn target(&self, master: Master) -> PosUm {
            PosUm::saturating_from_num(master.to_num::<i64>().saturating_mul(self.ratio.into()))
        }
    }

    impl<const S: usize> Controller<S> for MockLaw<S> {
        fn restart(&mut self, _inputs: &ControlInputs<S>) {
            self.restarts += 1;
        }

        fn tick(&mut self, inputs: &ControlInputs<S>) -> ControlOutputs<S> {
            let target = self.target(inputs.master);
            self.pressures = inputs.pressure_bar;
            let mut out = ControlOutputs::at(self.nulls);
            for i in 0..S {
                let e = target.saturating_sub(inputs.pos_um[i]);
                out.error_um[i] = e;
                let code = e.to_num::<i32>().saturating_mul(self.gain);
                out.dac[i] = DacCode::new_clamped(code.saturating_add(self.nulls[i].get().into()));
                out.axis_fault[i] = self.axis_fault[i];
            }
            out.end_of_table = inputs.master.to_num::<i64>() > self.end_master;
            out
        }

        #[allow(clippy::needless_range_loop)] // four arrays indexed alike
        fn tick_manual(
            &mut self,
            inputs: &ControlInputs<S>,
            refs: &[PosRef; S],
        ) -> ControlOutputs<S> {
            let mut out = ControlOutputs::at(self.nulls);
            for i in 0..S {
                let e = refs[i].x_ref_um.saturating_sub(inputs.pos_um[i]);
                out.error_um[i] = e;
                let code = e.to_num::<i32>().saturating_mul(self.gain);
                out.dac[i] = DacCode::new_clamped(code.saturating_add(self.nulls[i].get().into()));
                out.axis_fault[i] = self.axis_fault[i];
            }
            out
        }

        fn table_position_um(&self, master: Master) -> Option<[PosUm; S]> {
            Some([self.target(master); S])
        }

        fn null_codes(&self) -> [DacCode; S] {
            self.nulls
        }
    }
}
