//! Minimal valve-controller firmware: init, one periodic task that reads an encoder,
//! runs the core, writes one DAC channel. The board issue makes it real.
#![no_std]
#![no_main]

use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_stm32::dac::{Dac, Value};
use embassy_time::{Duration, Ticker};
use hydra_core::units::DacCode;
use panic_probe as _;

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let p = embassy_stm32::init(embassy_stm32::Config::default());
    let mut dac = Dac::new_blocking(p.DAC1, p.PA4, p.PA5);
    let mut ticker = Ticker::every(Duration::from_millis(1));
    loop {
        let code = DacCode::NULL;
        dac.ch1().set(Value::Bit12Right(code.to_unipolar()));
        ticker.next().await;
    }
}
