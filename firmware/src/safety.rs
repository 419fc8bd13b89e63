//! The E-stop input and the status LED.
//!
//! The E-stop chain is wired normally closed: the input reads high while every stop
//! button is released and the chain is intact. A pressed button, a broken wire or an
//! unplugged connector reads low (internal pull-down) = stop. The runtime faults on it
//! in the tick that reads it; the chain should also cut the valve power in hardware.

use embassy_stm32::gpio::Input;
use hydra_core::runtime::SafetyInput;

/// E-stop chain input (high = run permitted).
pub struct EStop {
    pin: Input<'static>,
}

impl EStop {
    /// Wraps the input pin.
    pub fn new(pin: Input<'static>) -> Self {
        Self { pin }
    }
}

impl SafetyInput for EStop {
    #[inline]
    fn estop_active(&mut self) -> bool {
        self.pin.is_low()
    }
}
