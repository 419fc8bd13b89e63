//! board-emu: the firmware's release ELF on an emulated STM32F407 whose peripherals are
//! wired to host-sim's hydraulic plant (firmware in the loop).
//!
//! Licensed GPL-2.0-only: it links unicorn-engine (GPL-2.0). Nothing else in the
//! workspace depends on this crate (ci.sh checks it).

pub mod adc;
pub mod bus;
pub mod clocks;
pub mod dac;
pub mod dma;
pub mod elf;
pub mod flash;
pub mod gpio;
pub mod host;
pub mod iwdg;
pub mod machine;
pub mod plant;
pub mod rtt;
pub mod scs;
pub mod session;
pub mod timers;
pub mod usart;
