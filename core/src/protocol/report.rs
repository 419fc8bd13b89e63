//! The runtime's [`Status`] as the protocol reports it: one mapping for every
//! [`super::Device`] (the firmware and the host's virtual board).

use super::handler::Motion;
use super::msg::{
    motion_reason, AxisStatus, Nak, NakCode, StatusMsg, FLAG_PRESSURE_STALE, FLAG_UNREFERENCED,
    INPUT_ESTOP, INPUT_VALVE_POWER,
};
use crate::runtime::{Command, CommandError, Fault, MotionError, RefState, State, Status};
use crate::table::TableLimits;
use crate::units::PosUm;

/// `Refused` detail: the device's law cannot be built from the table with the present
/// parameters.
pub const REFUSED_LAW: u16 = 0;
/// `Refused` detail: the runtime was not at a safe point.
pub const REFUSED_NOT_SAFE: u16 = 1;

/// The runtime command of a protocol motion request; a manual motion takes the slave's
/// position limits from `limits` (a missing slave gets an empty range: the runtime
/// answers `NoAxis`). A speed above the slave's `max_speed_um_per_s` is refused here
/// ([`motion_reason::TOO_FAST`]).
pub fn motion_command<const S: usize>(m: Motion, limits: &TableLimits<S>) -> Result<Command, Nak> {
    let axis_limits = |axis: u8| limits.axes.get(usize::from(axis));
    let range =
        |axis: u8| axis_limits(axis).map_or((PosUm::ZERO, PosUm::ZERO), |a| (a.min_um, a.max_um));
    let speed_ok = |axis: u8, v: i64| {
        axis_limits(axis).is_none_or(|a| v <= i64::from(a.max_speed_um_per_s.to_num::<i32>()))
    };
    let too_fast = |axis: u8| Nak::with(NakCode::Motion, u16::from(axis), motion_reason::TOO_FAST);
    Ok(match m {
        Motion::Start => Command::Start,
        Motion::Stop => Command::Stop,
        Motion::Hold => Command::Hold,
        Motion::ClearFault => Command::ClearFault,
        Motion::SetPosition { axis, pos_um } => Command::SetPosition { axis, pos_um },
        Motion::Home { axis } => Command::Home { axis },
        Motion::Jog {
            axis,
            speed,
            limits,
        } => {
            if !speed_ok(axis, i64::from(speed.to_num::<i32>().saturating_abs())) {
                return Err(too_fast(axis));
            }
            Command::Jog {
                axis,
                speed,
                limits,
                range: range(axis),
            }
        }
        Motion::MoveTo { axis, to, limits } => {
            if !speed_ok(axis, i64::from(limits.vel_um_per_s)) {
                return Err(too_fast(axis));
            }
            Command::MoveTo {
                axis,
                to,
                limits,
                range: range(axis),
            }
        }
        Motion::Test { axis, spec } => Command::Test {
            axis,
            spec,
            range: range(axis),
            max_speed_um_per_s: axis_limits(axis).map_or(0, |a| {
                u32::try_from(a.max_speed_um_per_s.to_num::<i32>()).unwrap_or(0)
            }),
        },
        Motion::Approach { limits } => {
            if let Some(axis) = (0..S).find(|&i| {
                !speed_ok(
                    u8::try_from(i).unwrap_or(u8::MAX),
                    i64::from(limits.vel_um_per_s),
                )
            }) {
                return Err(too_fast(u8::try_from(axis).unwrap_or(u8::MAX)));
            }
            Command::Approach { limits }
        }
    })
}

/// The Nak of a command the runtime refused with `e` in state `state`: the typed codes
/// for a reference problem (naming the slave), else `BadState` with the state in
/// `detail` and the reason ([`refusal_reason`]) in `detail2`.
pub const fn command_nak(state: u8, e: CommandError) -> Nak {
    match e {
        CommandError::NotReferenced { axis } => Nak::with(NakCode::NotReferenced, axis as u16, 0),
        CommandError::NoAxis { axis } => Nak::with(NakCode::NoAxis, axis as u16, 0),
        CommandError::Motion { axis, error } => Nak::with(
            NakCode::Motion,
            axis as u16,
            match error {
                MotionError::Limits => motion_reason::LIMITS,
                MotionError::OutsideLimits => motion_reason::OUTSIDE_LIMITS,
                MotionError::Moving => motion_reason::MOVING,
                MotionError::Plan => motion_reason::PLAN,
                MotionError::TestSpec => motion_reason::TEST_SPEC,
                MotionError::TooFast => motion_reason::TOO_FAST,
                MotionError::TestStep => motion_reason::TEST_STEP,
            },
        ),
        _ => Nak::with(NakCode::BadState, state as u16, refusal_reason(e)),
    }
}

/// `detail2` of a `BadState` Nak: why the runtime refused (PROTOCOL.md). 0 = not said.
pub const fn refusal_reason(e: CommandError) -> u8 {
    match e {
        CommandError::NoController => 1,
        CommandError::Faulted => 2,
        CommandError::CauseActive(_) => 3,
        CommandError::MasterMoved => 4,
        CommandError::EndOfTable => 5,
        CommandError::Busy => 6,
        CommandError::NotReferenced { .. } => 7,
        CommandError::NoAxis { .. } => 8,
        CommandError::Motion { .. } => 9,
    }
}

/// The Nak of a motion request the runtime refused in state `state` ([`state_code`]).
pub const fn bad_state(state: u8) -> Nak {
    Nak::with(NakCode::BadState, state as u16, 0)
}

/// The Nak of a table the device refused (`detail`: [`REFUSED_LAW`] or
/// [`REFUSED_NOT_SAFE`]).
pub const fn refused(detail: u16) -> Nak {
    Nak::with(NakCode::Refused, detail, 0)
}

/// State byte of Status ([`State::code`]).
pub const fn state_code(s: State) -> u8 {
    s.code()
}

/// Fills the runtime's part of a Status (state, end-of-table flag, fault and its axis,
/// tick count and timing, master, per-axis fields); the handler fills the rest (table
/// ids, upload, session). `cycles_to_ns` converts the tick timing's CPU cycles to ns.
pub fn fill_status<const S: usize, const P: usize>(
    st: &Status<S, P>,
    cycles_to_ns: impl Fn(u32) -> u32,
    out: &mut StatusMsg,
) {
    out.state = state_code(st.state);
    out.flags = u8::from(matches!(
        st.state,
        State::Holding(crate::runtime::HoldReason::EndOfTable)
    ));
    if st.reference.iter().any(|r| *r != RefState::Referenced) {
        out.flags |= FLAG_UNREFERENCED;
    }
    if !st.pressure_ok {
        out.flags |= FLAG_PRESSURE_STALE;
    }
    out.fault_code = st.fault.map_or(0, |f| f.fault.code());
    out.fault_axis = match st.fault.map(|f| f.fault) {
        Some(Fault::FollowingError { axis } | Fault::Controller { axis }) => axis,
        _ => 0xFF,
    };
    out.ticks = st.tick;
    out.tick_max_ns = cycles_to_ns(st.timing.max_cycles);
    out.tick_mean_ns = cycles_to_ns(st.timing.mean_cycles);
    out.overruns = st.timing.overruns;
    out.master = st.master.to_bits();
    out.axes.clear();
    out.inputs =
        if st.estop { INPUT_ESTOP } else { 0 } | if st.enable { INPUT_VALVE_POWER } else { 0 };
    for (((((p, t), e), d), r), m) in st
        .pos_um
        .iter()
        .zip(&st.target_um)
        .zip(&st.error_um)
        .zip(&st.dac)
        .zip(&st.reference)
        .zip(&st.manual)
    {
        let _ = out.axes.push(AxisStatus {
            pos_um: p.to_bits(),
            target_um: t.to_bits(),
            error_um: e.to_bits(),
            dac: d.get(),
            reference: match r {
                RefState::Unreferenced => 0,
                RefState::Homing => 1,
                RefState::Referenced => 2,
            },
            manual: m.code(),
            backoff: 0,
            ff_trim: [0; 2],
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::{FaultRecord, FaultSet, HoldReason};
    use crate::units::{DacCode, Master, PosUm, PressureBar};

    fn status(state: State, fault: Option<Fault>) -> Status<2, 4> {
        let mut timing = crate::runtime::timing::TickTiming::default();
        timing.max_cycles = 1680;
        timing.mean_cycles = 840;
        timing.overruns = 3;
        Status {
            tick: 77,
            state,
            fault: fault.map(|fault| FaultRecord { fault, tick: 70 }),
            fault_set: FaultSet::EMPTY,
            master: Master::from_num(12.5),
            pos_um: [PosUm::from_num(100), PosUm::from_num(-5)],
            target_um: [PosUm::from_num(101), PosUm::from_num(-4)],
            error_um: [PosUm::from_num(1), PosUm::from_num(1)],
            dac: [DacCode::NULL, DacCode::NULL],
            enable: true,
            estop: false,
            pressure_bar: [PressureBar::ZERO; 4],
            timing,
            reference: [RefState::Referenced; 2],
            pressure_ok: true,
            manual: [crate::runtime::ManualKind::Hold; 2],
        }
    }

    #[test]
    fn reference_and_pressure_flags() {
        let mut out = StatusMsg::default();
        let mut st = status(State::Idle, None);
        st.reference[1] = RefState::Homing;
        st.pressure_ok = false;
        fill_status(&st, |c| c, &mut out);
        assert_eq!(out.flags, FLAG_UNREFERENCED | FLAG_PRESSURE_STALE);
        assert_eq!(
            command_nak(0, CommandError::NotReferenced { axis: 1 }),
            Nak::with(NakCode::NotReferenced, 1, 0)
        );
        assert_eq!(
            command_nak(3, CommandError::Faulted),
            Nak::with(NakCode::BadState, 3, 2)
        );
        assert_eq!(
            command_nak(0, CommandError::NoController),
            Nak::with(NakCode::BadState, 0, 1)
        );
    }

    #[test]
    fn status_fields_map_one_to_one() {
        let mut out = StatusMsg::default();
        fill_status(&status(State::Following, None), |c| c * 10, &mut out);
        assert_eq!((out.state, out.flags, out.fault_code), (1, 0, 0));
        assert_eq!(out.fault_axis, 0xFF);
        assert_eq!(
            (out.ticks, out.tick_max_ns, out.tick_mean_ns),
            (77, 16800, 8400)
        );
        assert_eq!(out.overruns, 3);
        assert_eq!(out.master, Master::from_num(12.5).to_bits());
        assert_eq!(out.axes.len(), 2);
        assert_eq!(out.axes[1].pos_um, PosUm::from_num(-5).to_bits());
        assert_eq!(out.axes[0].target_um, PosUm::from_num(101).to_bits());
        assert_eq!(out.axes[1].error_um, PosUm::from_num(1).to_bits());
        assert_eq!(out.axes[0].dac, DacCode::NULL.get());
        // Filling twice does not append twice.
        fill_status(&status(State::Following, None), |c| c, &mut out);
        assert_eq!(out.axes.len(), 2);
    }

    #[test]
    fn motions_map_to_commands_and_naks_carry_their_detail() {
        let lim = crate::table::TableLimits::<1> {
            master_speed_per_s: crate::units::MasterRate::from_num(10_000),
            axes: [crate::table::AxisLimits {
                min_um: PosUm::from_num(-10),
                max_um: PosUm::from_num(500),
                max_speed_um_per_s: crate::units::VelUmPerS::from_num(20_000),
            }],
        };
        let mc = |m| motion_command(m, &lim);
        assert_eq!(mc(Motion::Start), Ok(Command::Start));
        assert_eq!(mc(Motion::Stop), Ok(Command::Stop));
        assert_eq!(mc(Motion::Hold), Ok(Command::Hold));
        assert_eq!(mc(Motion::ClearFault), Ok(Command::ClearFault));
        // A manual motion carries the axis' range; too fast is refused before the runtime.
        let limits = crate::runtime::MotionLimits {
            vel_um_per_s: 20_000,
            acc_um_per_s2: 1,
            jerk_um_per_s3: 1,
        };
        let to = PosUm::from_num(3);
        assert_eq!(
            mc(Motion::MoveTo {
                axis: 0,
                to,
                limits
            }),
            Ok(Command::MoveTo {
                axis: 0,
                to,
                limits,
                range: (PosUm::from_num(-10), PosUm::from_num(500))
            })
        );
        let fast = crate::runtime::MotionLimits {
            vel_um_per_s: 20_001,
            ..limits
        };
        let too_fast = Err(Nak::with(NakCode::Motion, 0, motion_reason::TOO_FAST));
        assert_eq!(
            mc(Motion::MoveTo {
                axis: 0,
                to,
                limits: fast
            }),
            too_fast
        );
        assert_eq!(mc(Motion::Approach { limits: fast }), too_fast);
        let speed = crate::units::VelUmPerS::from_num(-20_001);
        assert_eq!(
            mc(Motion::Jog {
                axis: 0,
                speed,
                limits
            }),
            too_fast
        );
        assert_eq!(
            command_nak(
                4,
                CommandError::Motion {
                    axis: 1,
                    error: MotionError::Moving
                }
            ),
            Nak::with(NakCode::Motion, 1, motion_reason::MOVING)
        );
        assert_eq!(
            (bad_state(2).code, bad_state(2).detail),
            (NakCode::BadState, 2)
        );
        let r = refused(REFUSED_NOT_SAFE);
        assert_eq!((r.code, r.detail), (NakCode::Refused, 1));
    }

    #[test]
    fn end_of_table_flag_and_fault_axis() {
        let mut out = StatusMsg::default();
        fill_status(
            &status(State::Holding(HoldReason::EndOfTable), None),
            |c| c,
            &mut out,
        );
        assert_eq!((out.state, out.flags), (2, 1));
        let f = Fault::FollowingError { axis: 1 };
        fill_status(&status(State::Fault, Some(f)), |c| c, &mut out);
        assert_eq!(
            (out.state, out.fault_code, out.fault_axis),
            (3, f.code(), 1)
        );
        let f = Fault::EStop;
        fill_status(&status(State::Fault, Some(f)), |c| c, &mut out);
        assert_eq!((out.fault_code, out.fault_axis), (f.code(), 0xFF));
    }
}
