//! The capture ring's storage (`hydra_core::runtime::capture`): 2 048 rows — 2.048 s of
//! every tick at 1 kHz — filling the F407's 64 KiB CCM RAM (0x1000_0000, CPU-only:
//! nothing here is touched by DMA), and the rows' flags bytes (2 048 B) in SRAM.
//!
//! The rows' section `.ccmram` is `NOLOAD` (`memory.x`): the start-up code does not
//! zero it, so [`take`] does, in place, before any reference to it exists.

use core::mem::MaybeUninit;
use hydra_core::profile::CAPTURE_ROWS;
use hydra_core::runtime::{Capture, CaptureRow};
use static_cell::ConstStaticCell;

use crate::consts::SLAVES;

/// The rows: 32 B each for two slaves, 65 536 B of CCM.
// Note(unsafe): a section of our own linker script (`memory.x`), nothing else in it.
#[allow(unsafe_code)]
#[link_section = ".ccmram.capture"]
static mut ROWS: MaybeUninit<[CaptureRow<SLAVES>; CAPTURE_ROWS]> = MaybeUninit::uninit();
/// The rows' flags (state, valve power, E-stop, command), in `.bss`.
static FLAGS: ConstStaticCell<[u8; CAPTURE_ROWS]> = ConstStaticCell::new([0; CAPTURE_ROWS]);

/// The capture ring over both (call once, at boot; `None` afterwards).
pub fn take() -> Option<Capture<'static, SLAVES>> {
    let flags = FLAGS.try_take()?;
    // Note(unsafe): `FLAGS` is taken once, so this runs once and the slice is the only
    // reference to `ROWS` ever made; the rows are zeroed (a valid `CaptureRow`: plain
    // integers) before the slice exists.
    #[allow(unsafe_code)]
    let rows = unsafe {
        let p = core::ptr::addr_of_mut!(ROWS).cast::<CaptureRow<SLAVES>>();
        core::ptr::write_bytes(p, 0, CAPTURE_ROWS);
        core::slice::from_raw_parts_mut(p, CAPTURE_ROWS)
    };
    Some(Capture::new(rows, flags))
}
