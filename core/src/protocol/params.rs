//! SetParam: one parameter applied to a follower configuration and its table limits.
//!
//! Shared by every [`super::Device`] (the firmware and the host's virtual board): the
//! device works on copies, calls [`apply_param`], rebuilds its law from the result and
//! keeps the copies only if that succeeds, so a refused parameter changes nothing.

use super::msg::{Nak, NakCode, ParamId};
use crate::axis::{AxisConfig, AxisConfigError};
use crate::follower::FollowerConfig;
use crate::table::{CamTable, TableLimits};
use crate::units::{MasterRate, PosUm, VelUmPerS};

/// Sets `param` of slave `axis` to `value` (engineering units, see [`ParamId`]) in `cfg`
/// and `lim`, then validates the whole configuration ([`validate_params`]): every axis
/// with its own builder ([`crate::axis::AxisConfig::build`]), every limit set, and the
/// `active` table against the new limits ([`CamTable::check_limits`]).
///
/// Errors: `UnknownParam` for an axis the device does not have, `ParamRange` (detail: axis
/// and parameter) for a value out of range or one the active table would violate; `cfg`
/// and `lim` may then be partly changed, so pass copies.
pub fn apply_param<const S: usize, const N: usize>(
    cfg: &mut FollowerConfig<S>,
    lim: &mut TableLimits<S>,
    active: Option<&CamTable<S, N>>,
    axis: u8,
    param: ParamId,
    value: f32,
) -> Result<(), Nak> {
    assign_param(cfg, lim, axis, param, value)?;
    validate_params(cfg, lim, active, Some((axis, param)))
}

/// Applies a whole set of saved parameters at once: every record is assigned first,
/// then the result is validated **once**, as a set ([`validate_params`]). So the order the
/// records were first set in does not matter (min 550 mm stored before max 700 mm is not
/// checked against the boot max of 500 mm), and a set that is not valid as a whole is
/// refused whole — never applied in part. `cfg` and `lim` may be partly changed on an
/// error, so pass copies. Records for [`ParamId::LinkTimeoutMs`] and
/// [`ParamId::SlaveOffsetUm`] are not follower parameters and are skipped here (the
/// handler and the device apply them).
pub fn apply_param_set<const S: usize, const N: usize>(
    cfg: &mut FollowerConfig<S>,
    lim: &mut TableLimits<S>,
    active: Option<&CamTable<S, N>>,
    records: &[super::ParamRecord],
) -> Result<(), Nak> {
    for r in records {
        if r.param.held_by_handler()
            || matches!(
                r.param,
                ParamId::SlaveOffsetUm | ParamId::PeriodUs | ParamId::HomeUm | ParamId::UmPerCount
            )
        {
            continue;
        }
        assign_param(cfg, lim, r.axis, r.param, r.value)?;
    }
    validate_params(cfg, lim, active, None)
}

/// A reference offset ([`ParamId::SlaveOffsetUm`]) of slave `axis` from its wire value,
/// µm: finite and within ±8 000 000 µm, else `ParamRange` naming the axis.
pub fn reference_offset_um(axis: u8, value: f32) -> Result<PosUm, Nak> {
    PosUm::checked_from_num(value)
        .filter(|_| value.abs() <= 8.0e6)
        .ok_or(Nak::with(
            NakCode::ParamRange,
            u16::from(axis),
            ParamId::SlaveOffsetUm as u8,
        ))
}

/// A home position ([`ParamId::HomeUm`]) of slave `axis` from its wire value, µm: finite
/// and within ±8 000 000 µm, else `ParamRange` naming the axis and the parameter.
pub fn home_um(axis: u8, value: f32) -> Result<PosUm, Nak> {
    let v = ParamId::HomeUm.check(axis, value)?;
    PosUm::checked_from_num(v).ok_or(Nak::with(
        NakCode::ParamRange,
        u16::from(axis),
        ParamId::HomeUm as u8,
    ))
}

/// An encoder scale ([`ParamId::UmPerCount`]) of slave `axis` from its wire value, µm per
/// count: finite, 0.001 ≤ |x| ≤ 1000, else `ParamRange` naming the axis and the
/// parameter.
pub fn um_per_count(axis: u8, value: f32) -> Result<f32, Nak> {
    let v = ParamId::UmPerCount.check(axis, value)?;
    if v.abs() < 0.001 {
        return Err(Nak::with(
            NakCode::ParamRange,
            u16::from(axis),
            ParamId::UmPerCount as u8,
        ));
    }
    Ok(v)
}

/// What a board keeps per slave beside the follower's configuration, restored with it
/// at boot: the reference offset of an absolute slave, the home position and the
/// encoder scale (`None`: the board's default).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlaveRefs<const S: usize> {
    /// [`ParamId::SlaveOffsetUm`], µm.
    pub offsets: [Option<PosUm>; S],
    /// [`ParamId::HomeUm`], µm.
    pub homes: [Option<PosUm>; S],
    /// [`ParamId::UmPerCount`], µm per count.
    pub scales: [Option<f32>; S],
}

impl<const S: usize> SlaveRefs<S> {
    /// Nothing kept: every slave at the board's defaults.
    pub const NONE: Self = Self {
        offsets: [None; S],
        homes: [None; S],
        scales: [None; S],
    };
}

/// A saved set as a board applies it at boot: the follower parameters with
/// [`apply_param_set`] and, per slave, the last [`ParamId::SlaveOffsetUm`]
/// ([`reference_offset_um`]), [`ParamId::HomeUm`] ([`home_um`]) and
/// [`ParamId::UmPerCount`] ([`um_per_count`]) into `refs`. All or
/// nothing for the caller, who passes copies and keeps them only on `Ok`.
pub fn apply_saved_set<const S: usize, const N: usize>(
    cfg: &mut FollowerConfig<S>,
    lim: &mut TableLimits<S>,
    refs: &mut SlaveRefs<S>,
    records: &[super::ParamRecord],
) -> Result<(), Nak> {
    apply_param_set::<S, N>(cfg, lim, None, records)?;
    for r in records {
        let range = Nak::with(NakCode::ParamRange, u16::from(r.axis), r.param as u8);
        let i = usize::from(r.axis);
        match r.param {
            ParamId::SlaveOffsetUm => {
                *refs.offsets.get_mut(i).ok_or(range)? =
                    Some(reference_offset_um(r.axis, r.value)?);
            }
            ParamId::HomeUm => {
                *refs.homes.get_mut(i).ok_or(range)? = Some(home_um(r.axis, r.value)?);
            }
            ParamId::UmPerCount => {
                *refs.scales.get_mut(i).ok_or(range)? = Some(um_per_count(r.axis, r.value)?);
            }
            _ => {}
        }
    }
    Ok(())
}

/// Writes one parameter's value, checked against its range alone ([`ParamId::check`]).
/// Read-only parameters ([`ParamId::PeriodUs`], [`ParamId::SlaveOffsetUm`]) and the
/// handler's own ([`ParamId::LinkTimeoutMs`]) are `UnknownParam` here.
fn assign_param<const S: usize>(
    cfg: &mut FollowerConfig<S>,
    lim: &mut TableLimits<S>,
    axis: u8,
    param: ParamId,
    value: f32,
) -> Result<(), Nak> {
    let unknown = Nak::with(NakCode::UnknownParam, u16::from(axis), param as u8);
    let value = param.check(axis, value)?;
    let range = Nak::with(NakCode::ParamRange, u16::from(axis), param as u8);
    match param {
        ParamId::MasterSpeedPerS => {
            lim.master_speed_per_s = MasterRate::checked_from_num(value).ok_or(range)?;
            return Ok(());
        }
        ParamId::MasterFilterHz => {
            cfg.master_filter.bandwidth_hz = value;
            return Ok(());
        }
        _ => {}
    }
    let i = usize::from(axis);
    let (Some(a), Some(l)) = (cfg.axes.get_mut(i), lim.axes.get_mut(i)) else {
        return Err(unknown);
    };
    match param {
        ParamId::MinUm => l.min_um = PosUm::checked_from_num(value).ok_or(range)?,
        ParamId::MaxUm => l.max_um = PosUm::checked_from_num(value).ok_or(range)?,
        ParamId::MaxSpeedUmPerS => {
            l.max_speed_um_per_s = VelUmPerS::checked_from_num(value).ok_or(range)?
        }
        _ => {
            if !assign_axis(a, param, value) {
                return Err(unknown);
            }
        }
    }
    Ok(())
}

/// Writes a gain or valve calibration field of one axis; `false` if `param` is not one.
pub(super) fn assign_axis(a: &mut AxisConfig, param: ParamId, value: f32) -> bool {
    let (g, v) = (&mut a.gains, &mut a.valve);
    match param {
        ParamId::KpLsbPerUm => g.kp_lsb_per_um = value,
        ParamId::KiLsbPerUmS => g.ki_lsb_per_um_s = value,
        ParamId::KdLsbSPerUm => g.kd_lsb_s_per_um = value,
        ParamId::IZoneUm => g.i_zone_um = value,
        ParamId::ILimitLsb => g.i_limit_lsb = value,
        ParamId::KvLsbPerUmS => {
            g.kv_pos_lsb_per_um_s = value;
            g.kv_neg_lsb_per_um_s = value;
        }
        ParamId::KvPosLsbPerUmS => g.kv_pos_lsb_per_um_s = value,
        ParamId::KvNegLsbPerUmS => g.kv_neg_lsb_per_um_s = value,
        ParamId::KaLsbPerUmS2 => g.ka_lsb_per_um_s2 = value,
        ParamId::ValveLagUs => g.valve_lag_us = value,
        ParamId::FollowingErrorUm => g.following_error_um = value,
        ParamId::DpGainLsbPerKn => g.dp_gain_lsb_per_kn = value,
        ParamId::DpCornerHz => g.dp_corner_hz = value,
        ParamId::AreaAMm2 => a.areas.area_a_mm2 = value,
        ParamId::AreaBMm2 => a.areas.area_b_mm2 = value,
        ParamId::OscBandUm => g.osc_band_um = value,
        ParamId::FfTrimTauS => g.ff_trim_tau_s = value,
        ParamId::ValveNullLsb => v.null_lsb = value,
        ParamId::ValveOverlapPosLsb => v.overlap_pos_lsb = value,
        ParamId::ValveOverlapNegLsb => v.overlap_neg_lsb = value,
        ParamId::ValveOverlapZoneLsb => v.overlap_zone_lsb = value,
        ParamId::ValveGainPos => v.gain_pos = value,
        ParamId::ValveGainNeg => v.gain_neg = value,
        ParamId::ValveInvert => v.invert = value != 0.0,
        // Checked an integer in 1 … 2047 by `ParamId::check`.
        ParamId::ValveClampLsb => v.clamp_lsb = value as u16,
        _ => match param.backoff_field() {
            Some(f) => *g.backoff.get_mut(f) = value,
            None => return false,
        },
    }
    true
}

/// The value of `param` of slave `axis` in `cfg` and `lim`, in its unit (what GetParam
/// answers for every parameter the follower holds; the handler answers
/// [`ParamId::LinkTimeoutMs`], the device [`ParamId::SlaveOffsetUm`]).
pub fn read_param<const S: usize>(
    cfg: &FollowerConfig<S>,
    lim: &TableLimits<S>,
    axis: u8,
    param: ParamId,
) -> Result<f32, Nak> {
    let unknown = Nak::with(NakCode::UnknownParam, u16::from(axis), param as u8);
    match param {
        ParamId::MasterSpeedPerS => return Ok(lim.master_speed_per_s.to_num()),
        ParamId::MasterFilterHz => return Ok(cfg.master_filter.bandwidth_hz),
        ParamId::PeriodUs => return Ok(cfg.period_us as f32),
        _ => {}
    }
    let i = usize::from(axis);
    let (Some(a), Some(l)) = (cfg.axes.get(i), lim.axes.get(i)) else {
        return Err(unknown);
    };
    let (g, v) = (&a.gains, &a.valve);
    Ok(match param {
        ParamId::KpLsbPerUm => g.kp_lsb_per_um,
        ParamId::KiLsbPerUmS => g.ki_lsb_per_um_s,
        ParamId::KdLsbSPerUm => g.kd_lsb_s_per_um,
        ParamId::IZoneUm => g.i_zone_um,
        ParamId::ILimitLsb => g.i_limit_lsb,
        ParamId::KvLsbPerUmS | ParamId::KvPosLsbPerUmS => g.kv_pos_lsb_per_um_s,
        ParamId::KvNegLsbPerUmS => g.kv_neg_lsb_per_um_s,
        ParamId::KaLsbPerUmS2 => g.ka_lsb_per_um_s2,
        ParamId::ValveLagUs => g.valve_lag_us,
        ParamId::FollowingErrorUm => g.following_error_um,
        ParamId::DpGainLsbPerKn => g.dp_gain_lsb_per_kn,
        ParamId::DpCornerHz => g.dp_corner_hz,
        ParamId::AreaAMm2 => a.areas.area_a_mm2,
        ParamId::AreaBMm2 => a.areas.area_b_mm2,
        ParamId::OscBandUm => g.osc_band_um,
        ParamId::FfTrimTauS => g.ff_trim_tau_s,
        ParamId::ValveNullLsb => v.null_lsb,
        ParamId::ValveOverlapPosLsb => v.overlap_pos_lsb,
        ParamId::ValveOverlapNegLsb => v.overlap_neg_lsb,
        ParamId::ValveOverlapZoneLsb => v.overlap_zone_lsb,
        ParamId::ValveGainPos => v.gain_pos,
        ParamId::ValveGainNeg => v.gain_neg,
        ParamId::ValveInvert => f32::from(u8::from(v.invert)),
        ParamId::ValveClampLsb => f32::from(v.clamp_lsb),
        ParamId::MinUm => l.min_um.to_num(),
        ParamId::MaxUm => l.max_um.to_num(),
        ParamId::MaxSpeedUmPerS => l.max_speed_um_per_s.to_num(),
        _ => match param.backoff_field() {
            Some(f) => g.backoff.get(f),
            None => return Err(unknown),
        },
    })
}

/// The parameter an axis configuration error names.
fn axis_error_param(e: AxisConfigError) -> ParamId {
    use crate::axis::DampingError as D;
    use crate::valve::ValveCalError as V;
    match e {
        AxisConfigError::Kp | AxisConfigError::Period => ParamId::KpLsbPerUm,
        AxisConfigError::Ki => ParamId::KiLsbPerUmS,
        AxisConfigError::Kd => ParamId::KdLsbSPerUm,
        AxisConfigError::IZone => ParamId::IZoneUm,
        AxisConfigError::ILimit => ParamId::ILimitLsb,
        AxisConfigError::Kv => ParamId::KvPosLsbPerUmS,
        AxisConfigError::Ka => ParamId::KaLsbPerUmS2,
        AxisConfigError::ValveLag => ParamId::ValveLagUs,
        AxisConfigError::FollowingError => ParamId::FollowingErrorUm,
        AxisConfigError::Valve(V::Null) => ParamId::ValveNullLsb,
        AxisConfigError::Valve(V::Overlap) => ParamId::ValveOverlapPosLsb,
        AxisConfigError::Valve(V::OverlapZone) => ParamId::ValveOverlapZoneLsb,
        AxisConfigError::Valve(V::Gain) => ParamId::ValveGainPos,
        AxisConfigError::Valve(V::Clamp) => ParamId::ValveClampLsb,
        AxisConfigError::OscBand(crate::axis::BandError::Setting(f)) => {
            ParamId::of_backoff_field(f)
        }
        AxisConfigError::OscBand(_) => ParamId::OscBandUm,
        AxisConfigError::FfTrim(_) => ParamId::FfTrimTauS,
        AxisConfigError::Damping(D::Gain) => ParamId::DpGainLsbPerKn,
        AxisConfigError::Damping(D::Corner) => ParamId::DpCornerHz,
        AxisConfigError::Damping(D::Area) => ParamId::AreaAMm2,
        AxisConfigError::Damping(D::Law) => ParamId::DpGainLsbPerKn,
    }
}

/// Validates a configuration as a whole: the master top speed positive; per axis min <
/// max and a positive top speed, and the axis' own builder at the follower's period; the
/// `active` table against the limits. `set`: the parameter just set (named in the error;
/// `None` for a set of them: the error then names the axis and the first field at fault).
pub fn validate_params<const S: usize, const N: usize>(
    cfg: &FollowerConfig<S>,
    lim: &TableLimits<S>,
    active: Option<&CamTable<S, N>>,
    set: Option<(u8, ParamId)>,
) -> Result<(), Nak> {
    let nak = |axis: usize, field: ParamId| {
        let (a, p) = set.unwrap_or((u8::try_from(axis).unwrap_or(u8::MAX), field));
        Nak::with(NakCode::ParamRange, u16::from(a), p as u8)
    };
    if lim.master_speed_per_s <= MasterRate::ZERO {
        return Err(nak(0, ParamId::MasterSpeedPerS));
    }
    if cfg.master_filter.build(cfg.period_us).is_err() {
        return Err(nak(0, ParamId::MasterFilterHz));
    }
    for (i, (a, l)) in cfg.axes.iter().zip(lim.axes.iter()).enumerate() {
        if l.min_um >= l.max_um {
            return Err(nak(i, ParamId::MinUm));
        }
        if l.max_speed_um_per_s <= VelUmPerS::ZERO {
            return Err(nak(i, ParamId::MaxSpeedUmPerS));
        }
        if let Err(e) = a.build(cfg.period_us) {
            return Err(nak(i, axis_error_param(e)));
        }
    }
    if let Some(t) = active {
        t.check_limits(lim).map_err(|_| nak(0, ParamId::MinUm))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::AxisConfig;
    use crate::table::{AxisLimits, Node};
    use crate::units::Master;

    const NONE: Option<&CamTable<1, 8>> = None;

    fn setup() -> (FollowerConfig<1>, TableLimits<1>) {
        let lim = TableLimits {
            master_speed_per_s: MasterRate::from_num(3000),
            axes: [AxisLimits {
                min_um: PosUm::ZERO,
                max_um: PosUm::from_num(500_000),
                max_speed_um_per_s: VelUmPerS::from_num(100_000),
            }],
        };
        (FollowerConfig::default(), lim)
    }

    #[test]
    fn applies_and_validates() {
        let (mut c, mut l) = setup();
        apply_param(&mut c, &mut l, NONE, 0, ParamId::KpLsbPerUm, 0.5).unwrap();
        assert_eq!(c.axes[0].gains.kp_lsb_per_um, 0.5);
        apply_param(&mut c, &mut l, NONE, 0, ParamId::KvNegLsbPerUmS, 0.02).unwrap();
        assert_eq!(c.axes[0].gains.kv_neg_lsb_per_um_s, 0.02);
        apply_param(&mut c, &mut l, NONE, 0, ParamId::MasterSpeedPerS, 5000.0).unwrap();
        assert_eq!(l.master_speed_per_s, MasterRate::from_num(5000));
        let range = Nak::with(NakCode::ParamRange, 0, ParamId::KpLsbPerUm as u8);
        assert_eq!(
            apply_param(&mut c, &mut l, NONE, 0, ParamId::KpLsbPerUm, -1.0),
            Err(range)
        );
        let range = Nak::with(NakCode::ParamRange, 0, ParamId::MinUm as u8);
        assert_eq!(
            apply_param(&mut c, &mut l, NONE, 0, ParamId::MinUm, 600_000.0),
            Err(range)
        );
        let unknown = Nak::with(NakCode::UnknownParam, 3, ParamId::KpLsbPerUm as u8);
        assert_eq!(
            apply_param(&mut c, &mut l, NONE, 3, ParamId::KpLsbPerUm, 1.0),
            Err(unknown)
        );
        assert_eq!(AxisConfig::default().valve, c.axes[0].valve);
    }

    #[test]
    fn a_damping_gain_without_areas_is_refused_naming_the_area() {
        let (mut c, mut l) = setup();
        let nak = Nak::with(NakCode::ParamRange, 0, ParamId::DpGainLsbPerKn as u8);
        assert_eq!(
            apply_param(&mut c, &mut l, NONE, 0, ParamId::DpGainLsbPerKn, 16.0),
            Err(nak),
            "the default configuration has no piston areas"
        );
        // apply_param works on copies (the caller keeps them only on Ok).
        c.axes[0].gains.dp_gain_lsb_per_kn = 0.0;
        apply_param(&mut c, &mut l, NONE, 0, ParamId::AreaAMm2, 5026.5).unwrap();
        apply_param(&mut c, &mut l, NONE, 0, ParamId::DpGainLsbPerKn, 16.0).unwrap();
        assert!(c.axes[0].build(c.period_us).unwrap().damping.is_on());
        assert_eq!(read_param(&c, &l, 0, ParamId::DpGainLsbPerKn), Ok(16.0));
        // A set validated as a whole names the field at fault.
        c.axes[0].areas.area_a_mm2 = 0.0;
        assert_eq!(
            validate_params(&c, &l, NONE, None),
            Err(Nak::with(NakCode::ParamRange, 0, ParamId::AreaAMm2 as u8))
        );
    }

    #[test]
    fn a_limit_the_active_table_would_violate_is_refused() {
        let (mut c, mut l) = setup();
        // 0 → 100 mm over 1000 master counts (100 µm/count): at a 500 counts/s master
        // top speed that is 50 mm/s, within the axis top speed of 100 mm/s.
        l.master_speed_per_s = MasterRate::from_num(500);
        let nodes = [0, 1000].map(|m| Node {
            master: Master::from_num(m),
            slave_um: [PosUm::from_num(m * 100)],
        });
        let t = CamTable::<1, 8>::try_from_nodes(&nodes, &l).unwrap();
        let active = Some(&t);
        // Within: accepted.
        apply_param(&mut c, &mut l, active, 0, ParamId::MaxUm, 150_000.0).unwrap();
        // The table reaches 100 mm: a 90 mm maximum is refused, the limits stay.
        let (c0, l0) = (c, l);
        let range = Nak::with(NakCode::ParamRange, 0, ParamId::MaxUm as u8);
        let (mut c1, mut l1) = (c0, l0);
        assert_eq!(
            apply_param(&mut c1, &mut l1, active, 0, ParamId::MaxUm, 90_000.0),
            Err(range)
        );
        // Its slope is 100 µm/count · 500 counts/s = 50 mm/s: a 40 mm/s top speed, or a
        // master at 1500 counts/s (150 mm/s > 100 mm/s), is refused.
        let speed = Nak::with(NakCode::ParamRange, 0, ParamId::MaxSpeedUmPerS as u8);
        let (mut c1, mut l1) = (c0, l0);
        assert_eq!(
            apply_param(
                &mut c1,
                &mut l1,
                active,
                0,
                ParamId::MaxSpeedUmPerS,
                40_000.0
            ),
            Err(speed)
        );
        let master = Nak::with(NakCode::ParamRange, 0, ParamId::MasterSpeedPerS as u8);
        let (mut c1, mut l1) = (c0, l0);
        assert_eq!(
            apply_param(
                &mut c1,
                &mut l1,
                active,
                0,
                ParamId::MasterSpeedPerS,
                1500.0
            ),
            Err(master)
        );
        // Without an active table the same value is accepted.
        let (mut c1, mut l1) = (c0, l0);
        apply_param(&mut c1, &mut l1, NONE, 0, ParamId::MaxUm, 90_000.0).unwrap();
    }

    /// Min 100 mm, max 700 mm, then min 550 mm (replacing the first
    /// record in place): one by one against the boot max of 500 mm the min fails; as a
    /// set the limits are [550, 700] mm. A set invalid as a whole changes nothing.
    #[test]
    fn a_set_is_validated_as_a_whole_not_in_record_order() {
        use crate::protocol::ParamRecord;
        let (c0, l0) = setup();
        let rec = |param, value| ParamRecord {
            axis: 0,
            param,
            value,
        };
        let set = [
            rec(ParamId::MinUm, 550_000.0),
            rec(ParamId::MaxUm, 700_000.0),
            rec(ParamId::LinkTimeoutMs, 100.0),
        ];
        let (mut c, mut l) = (c0, l0);
        // One by one, the first record is refused against the boot max.
        assert!(apply_param(&mut c, &mut l, NONE, 0, ParamId::MinUm, 550_000.0).is_err());
        let (mut c, mut l) = (c0, l0);
        apply_param_set(&mut c, &mut l, NONE, &set).unwrap();
        assert_eq!(l.axes[0].min_um, PosUm::from_num(550_000));
        assert_eq!(l.axes[0].max_um, PosUm::from_num(700_000));
        let bad = [
            rec(ParamId::MinUm, 800_000.0),
            rec(ParamId::MaxUm, 700_000.0),
        ];
        let (mut c, mut l) = (c0, l0);
        assert_eq!(
            apply_param_set(&mut c, &mut l, NONE, &bad),
            Err(Nak::with(NakCode::ParamRange, 0, ParamId::MinUm as u8))
        );
    }
}
