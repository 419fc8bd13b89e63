//! Axis control laws: position (Feedforward, Paper, NextNode) and force (press).

pub mod backoff;
pub mod config;
pub mod damping;
pub mod ff_trim;
pub mod position;
pub mod press;

pub use backoff::{BackoffCoeffs, BackoffField, BackoffSettings, BackoffState, BandError};
pub use config::{AxisCoeffs, AxisConfig, AxisConfigError, ControlMode, PositionGains};
pub use damping::{DampingCoeffs, DampingError, DampingState, PistonAreas};
pub use ff_trim::{FfTrimCoeffs, FfTrimError, FfTrimState};
pub use position::{position_law, PosRef, PosState};
pub use press::{
    PressCoeffs, PressConfig, PressConfigError, PressGains, PressOutput, PressPhase, PressState,
};
