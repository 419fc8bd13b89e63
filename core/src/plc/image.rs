//! The input registers' values: the runtime's [`Status`] and the board's PLC-side
//! facts, read through the register map ([`super::map::MAP`]).
//!
//! A read of `count` registers from `start` resolves every address through the map; an
//! address no register covers (a gap, beyond the last axis) refuses the whole read with
//! [`ReadError::IllegalAddress`] (Modbus exception 02), as does a read that would split a
//! 32-bit value. Values convert with saturation: a position beyond ±2^31 µm reads as the
//! `i32` limit.

use super::map::{AxisCount, RegType, Register, RegisterTable, StatusBit};
use super::owner::Side;
use crate::runtime::{RefState, State, Status};

/// `table.active_id` with no active table (or one whose id does not fit 16 bits).
pub const NO_TABLE: u16 = u16::MAX;

/// What the input registers report beyond the runtime's status, per axis where it says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlcFacts<const S: usize> {
    /// Idle with a law and a table (Start would be taken).
    pub ready: bool,
    /// Who owns the machine.
    pub owner: Side,
    /// The PLC's heartbeat is lost.
    pub heartbeat_lost: bool,
    /// The last command's outcome (0 none yet, 1 done, else the refusal's code).
    pub command_ack: u16,
    /// Commands taken, wrapping.
    pub command_count: u16,
    /// The active table's id ([`NO_TABLE`]: none).
    pub table_active_id: u16,
    /// The last parameter operation's outcome (see the map).
    pub param_result: u16,
    /// The value the last parameter read returned.
    pub param_read_value: f32,
    /// The master speed, master counts/s.
    pub master_speed_counts_per_s: i32,
    /// The tick's longest execution, µs.
    pub tick_max_us: u16,
    /// In-position window per axis, µm: |error| ≤ it sets the axis' in-position bit.
    pub in_position_um: [u32; S],
    /// The cylinder force per axis, N.
    pub force_n: [f32; S],
    /// The gain backoff's level per axis.
    pub backoff_level: [u8; S],
}

/// Why a read was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReadError {
    /// `address` is no register's, or the read splits a 32-bit value there (exception 02).
    IllegalAddress {
        /// The first offending address.
        address: u16,
    },
}

impl ReadError {
    /// Its Modbus exception code: 02 ILLEGAL DATA ADDRESS.
    pub const fn modbus_exception(self) -> u8 {
        0x02
    }
}

fn sat_i32(x: i64) -> u32 {
    x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32 as u32
}

/// The value of input register `r` of axis `axis`, as raw bits (a 16-bit value in the
/// low half); `None` for a register this image does not know (a map entry without a
/// source reads as an illegal address, never as a silent 0).
fn input_value<const S: usize, const P: usize>(
    r: &Register,
    axis: u8,
    st: &Status<S, P>,
    f: &PlcFacts<S>,
) -> Option<u32> {
    let n = usize::from(axis);
    let pos = |a: &[crate::units::PosUm; S]| a.get(n).map_or(0, |p| sat_i32(p.to_num::<i64>()));
    let bar = |k: usize| {
        st.pressure_bar
            .get(n.saturating_mul(2).saturating_add(k))
            .map_or(0.0f32, |p| p.to_num::<f32>())
            .to_bits()
    };
    // Bit i set where `bit(i)`, for the first 16 axes.
    let mask = |bit: &dyn Fn(usize) -> bool| -> u32 {
        (0..S.min(16))
            .filter(|&i| bit(i))
            .fold(0, |m, i| m | 1u32.wrapping_shl(i as u32))
    };
    let referenced = |i: usize| st.reference.get(i) == Some(&RefState::Referenced);
    let in_position = |i: usize| match (st.error_um.get(i), f.in_position_um.get(i)) {
        (Some(e), Some(&w)) => u64::from(e.unsigned_abs().to_num::<u32>()) <= u64::from(w),
        _ => false,
    };
    let v = match r.name {
        "status" => {
            let mut s = 0u32;
            let mut set = |b: StatusBit, on: bool| {
                if on {
                    s |= 1 << (b as u8);
                }
            };
            set(StatusBit::Ready, f.ready && st.state == State::Idle);
            set(StatusBit::Following, st.state == State::Following);
            set(StatusBit::Holding, matches!(st.state, State::Holding(_)));
            set(StatusBit::Manual, st.state == State::Manual);
            set(StatusBit::Fault, st.state == State::Fault);
            set(StatusBit::TableActive, f.table_active_id != NO_TABLE);
            set(StatusBit::OwnerIsPlc, f.owner == Side::Plc);
            set(StatusBit::HeartbeatLost, f.heartbeat_lost);
            s | ((mask(&referenced) & 0xF) << (StatusBit::Referenced0 as u8))
                | ((mask(&in_position) & 0xF) << (StatusBit::InPosition0 as u8))
        }
        "state" => u32::from(st.state.code()),
        "fault_code" => st.fault.map_or(0, |r| u32::from(r.fault.code())),
        "fault_axis" => st
            .fault
            .and_then(|r| r.fault.slave())
            .map_or(0xFFFF, u32::from),
        "command_ack" => u32::from(f.command_ack),
        "command_count" => u32::from(f.command_count),
        "table.active_id" => u32::from(f.table_active_id),
        "param.result" => u32::from(f.param_result),
        "param.read_value" => f.param_read_value.to_bits(),
        "referenced" => mask(&referenced),
        "in_position" => mask(&in_position),
        "master.position" => sat_i32(st.master.to_num::<i64>()),
        "master.speed" => f.master_speed_counts_per_s as u32,
        "tick_max_us" => u32::from(f.tick_max_us),
        "actual_um" => pos(&st.pos_um),
        "target_um" => pos(&st.target_um),
        "error_um" => pos(&st.error_um),
        "pressure_a_bar" => bar(0),
        "pressure_b_bar" => bar(1),
        "valve_lsb" => st.dac.get(n).map_or(0, |d| i32::from(d.get()) as u32),
        "force_n" => f.force_n.get(n).map_or(0.0f32, |x| *x).to_bits(),
        "backoff_level" => f.backoff_level.get(n).map_or(0, |&l| u32::from(l)),
        _ => return None,
    };
    Some(v)
}

/// Reads `out.len()` input registers from `start` (function code 4) of a board with
/// `axes` axes. On an error `out` is unspecified and nothing else changes.
pub fn read_input<const S: usize, const P: usize>(
    st: &Status<S, P>,
    facts: &PlcFacts<S>,
    axes: AxisCount,
    start: u16,
    out: &mut [u16],
) -> Result<(), ReadError> {
    let mut k = 0usize;
    while k < out.len() {
        let address = start.saturating_add(u16::try_from(k).unwrap_or(u16::MAX));
        let illegal = ReadError::IllegalAddress { address };
        let (r, axis, word) = Register::find(RegisterTable::Input, address, axes).ok_or(illegal)?;
        let v = input_value(r, axis, st, facts).ok_or(illegal)?;
        let words: &[u16] = &match r.ty {
            RegType::U16 | RegType::I16 => [v as u16, 0],
            _ => [(v >> 16) as u16, v as u16],
        };
        let n = usize::from(r.ty.words());
        // A read must start at a value's first word and take all of it.
        if word != 0 || k.saturating_add(n) > out.len() {
            return Err(illegal);
        }
        for (o, w) in out.iter_mut().skip(k).zip(words.iter().take(n)) {
            *o = *w;
        }
        k = k.saturating_add(n);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::timing::TickTiming;
    use crate::runtime::{Fault, FaultRecord, FaultSet, ManualKind};
    use crate::units::{DacCode, Master, PosUm, PressureBar};

    fn facts() -> PlcFacts<2> {
        PlcFacts {
            ready: false,
            owner: Side::Plc,
            heartbeat_lost: false,
            command_ack: 1,
            command_count: 7,
            table_active_id: 3,
            param_result: 0,
            param_read_value: 0.0,
            master_speed_counts_per_s: -1500,
            tick_max_us: 92,
            in_position_um: [10, 10],
            force_n: [0.0, 20_000.0],
            backoff_level: [2, 0],
        }
    }

    fn status() -> Status<2, 4> {
        Status {
            tick: 0,
            state: State::Following,
            fault: None,
            fault_set: FaultSet::EMPTY,
            master: Master::from_num(-123_456),
            pos_um: [PosUm::from_num(250_000), PosUm::from_num(-3)],
            target_um: [PosUm::from_num(250_004), PosUm::from_num(-3)],
            error_um: [PosUm::from_num(4), PosUm::from_num(-30)],
            dac: [DacCode::NULL; 2],
            enable: true,
            estop: false,
            pressure_bar: [
                PressureBar::from_num(100),
                PressureBar::from_num(50),
                PressureBar::from_num(210),
                PressureBar::ZERO,
            ],
            timing: TickTiming::default(),
            reference: [RefState::Referenced, RefState::Homing],
            pressure_ok: true,
            manual: [ManualKind::Hold; 2],
        }
    }

    fn read(start: u16, n: usize) -> Result<std::vec::Vec<u16>, ReadError> {
        let mut out = std::vec![0u16; n];
        read_input(
            &status(),
            &facts(),
            AxisCount::new(2).unwrap(),
            start,
            &mut out,
        )?;
        Ok(out)
    }

    fn i32_at(w: &[u16]) -> i32 {
        ((u32::from(w[0]) << 16) | u32::from(w[1])) as i32
    }

    #[test]
    fn the_board_block_reads_state_status_and_facts() {
        let w = read(0, 12).unwrap();
        let status = w[0];
        assert_eq!(status & (1 << StatusBit::Following as u8), 1 << 1);
        assert_ne!(status & (1 << StatusBit::TableActive as u8), 0);
        assert_ne!(status & (1 << StatusBit::OwnerIsPlc as u8), 0);
        assert_eq!(status & (1 << StatusBit::Ready as u8), 0);
        assert_eq!(
            (status >> 8) & 0xF,
            0b01,
            "axis 0 referenced, axis 1 homing"
        );
        assert_eq!(
            (status >> 12) & 0xF,
            0b01,
            "axis 0 within 10 µm, axis 1 30 µm off"
        );
        assert_eq!(w[1], u16::from(State::Following.code()));
        assert_eq!((w[2], w[3]), (0, 0xFFFF), "no fault");
        assert_eq!((w[4], w[5], w[6]), (1, 7, 3));
        let m = read(20, 4).unwrap();
        assert_eq!(i32_at(&m[0..2]), -123_456);
        assert_eq!(i32_at(&m[2..4]), -1500);
    }

    #[test]
    fn axis_blocks_read_positions_pressures_and_force_high_word_first() {
        let a0 = read(100, 10).unwrap();
        assert_eq!(i32_at(&a0[0..2]), 250_000);
        assert_eq!(i32_at(&a0[2..4]), 250_004);
        assert_eq!(i32_at(&a0[4..6]), 4);
        let pa = f32::from_bits((u32::from(a0[6]) << 16) | u32::from(a0[7]));
        assert_eq!(pa, 100.0);
        let a1 = read(120, 15).unwrap();
        assert_eq!(i32_at(&a1[0..2]), -3);
        let pa1 = f32::from_bits((u32::from(a1[6]) << 16) | u32::from(a1[7]));
        assert_eq!(pa1, 210.0);
        let f = f32::from_bits((u32::from(a1[12]) << 16) | u32::from(a1[13]));
        assert_eq!(f, 20_000.0);
        assert_eq!(read(114, 1).unwrap(), [2], "axis 0's backoff level");
    }

    #[test]
    fn gaps_split_values_and_missing_axes_are_illegal_addresses() {
        let e = |a| Err(ReadError::IllegalAddress { address: a });
        assert_eq!(read(30, 1), e(30), "a gap");
        assert_eq!(read(101, 1), e(101), "the low word alone");
        assert_eq!(read(100, 1), e(100), "the high word alone");
        assert_eq!(read(140, 2), e(140), "axis 2 of 2");
        assert_eq!(read(0, 12).map(|w| w.len()), Ok(12));
        assert_eq!(read(0, 13), e(12), "past the board block");
        assert_eq!(e(0).unwrap_err().modbus_exception(), 2);
    }

    #[test]
    fn every_input_register_of_the_map_has_a_value() {
        use crate::plc::map::{Scope, MAP};
        for r in MAP.iter().filter(|r| r.table == RegisterTable::Input) {
            let axes = if r.scope == Scope::Board { 1 } else { 2 };
            for a in 0..axes {
                let n = usize::from(r.ty.words());
                assert!(read(r.address_of(a), n).is_ok(), "{} axis {a}", r.name);
            }
        }
    }

    #[test]
    fn a_fault_reads_its_code_and_axis() {
        let mut st = status();
        st.state = State::Fault;
        let fault = Fault::FollowingError { axis: 1 };
        st.fault = Some(FaultRecord { fault, tick: 5 });
        let mut w = [0u16; 4];
        read_input(&st, &facts(), AxisCount::new(2).unwrap(), 0, &mut w).unwrap();
        assert_ne!(w[0] & (1 << StatusBit::Fault as u8), 0);
        assert_eq!((w[2], w[3]), (fault.code(), 1));
    }
}
