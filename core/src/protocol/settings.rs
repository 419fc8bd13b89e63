//! The settings tree: every parameter a board holds, by path, with its unit and range.
//!
//! A path is made of the field names core and the scenario files use:
//! `axis/<n>/<gain>` for the position loop ([`crate::axis::PositionGains`]),
//! `axis/<n>/valve/<field>` for the valve calibration ([`crate::valve::ValveCal`]),
//! `axis/<n>/cylinder/area_a_mm2` and `area_b_mm2` for the piston areas the active damping
//! needs ([`crate::axis::PistonAreas`]),
//! `axis/<n>/limits/<field>` for the table limits ([`crate::table::AxisLimits`]),
//! `axis/<n>/reference_offset_um` for an absolute slave's reference,
//! `axis/<n>/reference/home_um` for where homing references it,
//! `axis/<n>/encoder/um_per_count` for its encoder's scale, and board-wide
//! `limits/master_speed_per_s`, `master/filter_bandwidth_hz`, `link/timeout_ms` and
//! `period_us`. `<n>` is the 0-based slave.
//!
//! On the wire and on flash a parameter is its stable [`ParamId`] byte and an `f32` value
//! in the unit named (a boolean is 0 or 1, a count an integer): the id of a path never
//! changes when parameters are added, so a saved setting keeps its meaning across
//! firmware versions, and a record is 6 bytes. (`miniconf` — stabilizer's settings
//! tree — keys a leaf by its position in the tree, which moves when a field is added,
//! or by its path string, 20–35 bytes here; and its leaves are struct fields, while a
//! board validates the settings as one set together with the tables, see
//! [`super::params::validate_params`]. This table is the one description of the tree
//! for the board, the host and the documentation.)
//!
//! The range here is what SetParam accepts for the value alone; the set as a whole is
//! then validated (`min_um < max_um`, the axis' law at the board's period, the master
//! filter below 0.2/T, the active table within the limits).

use super::msg::{Nak, NakCode};
use crate::axis::BackoffField;
use core::fmt;

/// Settable parameters (`SetParam.param`, `GetParam.param`). Values are `f32` in the
/// unit of [`ParamId::info`]; the byte is stable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ParamId {
    /// Proportional gain, DAC LSB per µm.
    KpLsbPerUm = 1,
    /// Integral gain, DAC LSB per (µm·s).
    KiLsbPerUmS = 2,
    /// Derivative gain, DAC LSB per (µm/s).
    KdLsbSPerUm = 3,
    /// Velocity feed-forward for both directions, LSB per (µm/s): sets the extending and
    /// the retracting one (reads the extending one). Its meaning since version 1; the
    /// handler records it as the two ([`ParamId::KvPosLsbPerUmS`],
    /// [`ParamId::KvNegLsbPerUmS`]), so a saved set replays in any order.
    KvLsbPerUmS = 4,
    /// Acceleration feed-forward, LSB per (µm/s²).
    KaLsbPerUmS2 = 5,
    /// Following-error fault limit, µm.
    FollowingErrorUm = 6,
    /// Table validation: lowest position, µm.
    MinUm = 7,
    /// Table validation: highest position, µm.
    MaxUm = 8,
    /// Table validation: axis top speed, µm/s.
    MaxSpeedUmPerS = 9,
    /// Table validation: fastest master speed, master counts/s (axis byte ignored).
    MasterSpeedPerS = 10,
    /// Valve calibration: null offset, DAC LSB.
    ValveNullLsb = 11,
    /// Host-link watchdog, ms (axis byte ignored): while following after a Start from
    /// the link, no valid frame for this long holds the axes. 0 = off (the default; 10 …
    /// 60 000 otherwise). Kept by the protocol handler, not the device.
    LinkTimeoutMs = 12,
    /// Reference offset of an absolute slave, µm (|x| ≤ 8 000 000): written by the
    /// handler when a set-position on an absolute axis succeeds, so Save persists it and
    /// boot restores it (`runtime::reference`). Read-only for SetParam.
    SlaveOffsetUm = 13,
    /// Velocity feed-forward for retracting (negative) target speed, LSB per (µm/s).
    KvNegLsbPerUmS = 14,
    /// Integral separation zone, µm.
    IZoneUm = 15,
    /// Integrator clamp, DAC LSB.
    ILimitLsb = 16,
    /// Valve response delay the feed-forward is aimed at, µs.
    ValveLagUs = 17,
    /// Valve calibration: deadband compensation for positive commands, LSB.
    ValveOverlapPosLsb = 18,
    /// Valve calibration: deadband compensation for negative commands, LSB.
    ValveOverlapNegLsb = 19,
    /// Valve calibration: width of the linear zone around zero, LSB.
    ValveOverlapZoneLsb = 20,
    /// Valve calibration: gain for positive commands (ratio).
    ValveGainPos = 21,
    /// Valve calibration: gain for negative commands (ratio).
    ValveGainNeg = 22,
    /// Valve calibration: 1 if a positive code retracts the axis, else 0.
    ValveInvert = 23,
    /// Valve calibration: largest |code| ever output, LSB (integer).
    ValveClampLsb = 24,
    /// Master tracking filter bandwidth, Hz (axis byte ignored).
    MasterFilterHz = 25,
    /// The control period, µs (axis byte ignored; read-only: the firmware's tick).
    PeriodUs = 26,
    /// Velocity feed-forward for extending (positive) target speed, LSB per (µm/s).
    KvPosLsbPerUmS = 27,
    /// Active damping gain, LSB per kN of high-passed hydraulic force (0 = off).
    DpGainLsbPerKn = 28,
    /// Active damping high-pass corner, Hz.
    DpCornerHz = 29,
    /// Piston area of chamber A (pressure input 2n), mm².
    AreaAMm2 = 30,
    /// Piston area of chamber B (pressure input 2n + 1), mm².
    AreaBMm2 = 31,
    /// Gain backoff band, µm (0 = off): the high-passed following error crossing it
    /// back and forth four times in 150 ms takes the proportional gain (from the second
    /// time also the integral gain) down.
    OscBandUm = 32,
    /// Feed-forward trim time constant, s (0 = off): while the axis moves, the
    /// integrator's content moves with this time constant into a per-direction ratio of
    /// the velocity feed-forward (the valve's real flow gain, learned).
    FfTrimTauS = 33,
    /// Where homing references the slave: its position at the reference edge (index or
    /// switch), µm. Takes effect at the next `motion home`.
    HomeUm = 34,
    /// The slave encoder's scale, µm per count (0.001 ≤ |x| ≤ 1000; negative reverses
    /// the count). Idle or Fault only; an incremental slave must be referenced again.
    UmPerCount = 35,
    /// Gain backoff: the detector's high-pass corner, Hz (`axis::BackoffSettings`).
    BackoffHighPassHz = 36,
    /// Gain backoff: half-cycles across the band that make an oscillation (integer).
    BackoffHalfCycles = 37,
    /// Gain backoff: the window the half-cycles must fall in, ms.
    BackoffWindowMs = 38,
    /// Gain backoff: the settling after a cut, ms.
    BackoffSettleMs = 39,
    /// Gain backoff: the raised band's decay time constant, ms.
    BackoffBandTauMs = 40,
    /// Gain backoff: the deepest level (integer).
    BackoffMaxLevel = 41,
    /// Gain backoff: the proportional scale at the first level, ratio.
    BackoffFirstScale = 42,
    /// Gain backoff: the scale's factor at each further level, ratio.
    BackoffStepScale = 43,
    /// Gain backoff: the raised band over the oscillation's peak, ratio.
    BackoffBandMargin = 44,
    /// Gain backoff: the growth a half-cycle must show over the last, ratio.
    BackoffGrowth = 45,
    /// Gain backoff: growing half-cycles in a row that take the next level (integer).
    BackoffGrowthHalfCycles = 46,
    /// The PLC link (Modbus) answers requests: 1 on, 0 off (the default). Kept by the
    /// protocol handler ([`crate::plc::PlcSettings`]).
    PlcEnable = 47,
    /// The PLC's heartbeat time, ms: while the PLC owns the machine and it moves, the
    /// `heartbeat` register unchanged for this long holds the axes. 0 = off, else
    /// 50 … 60 000; 1 000 by default.
    PlcHeartbeatMs = 48,
    /// The in-position window of a slave, µm: |following error| within it sets the
    /// slave's `in_position` bit. 100 by default.
    InPositionUm = 49,
    /// The board's Modbus unit id (RTU slave address; a TCP request's unit id must be it
    /// or 255), 1 … 247; 1 by default.
    PlcUnitId = 50,
    /// First allowed Modbus TCP client: the address' first two octets as a·256 + b
    /// (0 … 65 535). An entry of 0.0.0.0 is empty; with every entry empty any client
    /// may connect.
    PlcAllow0High = 51,
    /// First allowed Modbus TCP client: the last two octets as c·256 + d.
    PlcAllow0Low = 52,
    /// Second allowed Modbus TCP client: the first two octets as a·256 + b.
    PlcAllow1High = 53,
    /// Second allowed Modbus TCP client: the last two octets as c·256 + d.
    PlcAllow1Low = 54,
}

/// Whether a parameter belongs to each slave or to the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// One value per slave: `axis/<n>/…`.
    Axis,
    /// One value for the board (the axis byte is ignored and sent as 0).
    Board,
}

/// One parameter of the tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamInfo {
    /// Its id.
    pub id: ParamId,
    /// Per slave or board-wide.
    pub scope: Scope,
    /// The path after `axis/<n>/` (per slave) or the whole path (board-wide).
    pub path: &'static str,
    /// Unit of the value.
    pub unit: &'static str,
    /// Smallest value accepted (inclusive).
    pub min: f32,
    /// Largest value accepted (inclusive).
    pub max: f32,
    /// Only integers are accepted (booleans are 0 or 1).
    pub integer: bool,
    /// SetParam refuses it ([`NakCode::ReadOnly`]): the board sets it itself.
    pub read_only: bool,
}

const fn p(
    id: ParamId,
    scope: Scope,
    path: &'static str,
    unit: &'static str,
    min: f32,
    max: f32,
) -> ParamInfo {
    ParamInfo {
        id,
        scope,
        path,
        unit,
        min,
        max,
        integer: false,
        read_only: false,
    }
}

const fn int(i: ParamInfo) -> ParamInfo {
    ParamInfo { integer: true, ..i }
}

const fn ro(i: ParamInfo) -> ParamInfo {
    ParamInfo {
        read_only: true,
        ..i
    }
}

use ParamId as P;
use Scope::{Axis as A, Board as B};

/// Every parameter, in the order `param list` prints them (per-slave ones first). A
/// `static`, not a `const`: a `const` array would be copied onto the stack (1.2 KiB) at
/// every lookup.
pub static PARAMS: [ParamInfo; ParamId::COUNT] = [
    p(P::KpLsbPerUm, A, "kp_lsb_per_um", "LSB/µm", 0.0, 1000.0),
    p(P::KiLsbPerUmS, A, "ki_lsb_per_um_s", "LSB/(µm·s)", 0.0, 1e5),
    p(P::KdLsbSPerUm, A, "kd_lsb_s_per_um", "LSB·s/µm", 0.0, 10.0),
    p(P::IZoneUm, A, "i_zone_um", "µm", 1e-3, 1e6),
    p(P::ILimitLsb, A, "i_limit_lsb", "LSB", 0.0, 2047.0),
    p(P::KvLsbPerUmS, A, "kv_lsb_per_um_s", "LSB·s/µm", 0.0, 100.0),
    p(
        P::KvPosLsbPerUmS,
        A,
        "kv_pos_lsb_per_um_s",
        "LSB·s/µm",
        0.0,
        100.0,
    ),
    p(
        P::KvNegLsbPerUmS,
        A,
        "kv_neg_lsb_per_um_s",
        "LSB·s/µm",
        0.0,
        100.0,
    ),
    p(
        P::KaLsbPerUmS2,
        A,
        "ka_lsb_per_um_s2",
        "LSB·s²/µm",
        0.0,
        0.4,
    ),
    p(P::ValveLagUs, A, "valve_lag_us", "µs", 0.0, 100_000.0),
    p(
        P::FollowingErrorUm,
        A,
        "following_error_um",
        "µm",
        1e-3,
        1e6,
    ),
    p(
        P::DpGainLsbPerKn,
        A,
        "dp_gain_lsb_per_kn",
        "LSB/kN",
        0.0,
        1000.0,
    ),
    p(P::DpCornerHz, A, "dp_corner_hz", "Hz", 0.1, 1000.0),
    p(P::InPositionUm, A, "in_position_um", "µm", 0.0, 1e6),
    p(P::AreaAMm2, A, "cylinder/area_a_mm2", "mm²", 0.0, 1e6),
    p(P::AreaBMm2, A, "cylinder/area_b_mm2", "mm²", 0.0, 1e6),
    p(P::OscBandUm, A, "osc_band_um", "µm", 0.0, 10_000.0),
    p(P::FfTrimTauS, A, "ff_trim_tau_s", "s", 0.0, 1000.0),
    p(
        P::BackoffHighPassHz,
        A,
        "backoff/high_pass_hz",
        "Hz",
        0.1,
        1000.0,
    ),
    int(p(
        P::BackoffHalfCycles,
        A,
        "backoff/half_cycles",
        "count",
        2.0,
        16.0,
    )),
    p(
        P::BackoffWindowMs,
        A,
        "backoff/window_ms",
        "ms",
        1.0,
        10_000.0,
    ),
    p(
        P::BackoffSettleMs,
        A,
        "backoff/settle_ms",
        "ms",
        0.0,
        10_000.0,
    ),
    p(
        P::BackoffBandTauMs,
        A,
        "backoff/band_tau_ms",
        "ms",
        1.0,
        100_000.0,
    ),
    int(p(
        P::BackoffMaxLevel,
        A,
        "backoff/max_level",
        "count",
        1.0,
        4.0,
    )),
    p(
        P::BackoffFirstScale,
        A,
        "backoff/first_scale",
        "ratio",
        0.05,
        1.0,
    ),
    p(
        P::BackoffStepScale,
        A,
        "backoff/step_scale",
        "ratio",
        0.05,
        1.0,
    ),
    p(
        P::BackoffBandMargin,
        A,
        "backoff/band_margin",
        "ratio",
        1.0,
        4.0,
    ),
    p(P::BackoffGrowth, A, "backoff/growth", "ratio", 0.0, 1.0),
    int(p(
        P::BackoffGrowthHalfCycles,
        A,
        "backoff/growth_half_cycles",
        "count",
        1.0,
        16.0,
    )),
    p(P::ValveNullLsb, A, "valve/null_lsb", "LSB", -500.0, 500.0),
    p(
        P::ValveOverlapPosLsb,
        A,
        "valve/overlap_pos_lsb",
        "LSB",
        0.0,
        1000.0,
    ),
    p(
        P::ValveOverlapNegLsb,
        A,
        "valve/overlap_neg_lsb",
        "LSB",
        0.0,
        1000.0,
    ),
    p(
        P::ValveOverlapZoneLsb,
        A,
        "valve/overlap_zone_lsb",
        "LSB",
        1e-3,
        1000.0,
    ),
    p(P::ValveGainPos, A, "valve/gain_pos", "ratio", 0.1, 10.0),
    p(P::ValveGainNeg, A, "valve/gain_neg", "ratio", 0.1, 10.0),
    int(p(P::ValveInvert, A, "valve/invert", "bool", 0.0, 1.0)),
    int(p(
        P::ValveClampLsb,
        A,
        "valve/clamp_lsb",
        "LSB",
        1.0,
        2047.0,
    )),
    p(P::MinUm, A, "limits/min_um", "µm", -8.0e6, 8.0e6),
    p(P::MaxUm, A, "limits/max_um", "µm", -8.0e6, 8.0e6),
    p(
        P::MaxSpeedUmPerS,
        A,
        "limits/max_speed_um_per_s",
        "µm/s",
        1e-3,
        8.0e6,
    ),
    ro(p(
        P::SlaveOffsetUm,
        A,
        "reference_offset_um",
        "µm",
        -8.0e6,
        8.0e6,
    )),
    p(P::HomeUm, A, "reference/home_um", "µm", -8.0e6, 8.0e6),
    p(
        P::UmPerCount,
        A,
        "encoder/um_per_count",
        "µm/count",
        -1000.0,
        1000.0,
    ),
    p(
        P::MasterSpeedPerS,
        B,
        "limits/master_speed_per_s",
        "counts/s",
        1e-3,
        1e9,
    ),
    p(
        P::MasterFilterHz,
        B,
        "master/filter_bandwidth_hz",
        "Hz",
        0.1,
        4000.0,
    ),
    int(p(
        P::LinkTimeoutMs,
        B,
        "link/timeout_ms",
        "ms",
        0.0,
        60_000.0,
    )),
    ro(int(p(P::PeriodUs, B, "period_us", "µs", 50.0, 1e6))),
    int(p(P::PlcEnable, B, "plc/enable", "bool", 0.0, 1.0)),
    int(p(
        P::PlcHeartbeatMs,
        B,
        "plc/heartbeat_ms",
        "ms",
        0.0,
        60_000.0,
    )),
    int(p(P::PlcUnitId, B, "plc/unit_id", "id", 1.0, 247.0)),
    int(p(
        P::PlcAllow0High,
        B,
        "plc/allow/0/high",
        "a·256+b",
        0.0,
        65_535.0,
    )),
    int(p(
        P::PlcAllow0Low,
        B,
        "plc/allow/0/low",
        "c·256+d",
        0.0,
        65_535.0,
    )),
    int(p(
        P::PlcAllow1High,
        B,
        "plc/allow/1/high",
        "a·256+b",
        0.0,
        65_535.0,
    )),
    int(p(
        P::PlcAllow1Low,
        B,
        "plc/allow/1/low",
        "c·256+d",
        0.0,
        65_535.0,
    )),
];

impl ParamId {
    /// Number of parameter ids.
    pub const COUNT: usize = 54;

    /// Held by the protocol handler, not the device: the host-link watchdog and the PLC
    /// link's settings ([`crate::plc::PlcSettings`]). The device neither sets nor reads
    /// them, and a saved set passes them to the handler.
    pub const fn held_by_handler(self) -> bool {
        matches!(
            self,
            P::LinkTimeoutMs
                | P::PlcEnable
                | P::PlcHeartbeatMs
                | P::InPositionUm
                | P::PlcUnitId
                | P::PlcAllow0High
                | P::PlcAllow0Low
                | P::PlcAllow1High
                | P::PlcAllow1Low
        )
    }

    /// The gain backoff threshold this parameter sets, if it is one.
    pub fn backoff_field(self) -> Option<BackoffField> {
        use BackoffField as F;
        Some(match self {
            P::BackoffHighPassHz => F::HighPassHz,
            P::BackoffHalfCycles => F::HalfCycles,
            P::BackoffWindowMs => F::WindowMs,
            P::BackoffSettleMs => F::SettleMs,
            P::BackoffBandTauMs => F::BandTauMs,
            P::BackoffMaxLevel => F::MaxLevel,
            P::BackoffFirstScale => F::FirstScale,
            P::BackoffStepScale => F::StepScale,
            P::BackoffBandMargin => F::BandMargin,
            P::BackoffGrowth => F::Growth,
            P::BackoffGrowthHalfCycles => F::GrowthHalfCycles,
            _ => return None,
        })
    }

    /// The parameter that sets the gain backoff threshold `f`.
    pub fn of_backoff_field(f: BackoffField) -> Self {
        PARAMS
            .iter()
            .map(|i| i.id)
            .find(|id| id.backoff_field() == Some(f))
            .unwrap_or(P::OscBandUm)
    }

    /// From the wire byte.
    pub fn from_u8(b: u8) -> Option<Self> {
        PARAMS.iter().map(|i| i.id).find(|c| *c as u8 == b)
    }

    /// Its path, unit and range.
    pub fn info(self) -> &'static ParamInfo {
        // Every id is in PARAMS (a unit test checks it); the fallback is never taken.
        const FALLBACK: &ParamInfo = &ro(p(P::PeriodUs, B, "period_us", "µs", 50.0, 1e6));
        PARAMS.iter().find(|i| i.id == self).unwrap_or(FALLBACK)
    }

    /// Checks `value` against the range alone: finite, within `min … max`, an integer
    /// where one is needed. Error: `ParamRange` naming `axis` and the parameter.
    pub fn check(self, axis: u8, value: f32) -> Result<f32, Nak> {
        let i = self.info();
        let whole = !i.integer || value == libm::roundf(value);
        if value.is_finite() && value >= i.min && value <= i.max && whole {
            Ok(value)
        } else {
            Err(Nak::with(NakCode::ParamRange, u16::from(axis), self as u8))
        }
    }
}

/// Why a path names no parameter of this board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathError {
    /// No parameter has this name.
    Unknown,
    /// `axis/<n>/…` with `<n>` not a slave of the board (the board's slave count).
    NoAxis(u8),
}

impl fmt::Display for PathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PathError::Unknown => f.write_str("no parameter has this path"),
            PathError::NoAxis(n) => write!(
                f,
                "the board has {n} slave(s): axis/0 … axis/{}",
                n.saturating_sub(1)
            ),
        }
    }
}

impl core::error::Error for PathError {}

/// The parameter and slave a path names on a board of `axes` slaves (board-wide
/// parameters: slave 0).
pub fn parse_path(path: &str, axes: u8) -> Result<(u8, ParamId), PathError> {
    let path = path.trim_matches('/');
    if let Some(rest) = path.strip_prefix("axis/") {
        let (n, name) = rest.split_once('/').ok_or(PathError::Unknown)?;
        let n: u8 = n.parse().map_err(|_| PathError::Unknown)?;
        let i = PARAMS
            .iter()
            .find(|i| i.scope == Scope::Axis && i.path == name)
            .ok_or(PathError::Unknown)?;
        if n >= axes {
            return Err(PathError::NoAxis(axes));
        }
        return Ok((n, i.id));
    }
    PARAMS
        .iter()
        .find(|i| i.scope == Scope::Board && i.path == path)
        .map(|i| (0, i.id))
        .ok_or(PathError::Unknown)
}

/// A parameter's path on slave `axis` (`Display`: `axis/1/valve/null_lsb`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamPath {
    /// The parameter.
    pub id: ParamId,
    /// The slave (ignored for a board-wide parameter).
    pub axis: u8,
}

impl fmt::Display for ParamPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let i = self.id.info();
        match i.scope {
            Scope::Axis => write!(f, "axis/{}/{}", self.axis, i.path),
            Scope::Board => f.write_str(i.path),
        }
    }
}

/// Every `(axis, parameter)` of a board of `axes` slaves: slave 0's parameters in
/// [`PARAMS`] order, then slave 1's, …, then the board-wide ones.
pub fn all_paths(axes: u8) -> impl Iterator<Item = ParamPath> {
    let of = |scope| PARAMS.iter().filter(move |i| i.scope == scope);
    let per_axis =
        (0..axes).flat_map(move |axis| of(Scope::Axis).map(move |i| ParamPath { id: i.id, axis }));
    per_axis.chain(of(Scope::Board).map(|i| ParamPath { id: i.id, axis: 0 }))
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn every_id_is_described_once_and_its_path_parses_back() {
        for b in 0..=u8::MAX {
            let n = PARAMS.iter().filter(|i| i.id as u8 == b).count();
            assert!(n <= 1, "id {b} described {n} times");
            if let Some(id) = ParamId::from_u8(b) {
                assert_eq!(id.info().id, id);
            }
        }
        assert_eq!(all_paths(2).count(), 43 * 2 + 11);
        for pp in all_paths(3) {
            let s = pp.to_string();
            let (axis, id) = parse_path(&s, 3).unwrap();
            assert_eq!(id, pp.id, "{s}");
            if pp.id.info().scope == Scope::Axis {
                assert_eq!(axis, pp.axis, "{s}");
            }
            assert!(parse_path(&s.to_uppercase(), 3).is_err() || !s.contains('_'));
        }
        let mut paths: std::vec::Vec<_> = all_paths(2).map(|p| p.to_string()).collect();
        paths.sort();
        paths.dedup();
        assert_eq!(paths.len(), 97, "two parameters share a path");
    }

    /// The tree's range of each backoff threshold is the one the axis build enforces.
    #[test]
    fn backoff_ranges_are_the_axis_ones() {
        for (f, lo, hi, integer) in crate::axis::BackoffSettings::RANGES {
            let id = ParamId::of_backoff_field(f);
            assert_eq!(id.backoff_field(), Some(f));
            let i = id.info();
            assert_eq!((i.min, i.max, i.integer), (lo, hi, integer), "{f:?}");
        }
    }

    #[test]
    fn a_bad_path_is_named_as_such() {
        assert_eq!(
            parse_path("axis/0/kp_lsb_per_um", 2),
            Ok((0, ParamId::KpLsbPerUm))
        );
        assert_eq!(
            parse_path("/limits/master_speed_per_s", 2),
            Ok((0, ParamId::MasterSpeedPerS))
        );
        assert_eq!(
            parse_path("axis/2/kp_lsb_per_um", 2),
            Err(PathError::NoAxis(2))
        );
        assert_eq!(
            parse_path("axis/x/kp_lsb_per_um", 2),
            Err(PathError::Unknown)
        );
        assert_eq!(parse_path("axis/0/kp", 2), Err(PathError::Unknown));
        assert_eq!(parse_path("kp_lsb_per_um", 2), Err(PathError::Unknown));
        assert_eq!(parse_path("axis/0", 2), Err(PathError::Unknown));
        assert_eq!(parse_path("", 2), Err(PathError::Unknown));
        assert_eq!(parse_path("axis/0/period_us", 2), Err(PathError::Unknown));
    }

    #[test]
    fn values_are_checked_against_the_range_alone() {
        let k = ParamId::KpLsbPerUm;
        assert_eq!(k.check(1, 1000.0), Ok(1000.0));
        let e = Err(Nak::with(NakCode::ParamRange, 1, k as u8));
        assert_eq!(k.check(1, 1000.1), e);
        assert_eq!(k.check(1, -0.0001), e);
        assert_eq!(k.check(1, f32::NAN), e);
        assert_eq!(k.check(1, f32::INFINITY), e);
        let c = ParamId::ValveClampLsb;
        assert!(c.check(0, 2047.0).is_ok());
        assert!(c.check(0, 2046.5).is_err());
        assert!(c.check(0, 0.0).is_err());
        assert!(ParamId::ValveInvert.check(0, 0.5).is_err());
        assert!(ParamId::ValveInvert.check(0, 1.0).is_ok());
    }

    /// The ranges here are the builders' own: each bound is accepted by the struct's
    /// validation and a value just outside it refused (so this table cannot drift from
    /// the code that enforces it).
    #[test]
    fn the_ranges_are_the_builders_ranges() {
        use crate::axis::AxisConfig;
        use crate::master::MasterFilterConfig;
        let gains = [
            P::KpLsbPerUm,
            P::KiLsbPerUmS,
            P::KdLsbSPerUm,
            P::IZoneUm,
            P::ILimitLsb,
            P::KvLsbPerUmS,
            P::KvPosLsbPerUmS,
            P::KvNegLsbPerUmS,
            P::KaLsbPerUmS2,
            P::ValveLagUs,
            P::FollowingErrorUm,
            P::ValveNullLsb,
            P::ValveOverlapPosLsb,
            P::ValveOverlapNegLsb,
            P::ValveOverlapZoneLsb,
            P::ValveGainPos,
            P::ValveGainNeg,
            P::ValveClampLsb,
            P::DpGainLsbPerKn,
            P::DpCornerHz,
            P::AreaAMm2,
            P::AreaBMm2,
            P::OscBandUm,
            P::FfTrimTauS,
        ];
        for id in gains {
            let i = id.info();
            for (v, ok) in [
                (i.min, true),
                (i.max, true),
                (i.min - i.min.abs().max(1e-3) * 0.01, false),
                (i.max + i.max.abs() * 0.01, false),
            ] {
                // The damping's gain needs an area to act on.
                let mut a = AxisConfig {
                    areas: crate::profile::piston_areas(),
                    ..AxisConfig::default()
                };
                if id == P::ValveClampLsb {
                    a.valve.clamp_lsb = v as u16;
                    if !ok && v < 1.0 {
                        a.valve.clamp_lsb = 0;
                    }
                } else {
                    assert!(super::super::params::assign_axis(&mut a, id, v));
                }
                // Ki at its top needs a narrow zone to stay inside the integrator format.
                if id == P::KiLsbPerUmS {
                    a.gains.i_zone_um = 1.0;
                }
                assert_eq!(a.build(1000).is_ok(), ok, "{} = {v}", i.path);
            }
        }
        let f = P::MasterFilterHz.info();
        assert!(MasterFilterConfig {
            bandwidth_hz: f.min
        }
        .build(50)
        .is_ok());
        assert!(MasterFilterConfig {
            bandwidth_hz: f.max
        }
        .build(50)
        .is_ok());
        assert!(MasterFilterConfig {
            bandwidth_hz: f.max * 1.01
        }
        .build(50)
        .is_err());
        assert!(MasterFilterConfig { bandwidth_hz: 0.09 }.build(50).is_err());
    }
}
