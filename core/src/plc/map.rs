//! The Modbus register map: every value a PLC reads or writes, with its table, address,
//! type, unit and access, in one table ([`MAP`]).
//!
//! **Addresses** are the protocol's 0-based register numbers (a PLC's "4x00001" is
//! holding register 0). Board-wide values sit below 100; axis `n`'s block starts at
//! `100 + n·AXIS_STRIDE` in its table ([`Register::address_of`]), for up to
//! [`MAX_AXES`] axes.
//!
//! **Word order**: a 32-bit value (`u32`, `i32`, `f32`) takes two registers, the high
//! word first (big-endian words, "ABCD"): value = reg[a]·65 536 + reg[a + 1]. An `f32`
//! is IEEE 754 binary32 in that order.
//!
//! **Commands** ([`CommandBit`]) are bits of the holding register `command`: a bit acts on
//! its rising edge (0 → 1), except `enable`, `jog_pos` and `jog_neg`, which act while
//! set (a jog stops when its bit clears or the PLC's heartbeat is lost). The axis of
//! `home`, the jogs and `move` is `command_axis`. The outcome lands in `command_ack`.

/// Largest number of axes the map addresses.
pub const MAX_AXES: u8 = 8;
/// Registers per axis block.
pub const AXIS_STRIDE: u16 = 20;
/// First register of axis 0's block.
pub const AXIS_BASE: u16 = 100;

/// The Modbus data table a register lives in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RegisterTable {
    /// Read-write bits (function codes 1, 5, 15).
    Coil,
    /// Read-only bits (function code 2).
    Discrete,
    /// Read-only 16-bit registers (function code 4).
    Input,
    /// Read-write 16-bit registers (function codes 3, 6, 16).
    Holding,
}

impl RegisterTable {
    /// Its name in the export: `coil`, `discrete`, `input`, `holding`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Coil => "coil",
            Self::Discrete => "discrete",
            Self::Input => "input",
            Self::Holding => "holding",
        }
    }
}

/// A register's value type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RegType {
    /// Unsigned 16 bits, one register.
    U16,
    /// Signed 16 bits (two's complement), one register.
    I16,
    /// Unsigned 32 bits, two registers, high word first.
    U32,
    /// Signed 32 bits, two registers, high word first.
    I32,
    /// IEEE 754 binary32, two registers, high word first.
    F32,
}

impl RegType {
    /// Its name in the export: `u16`, `i16`, `u32`, `i32`, `f32`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::U16 => "u16",
            Self::I16 => "i16",
            Self::U32 => "u32",
            Self::I32 => "i32",
            Self::F32 => "f32",
        }
    }

    /// Registers it takes: 1 or 2.
    pub const fn words(self) -> u16 {
        match self {
            Self::U16 | Self::I16 => 1,
            Self::U32 | Self::I32 | Self::F32 => 2,
        }
    }
}

/// Who may write a register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Anyone may read it; nobody writes it.
    Read,
    /// Anyone may read it; the machine's owner writes it (`owner` itself: see its
    /// description).
    ReadWrite,
}

impl Access {
    /// Its name in the export: `r` or `rw`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Read => "r",
            Self::ReadWrite => "rw",
        }
    }
}

/// Whether a register exists once or once per axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// One register for the board: its name is the entry's.
    Board,
    /// One per axis: `axis<n>.<name>` at [`Register::address_of`].
    Axis,
}

/// One entry of the map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Register {
    /// Its name (for an axis register, without the `axis<n>.` prefix).
    pub name: &'static str,
    /// Board-wide or per axis.
    pub scope: Scope,
    /// The data table.
    pub table: RegisterTable,
    /// Its address (an axis register's offset within the axis block).
    pub offset: u16,
    /// The value type.
    pub ty: RegType,
    /// The unit ("" for a code or a bit field).
    pub unit: &'static str,
    /// Who writes it.
    pub access: Access,
    /// What it is, for the integrator.
    pub description: &'static str,
}

/// The number of axes a board serves, 1 … [`MAX_AXES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisCount(u8);

impl AxisCount {
    /// One axis.
    pub const ONE: Self = Self(1);

    /// `n` axes, if 1 ≤ n ≤ [`MAX_AXES`].
    pub const fn new(n: u8) -> Option<Self> {
        if n >= 1 && n <= MAX_AXES {
            Some(Self(n))
        } else {
            None
        }
    }

    /// The count.
    pub const fn get(self) -> u8 {
        self.0
    }
}

impl Register {
    /// The register's address for axis `axis` (board registers ignore it): `offset`, or
    /// `AXIS_BASE + axis·AXIS_STRIDE + offset`.
    pub const fn address_of(&self, axis: u8) -> u16 {
        match self.scope {
            Scope::Board => self.offset,
            // axis < MAX_AXES and offset < AXIS_STRIDE in MAP: below 260, no overflow.
            Scope::Axis => AXIS_BASE
                .saturating_add((axis as u16).saturating_mul(AXIS_STRIDE))
                .saturating_add(self.offset),
        }
    }

    /// The entry of `table` whose registers cover `address`, with the axis it belongs
    /// to and the word within the value (0: the first/high word), for a board with
    /// `axes` axes.
    pub fn find(
        table: RegisterTable,
        address: u16,
        axes: AxisCount,
    ) -> Option<(&'static Register, u8, u16)> {
        MAP.iter().filter(|r| r.table == table).find_map(|r| {
            let axes = match r.scope {
                Scope::Board => 0..1,
                Scope::Axis => 0..axes.get(),
            };
            axes.into_iter().find_map(|n| {
                let a = r.address_of(n);
                let w = address.checked_sub(a)?;
                (w < r.ty.words()).then_some((r, n, w))
            })
        })
    }
}

/// Bits of the holding register `command` (see the module docs for edge and level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum CommandBit {
    /// Valve power permitted (level): clearing it stops any motion (Stop).
    Enable = 0,
    /// Start following the active table: from a commanded hold it resumes (Start); else
    /// every axis moves to the table at the present master by an S-curve with axis 0's
    /// `move_*` limits, then follows (Approach).
    Start = 1,
    /// Stop: every axis to Idle, valves at null.
    Stop = 2,
    /// Hold: freeze the master, the axes hold their targets.
    Hold = 3,
    /// Clear a latched fault (refused while its cause is present).
    ClearFault = 4,
    /// Arm homing of `command_axis` (the next reference edge references it).
    Home = 5,
    /// Jog `command_axis` forward (level).
    JogPos = 6,
    /// Jog `command_axis` backward (level).
    JogNeg = 7,
    /// Move `command_axis` to `axis<n>.move_to_um` at `axis<n>.move_speed_um_s`.
    Move = 8,
    /// Make `table.select_id` the active table (Idle only).
    ActivateTable = 9,
    /// Save the settings and the active table to flash.
    Save = 10,
}

impl CommandBit {
    /// Every command bit, in bit order.
    pub const ALL: [Self; 11] = [
        Self::Enable,
        Self::Start,
        Self::Stop,
        Self::Hold,
        Self::ClearFault,
        Self::Home,
        Self::JogPos,
        Self::JogNeg,
        Self::Move,
        Self::ActivateTable,
        Self::Save,
    ];

    /// Its name in docs/plc.md and the export.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Enable => "enable",
            Self::Start => "start",
            Self::Stop => "stop",
            Self::Hold => "hold",
            Self::ClearFault => "clear_fault",
            Self::Home => "home",
            Self::JogPos => "jog_pos",
            Self::JogNeg => "jog_neg",
            Self::Move => "move",
            Self::ActivateTable => "activate_table",
            Self::Save => "save",
        }
    }

    /// Acts while set (`true`) or on its rising edge.
    pub const fn is_level(self) -> bool {
        matches!(self, Self::Enable | Self::JogPos | Self::JogNeg)
    }

    /// Its mask in `command`.
    pub const fn mask(self) -> u16 {
        1 << (self as u8)
    }
}

/// Bits of the input register `status`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum StatusBit {
    /// Idle, every axis referenced, with a law and a table: Start would be taken.
    Ready = 0,
    /// Following the table.
    Following = 1,
    /// Holding (commanded, end of table, link or heartbeat loss).
    Holding = 2,
    /// Moving by hand (jog, move, approach, test move).
    Manual = 3,
    /// A fault is latched (`fault_code`, `fault_axis`).
    Fault = 4,
    /// A table is active.
    TableActive = 5,
    /// The PLC owns the machine.
    OwnerIsPlc = 6,
    /// The PLC's heartbeat stopped changing for `plc/heartbeat_ms`: the axes hold.
    HeartbeatLost = 7,
    /// Axes 0 … 3 referenced (bit 8 + n; every axis: `referenced`).
    Referenced0 = 8,
    /// Axes 0 … 3 in position (bit 12 + n; every axis: `in_position`).
    InPosition0 = 12,
}

impl StatusBit {
    /// Every status bit (the per-axis ones by their first bit), in bit order.
    pub const ALL: [Self; 10] = [
        Self::Ready,
        Self::Following,
        Self::Holding,
        Self::Manual,
        Self::Fault,
        Self::TableActive,
        Self::OwnerIsPlc,
        Self::HeartbeatLost,
        Self::Referenced0,
        Self::InPosition0,
    ];

    /// Its name in docs/plc.md.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Ready => "ready",
            Self::Following => "following",
            Self::Holding => "holding",
            Self::Manual => "manual",
            Self::Fault => "fault",
            Self::TableActive => "table_active",
            Self::OwnerIsPlc => "owner_is_plc",
            Self::HeartbeatLost => "heartbeat_lost",
            Self::Referenced0 => "referenced (axes 0–3: bits 8–11)",
            Self::InPosition0 => "in_position (axes 0–3: bits 12–15)",
        }
    }
}

#[allow(clippy::too_many_arguments)] // one row of the table, every column named
const fn reg(
    name: &'static str,
    scope: Scope,
    table: RegisterTable,
    offset: u16,
    ty: RegType,
    unit: &'static str,
    access: Access,
    description: &'static str,
) -> Register {
    Register {
        name,
        scope,
        table,
        offset,
        ty,
        unit,
        access,
        description,
    }
}

use Access::{Read as R, ReadWrite as RW};
use RegType::{F32, I32, U16, U32};
use RegisterTable::{Holding as H, Input as I};
use Scope::{Axis as A, Board as B};

/// The register map.
pub const MAP: [Register; 35] = [
    // ---- holding: what the PLC writes ----
    reg("command", B, H, 0, U16, "", RW, "command bits (CommandBit): enable, start, stop, hold, clear_fault, home, jog_pos, jog_neg, move, activate_table, save"),
    reg("command_axis", B, H, 1, U16, "", RW, "the axis of home, jog_pos, jog_neg and move"),
    reg("heartbeat", B, H, 2, U16, "", RW, "the PLC writes a changing value; unchanged for the PLC link's heartbeat time holds the axes (status heartbeat_lost)"),
    reg("owner", B, H, 3, U16, "", RW, "who moves the machine: 0 none, 1 serial host, 2 PLC; free while nobody owns it, else taken in Idle or Fault or from an owner that timed out; released by its owner"),
    reg("table.select_id", B, H, 4, U16, "", RW, "the table activate_table makes active: a table id of PROTOCOL.md, 0 … 65 534"),
    reg("param.id", B, H, 10, U16, "", RW, "the setting's stable id (PROTOCOL.md §3)"),
    reg("param.op", B, H, 11, U16, "", RW, "1 read, 2 write: acts when written; param.result tells the outcome"),
    reg("param.value", B, H, 12, F32, "setting's unit", RW, "the value to write"),
    reg("param.axis", B, H, 14, U16, "", RW, "the slave of a per-axis setting (ignored for a board setting)"),
    reg("move_to_um", A, H, 0, I32, "µm", RW, "move: the target position"),
    reg("move_speed_um_s", A, H, 2, I32, "µm/s", RW, "move and jog: the top speed (> 0; a jog's sign is its bit's), also start's approach speed on axis 0"),
    reg("move_acc_um_s2", A, H, 4, U32, "µm/s²", RW, "move, jog and approach: the acceleration limit (0: 100 000)"),
    reg("move_jerk_um_s3", A, H, 6, U32, "µm/s³", RW, "move, jog and approach: the jerk limit (0: 1 000 000)"),
    // ---- input: what the board reports ----
    reg("status", B, I, 0, U16, "", R, "status bits (StatusBit)"),
    reg("state", B, I, 1, U16, "", R, "0 idle, 1 following, 2 holding, 3 fault, 4 manual (the serial Status' codes)"),
    reg("fault_code", B, I, 2, U16, "", R, "the latched fault's code (0: none; PROTOCOL.md fault table)"),
    reg("fault_axis", B, I, 3, U16, "", R, "the latched fault's axis (0xFFFF: the board)"),
    reg("command_ack", B, I, 4, U16, "", R, "the last command's outcome: 0 none yet, 1 done, 0x100 + the serial Nak code when refused"),
    reg("command_count", B, I, 5, U16, "", R, "counts the commands taken (wrapping): a new command_ack is one with a new count"),
    reg("table.active_id", B, I, 6, U16, "", R, "the active table's id (0xFFFF: none, or an id beyond 65 534)"),
    reg("param.result", B, I, 7, U16, "", R, "the last param.op's outcome: 0 none yet, 1 done, 2 unknown id, 3 out of range, 4 read-only, 5 busy"),
    reg("param.read_value", B, I, 8, F32, "setting's unit", R, "the value param.op read"),
    reg("referenced", B, I, 10, U16, "", R, "bit n: axis n referenced"),
    reg("in_position", B, I, 11, U16, "", R, "bit n: axis n within its in-position window"),
    reg("master.position", B, I, 20, I32, "master counts", R, "the master position the law follows"),
    reg("master.speed", B, I, 22, I32, "master counts/s", R, "the master speed"),
    reg("tick_max_us", B, I, 24, U16, "µs", R, "the tick's longest execution since power-up"),
    reg("actual_um", A, I, 0, I32, "µm", R, "the measured position"),
    reg("target_um", A, I, 2, I32, "µm", R, "the position the law is chasing"),
    reg("error_um", A, I, 4, I32, "µm", R, "target − actual"),
    reg("pressure_a_bar", A, I, 6, F32, "bar", R, "chamber A (piston side) pressure"),
    reg("pressure_b_bar", A, I, 8, F32, "bar", R, "chamber B (rod side) pressure"),
    reg("valve_lsb", A, I, 10, I32, "DAC LSB", R, "the valve code written, from the DAC's mid-scale (the valve's null is its calibrated null code)"),
    reg("force_n", A, I, 12, F32, "N", R, "the cylinder force A_A·p_A − A_B·p_B"),
    reg("backoff_level", A, I, 14, U16, "", R, "the gain backoff's level (0: the set gain)"),
];

#[cfg(test)]
mod tests {
    use super::*;

    fn axes(n: u8) -> AxisCount {
        AxisCount::new(n).unwrap()
    }

    #[test]
    fn no_two_registers_overlap_and_axis_blocks_fit() {
        for t in [RegisterTable::Holding, RegisterTable::Input] {
            let mut used = [false; 512];
            for r in MAP.iter().filter(|r| r.table == t) {
                if r.scope == Scope::Board {
                    assert!(r.offset + r.ty.words() <= AXIS_BASE, "{}", r.name);
                } else {
                    assert!(r.offset + r.ty.words() <= AXIS_STRIDE, "{}", r.name);
                }
                let n = if r.scope == Scope::Board { 1 } else { MAX_AXES };
                for a in 0..n {
                    for w in 0..r.ty.words() {
                        let addr = usize::from(r.address_of(a) + w);
                        assert!(!used[addr], "{} overlaps at {addr}", r.name);
                        used[addr] = true;
                    }
                }
            }
        }
    }

    #[test]
    fn names_are_unique_per_table() {
        for (i, a) in MAP.iter().enumerate() {
            for b in &MAP[i + 1..] {
                assert!(!(a.name == b.name && a.table == b.table), "{}", a.name);
            }
        }
    }

    #[test]
    fn every_word_finds_its_register_and_gaps_find_none() {
        let r = Register::find(RegisterTable::Input, 101, axes(2)).unwrap();
        assert_eq!((r.0.name, r.1, r.2), ("actual_um", 0, 1));
        let r = Register::find(RegisterTable::Input, 128, axes(2)).unwrap();
        assert_eq!((r.0.name, r.1, r.2), ("pressure_b_bar", 1, 0));
        assert!(
            Register::find(RegisterTable::Input, 140, axes(2)).is_none(),
            "axis 2 of 2"
        );
        assert!(
            Register::find(RegisterTable::Input, 9, axes(2)).is_some(),
            "f32 low word"
        );
        assert!(Register::find(RegisterTable::Input, 12, axes(2)).is_none());
        assert!(
            Register::find(RegisterTable::Input, 30, axes(2)).is_none(),
            "a gap"
        );
        assert!(Register::find(RegisterTable::Holding, 13, axes(1)).is_some());
        assert!(Register::find(RegisterTable::Coil, 0, axes(1)).is_none());
        assert_eq!(AxisCount::new(0), None);
        assert_eq!(AxisCount::new(9), None);
    }

    #[test]
    fn command_bits_are_the_documented_eleven() {
        let names: [&str; 11] = CommandBit::ALL.map(CommandBit::name);
        assert_eq!(
            names,
            [
                "enable",
                "start",
                "stop",
                "hold",
                "clear_fault",
                "home",
                "jog_pos",
                "jog_neg",
                "move",
                "activate_table",
                "save"
            ]
        );
        for (i, b) in CommandBit::ALL.iter().enumerate() {
            assert_eq!(b.mask(), 1 << i);
        }
    }
}
