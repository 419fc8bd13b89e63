//! Runtime configuration in engineering units, validated once into per-tick integers.
//!
//! ```text
//! jump limit (counts/tick)  = ⌈v_max · T / scale⌉        (master: ⌈θ̇_max · T⌉)
//! stall timeout (ticks)      = ⌈t_stall / T⌉
//! position (µm)              = count · um_per_count + offset_um
//! ```
//!
//! with T the control period. Defaults are those of the reference machine (PLANT.md):
//! 1 kHz, master 0.001°/count on an encoder, slaves 1 µm/count.

use super::reference::ReferenceMode;
use crate::units::PosUm;
use fixed::types::I32F32;

/// Where the master position comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MasterSource {
    /// The master encoder (channel 0), one master count per encoder count.
    Encoder,
    /// Time: the master advances one count per tick while following and stands still
    /// while holding (a time-based trajectory table).
    Time,
}

/// Runtime configuration in engineering units (validated by [`RuntimeConfig::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RuntimeConfig<const S: usize> {
    /// Control period, µs (100 … 1 000 000, i.e. 10 kHz … 1 Hz; default 1000). The board
    /// runs 1 kHz; the simulator runs the runtime at the long periods of the baselines
    /// (72 ms, the paper's machine) too.
    pub period_us: u32,
    /// Where the master comes from.
    pub master_source: MasterSource,
    /// Count the master encoder backwards (wiring).
    pub master_invert: bool,
    /// Fastest plausible master speed, master counts/s (> 0). A faster step in one tick
    /// is an encoder fault.
    pub master_max_speed_counts_per_s: f32,
    /// Slave encoder scale, µm per count (0.001 ≤ |x| ≤ 1000; negative reverses).
    pub slave_um_per_count: [f32; S],
    /// Slave position at count 0, µm (|x| ≤ 8 000 000).
    pub slave_offset_um: [f32; S],
    /// Fastest plausible slave speed, µm/s (> 0). A faster step is an encoder fault.
    pub slave_max_speed_um_per_s: [f32; S],
    /// Largest |target − position| tolerated while controlling, µm (0 < x ≤ 1 000 000).
    pub following_error_limit_um: [f32; S],
    /// Following, a master standing still this long after it has moved is a fault, s
    /// (0.01 … 600).
    pub stall_timeout_s: f32,
    /// The master "moves" if it changes by at least this many counts (≥ 1) within the
    /// stall timeout.
    pub stall_min_move_counts: u32,
    /// A master standing still within this distance of either end of the law's master
    /// span (or beyond it) is not a stall, master counts.
    pub stall_end_window_counts: u32,
    /// Holding → Following is refused if the master moved more than this while holding,
    /// master counts.
    pub resume_window_counts: u32,
    /// How each slave's position is referenced (`super::reference`; default
    /// `Absolute`: the count is the position). An `Incremental` slave must be
    /// referenced (set-position or homing) before Start.
    pub slave_reference: [ReferenceMode; S],
    /// Each slave's position at its reference edge (homing), µm (|x| ≤ 8 000 000).
    pub home_position_um: [f32; S],
    /// A law that depends on the pressure inputs runs (a force axis): a pressure input
    /// that stops updating (`PressureInput::healthy` false) latches
    /// `Fault::PressureInput`. Without one, a stale pressure is only reported.
    pub pressure_required: bool,
}

impl<const S: usize> Default for RuntimeConfig<S> {
    fn default() -> Self {
        Self {
            period_us: 1000,
            master_source: MasterSource::Encoder,
            master_invert: false,
            // 60 °/s at 0.001 °/count: 20× the nominal table speed.
            master_max_speed_counts_per_s: 60_000.0,
            slave_um_per_count: [1.0; S],
            slave_offset_um: [0.0; S],
            // 1 m/s: ~8× what the reference valve can give the cylinder.
            slave_max_speed_um_per_s: [1_000_000.0; S],
            following_error_limit_um: [2_000.0; S],
            stall_timeout_s: 1.0,
            stall_min_move_counts: 10,
            stall_end_window_counts: 100,
            resume_window_counts: 100,
            slave_reference: [ReferenceMode::Absolute; S],
            home_position_um: [0.0; S],
            pressure_required: false,
        }
    }
}

/// A configuration value out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RuntimeConfigError {
    /// `period_us` not in 100 … 1 000 000.
    Period,
    /// `master_max_speed_counts_per_s` not positive and finite, or more than 16 383
    /// counts per tick (the 16-bit extension needs steps below 2^15).
    MasterMaxSpeed,
    /// A slave's `um_per_count` outside 0.001 … 1000 in magnitude.
    Scale {
        /// Slave axis.
        axis: u8,
    },
    /// A slave's offset beyond ±8 000 000 µm.
    Offset {
        /// Slave axis.
        axis: u8,
    },
    /// A slave's plausible speed not positive, or more than 16 383 counts per tick.
    SlaveMaxSpeed {
        /// Slave axis.
        axis: u8,
    },
    /// A following-error limit not in (0, 1 000 000] µm.
    FollowingErrorLimit {
        /// Slave axis.
        axis: u8,
    },
    /// `stall_timeout_s` not in 0.01 … 600 or `stall_min_move_counts` is 0.
    Stall,
    /// A slave's home position beyond ±8 000 000 µm.
    Home {
        /// Slave axis.
        axis: u8,
    },
}

/// Largest per-tick step limit: below 2^14 so a 16-bit extension can never alias a
/// step it accepts.
pub const MAX_STEP_LIMIT_COUNTS: u32 = (1 << 14) - 1;

/// Validated runtime configuration (per-tick integers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RuntimeCoeffs<const S: usize> {
    /// Control period, µs.
    pub period_us: u32,
    /// Master source.
    pub master_source: MasterSource,
    /// Master counted backwards.
    pub master_invert: bool,
    /// Master plausibility limit, counts per tick.
    pub master_step_limit: u32,
    /// Slave scale, µm/count in Q31.32 (`i64` raw, resolution 2.3e-10 µm/count).
    pub slave_scale_q32: [i64; S],
    /// Slave offset, µm (`I24F8`).
    pub slave_offset_um: [PosUm; S],
    /// Slave plausibility limits, counts per tick.
    pub slave_step_limit: [u32; S],
    /// Following-error limits, µm (`I24F8`).
    pub following_error_limit_um: [PosUm; S],
    /// Stall timeout, ticks (≥ 1).
    pub stall_timeout_ticks: u32,
    /// Stall movement threshold, master counts.
    pub stall_min_move_counts: u32,
    /// Stall end window, master counts.
    pub stall_end_window_counts: u32,
    /// Resume window, master counts.
    pub resume_window_counts: u32,
    /// Reference mode per slave.
    pub slave_reference: [ReferenceMode; S],
    /// Home position per slave, µm (`I24F8`).
    pub home_position_um: [PosUm; S],
    /// Pressure inputs required (see [`RuntimeConfig::pressure_required`]).
    pub pressure_required: bool,
}

fn finite_in(x: f32, lo: f32, hi: f32) -> bool {
    x.is_finite() && x >= lo && x <= hi
}

/// ⌈x⌉ for 0 ≤ x (no_std has no `f64::ceil`); saturates at `u32::MAX`.
fn ceil_u32(x: f64) -> u32 {
    // `as` saturates and truncates toward zero; add one if a fraction was cut off.
    let t = x as u32;
    if f64::from(t) < x {
        t.saturating_add(1)
    } else {
        t
    }
}

/// ⌈counts per tick⌉ for a speed in counts/s, or `None` above the extension limit.
fn step_limit(counts_per_s: f64, period_us: u32) -> Option<u32> {
    if !counts_per_s.is_finite() || counts_per_s <= 0.0 {
        return None;
    }
    let per_tick = ceil_u32(counts_per_s * f64::from(period_us) * 1e-6);
    if per_tick > MAX_STEP_LIMIT_COUNTS {
        return None;
    }
    Some(per_tick.max(1))
}

/// Shortest control period the runtime accepts, µs (10 kHz).
pub const PERIOD_MIN_US: u32 = 100;
/// Longest control period the runtime accepts, µs (1 Hz).
pub const PERIOD_MAX_US: u32 = 1_000_000;

impl<const S: usize> RuntimeCoeffs<S> {
    /// Slave `axis`' encoder scale, µm per count (the Q31.32 coefficient as `f32`).
    pub fn um_per_count(&self, axis: u8) -> Option<f32> {
        let k = *self.slave_scale_q32.get(usize::from(axis))?;
        Some(I32F32::from_bits(k).to_num())
    }

    /// Changes slave `axis`' encoder scale to `um_per_count` (0.001 ≤ |x| ≤ 1000, as
    /// [`RuntimeConfig::build`] requires; negative reverses the count) and its
    /// plausibility limit with it, so the slave's top speed in µm/s stays what it was:
    /// `limit' = ⌈limit · |k| / |k'|⌉` counts per tick (within one count of building
    /// the configuration anew). `None` for an impossible scale, a missing slave or a
    /// limit beyond [`super::MAX_STEP_LIMIT_COUNTS`]; nothing changes then.
    pub fn set_um_per_count(&mut self, axis: u8, um_per_count: f32) -> Option<()> {
        if !finite_in(um_per_count.abs(), 0.001, 1000.0) {
            return None;
        }
        let i = usize::from(axis);
        let old = I32F32::from_bits(*self.slave_scale_q32.get(i)?).to_num::<f64>();
        let limit = *self.slave_step_limit.get(i)?;
        let counts = f64::from(limit) * old.abs() / f64::from(um_per_count.abs());
        let new_limit = ceil_u32(counts).max(1);
        if new_limit > super::MAX_STEP_LIMIT_COUNTS {
            return None;
        }
        *self.slave_scale_q32.get_mut(i)? = I32F32::saturating_from_num(um_per_count).to_bits();
        *self.slave_step_limit.get_mut(i)? = new_limit;
        Some(())
    }
}

impl<const S: usize> RuntimeConfig<S> {
    /// Validates the configuration and converts it to per-tick integers.
    pub fn build(&self) -> Result<RuntimeCoeffs<S>, RuntimeConfigError> {
        if !(PERIOD_MIN_US..=PERIOD_MAX_US).contains(&self.period_us) {
            return Err(RuntimeConfigError::Period);
        }
        let master_step_limit = step_limit(
            f64::from(self.master_max_speed_counts_per_s),
            self.period_us,
        )
        .ok_or(RuntimeConfigError::MasterMaxSpeed)?;
        let mut c = RuntimeCoeffs {
            period_us: self.period_us,
            master_source: self.master_source,
            master_invert: self.master_invert,
            master_step_limit,
            slave_scale_q32: [0; S],
            slave_offset_um: [PosUm::ZERO; S],
            slave_step_limit: [0; S],
            following_error_limit_um: [PosUm::ZERO; S],
            stall_timeout_ticks: 0,
            stall_min_move_counts: self.stall_min_move_counts,
            stall_end_window_counts: self.stall_end_window_counts,
            resume_window_counts: self.resume_window_counts,
            slave_reference: self.slave_reference,
            home_position_um: [PosUm::ZERO; S],
            pressure_required: self.pressure_required,
        };
        for (i, (o, &h)) in c
            .home_position_um
            .iter_mut()
            .zip(self.home_position_um.iter())
            .enumerate()
        {
            if !finite_in(h, -8.0e6, 8.0e6) {
                let axis = u8::try_from(i).unwrap_or(u8::MAX);
                return Err(RuntimeConfigError::Home { axis });
            }
            *o = PosUm::saturating_from_num(h);
        }
        let axes = self
            .slave_um_per_count
            .iter()
            .zip(self.slave_offset_um.iter())
            .zip(self.slave_max_speed_um_per_s.iter())
            .zip(self.following_error_limit_um.iter());
        let out = c
            .slave_scale_q32
            .iter_mut()
            .zip(c.slave_offset_um.iter_mut())
            .zip(c.slave_step_limit.iter_mut())
            .zip(c.following_error_limit_um.iter_mut());
        for (i, ((((&scale, &offset), &vmax), &fe), (((o_scale, o_off), o_step), o_fe))) in
            axes.zip(out).enumerate()
        {
            let axis = u8::try_from(i).unwrap_or(u8::MAX);
            if !finite_in(scale.abs(), 0.001, 1000.0) {
                return Err(RuntimeConfigError::Scale { axis });
            }
            if !finite_in(offset, -8.0e6, 8.0e6) {
                return Err(RuntimeConfigError::Offset { axis });
            }
            let counts_per_s = f64::from(vmax) / f64::from(scale.abs());
            *o_step = step_limit(counts_per_s, self.period_us)
                .ok_or(RuntimeConfigError::SlaveMaxSpeed { axis })?;
            if !finite_in(fe, f32::MIN_POSITIVE, 1.0e6) {
                return Err(RuntimeConfigError::FollowingErrorLimit { axis });
            }
            // |scale| ≤ 1000 ⇒ |scale·2^32| < 2^42: in range; rounded to nearest.
            *o_scale = I32F32::saturating_from_num(scale).to_bits();
            *o_off = PosUm::saturating_from_num(offset);
            *o_fe = PosUm::saturating_from_num(fe);
        }
        if !finite_in(self.stall_timeout_s, 0.01, 600.0) || self.stall_min_move_counts == 0 {
            return Err(RuntimeConfigError::Stall);
        }
        // ≤ 600 s / 100 µs = 6e6 ticks: fits u32.
        c.stall_timeout_ticks =
            ceil_u32(f64::from(self.stall_timeout_s) * 1e6 / f64::from(self.period_us));
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_builds_to_reference_limits() {
        let c = RuntimeConfig::<2>::default().build().unwrap();
        assert_eq!(c.master_step_limit, 60);
        assert_eq!(c.slave_step_limit, [1000, 1000]);
        assert_eq!(c.slave_scale_q32, [1i64 << 32; 2]);
        assert_eq!(c.stall_timeout_ticks, 1000);
        assert_eq!(c.following_error_limit_um[0], PosUm::from_num(2000));
    }

    #[test]
    fn period_scales_limits() {
        let cfg = RuntimeConfig::<1> {
            period_us: 100,
            ..Default::default()
        };
        let c = cfg.build().unwrap();
        assert_eq!(c.master_step_limit, 6);
        assert_eq!(c.slave_step_limit, [100]);
        assert_eq!(c.stall_timeout_ticks, 10_000);
    }

    #[test]
    fn rejects_each_bad_value() {
        let bad = |f: fn(&mut RuntimeConfig<2>)| {
            let mut c = RuntimeConfig::<2>::default();
            f(&mut c);
            c.build()
        };
        assert_eq!(bad(|c| c.period_us = 99), Err(RuntimeConfigError::Period));
        assert_eq!(
            bad(|c| c.period_us = 1_000_001),
            Err(RuntimeConfigError::Period)
        );
        assert_eq!(
            bad(|c| c.master_max_speed_counts_per_s = f32::NAN),
            Err(RuntimeConfigError::MasterMaxSpeed)
        );
        assert_eq!(
            bad(|c| c.master_max_speed_counts_per_s = 2.0e7),
            Err(RuntimeConfigError::MasterMaxSpeed)
        );
        assert_eq!(
            bad(|c| c.slave_um_per_count[1] = 0.0),
            Err(RuntimeConfigError::Scale { axis: 1 })
        );
        assert_eq!(
            bad(|c| c.slave_offset_um[0] = 9.0e6),
            Err(RuntimeConfigError::Offset { axis: 0 })
        );
        assert_eq!(
            bad(|c| c.slave_max_speed_um_per_s[1] = -1.0),
            Err(RuntimeConfigError::SlaveMaxSpeed { axis: 1 })
        );
        assert_eq!(
            bad(|c| c.slave_max_speed_um_per_s[0] = 1.0e9),
            Err(RuntimeConfigError::SlaveMaxSpeed { axis: 0 })
        );
        assert_eq!(
            bad(|c| c.following_error_limit_um[1] = 0.0),
            Err(RuntimeConfigError::FollowingErrorLimit { axis: 1 })
        );
        assert_eq!(
            bad(|c| c.stall_timeout_s = 0.0),
            Err(RuntimeConfigError::Stall)
        );
        assert_eq!(
            bad(|c| c.stall_min_move_counts = 0),
            Err(RuntimeConfigError::Stall)
        );
    }

    #[test]
    fn negative_scale_is_allowed() {
        let cfg = RuntimeConfig::<1> {
            slave_um_per_count: [-0.5],
            ..Default::default()
        };
        let c = cfg.build().unwrap();
        assert_eq!(c.slave_scale_q32, [-(1i64 << 31)]);
        assert_eq!(c.slave_step_limit, [2000]);
    }
}
