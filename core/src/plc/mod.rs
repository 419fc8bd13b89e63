//! The PLC side of the board: what a PLC reads and writes over Modbus.
//!
//! - [`map`]: the register map, one table from which the server's decoding, the
//!   integrator's documentation (docs/plc.md) and `host-sim modbus-map --json` come.
//! - [`image`]: the input registers' values from the runtime's status;
//! - [`owner`]: control ownership (one side moves the machine) and the PLC's heartbeat;
//! - [`server`]: register reads and writes as the handler's requests (what a Modbus
//!   transport calls);
//! - [`settings`]: the PLC link's settings (`plc/…`).
pub mod image;
pub mod map;
pub mod owner;
pub mod server;
pub mod settings;

pub use image::{read_input, PlcFacts, ReadError, NO_TABLE};
pub use map::{
    Access, AxisCount, CommandBit, RegType, Register, RegisterTable, Scope, StatusBit, AXIS_BASE,
    AXIS_STRIDE, MAP, MAX_AXES,
};
pub use owner::{Heartbeat, MachineNow, OwnerError, Ownership, Side};
pub use server::{Exception, Live, Server};
pub use settings::PlcSettings;
