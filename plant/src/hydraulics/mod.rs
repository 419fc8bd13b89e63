//! The hydraulic plant of `shared/PLANT.md`: what the controller drives in simulation.
//!
//! | file | model |
//! |---|---|
//! | [`valve`] | 2nd-order spool, saturated travel, turbulent flow per land with the direction logic, laminar leakage |
//! | [`cylinder`] | single-rod cylinder: areas, dead volumes, mass, viscous + smoothed Coulomb friction, external load, spring contact, end stops |
//! | [`axis`] | one valve + cylinder: chamber-pressure dynamics with clamps, initial equilibrium, fixed-step RK4 in `f64` |
//! | [`master`] | the rotary table's angle: cosine speed ramps, speed ripple, exact stop, hold |
//! | [`sensors`] | quantised encoders (position, master), pressure ADC, valve DAC |
//! | [`edges`] | the master encoder's timestamped rising A edges (the board's edge timer) |
//!
//! SI units inside the model (m, m/s, Pa, m³/s, N, kg); engineering units (mm, µm, bar,
//! degrees) only at the scenario and sensor interfaces. The computation delay (output
//! of the controller applied one period after the sample) belongs to the simulation loop
//! that couples the plant with the controller.

pub mod axis;
pub mod cylinder;
pub mod edges;
pub mod master;
pub mod sensors;
pub mod valve;

pub use axis::{HydraulicAxis, Supply};
pub use cylinder::{Contact, Cylinder};
pub use edges::EdgeTimer;
pub use master::{MasterMotion, MasterProfile};
pub use sensors::{valve_command, Encoder, PressureAdc};
pub use valve::Valve;
