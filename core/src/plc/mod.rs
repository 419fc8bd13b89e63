//! The PLC side of the board: what a PLC reads and writes over Modbus.
//!
//! - [`map`]: the register map, one table from which the server's decoding, the
//!   integrator's documentation (docs/plc.md) and `host-sim modbus-map --json` come.
pub mod map;

pub use map::{
    Access, AxisCount, CommandBit, RegType, Register, RegisterTable, Scope, StatusBit, AXIS_BASE,
    AXIS_STRIDE, MAP, MAX_AXES,
};
