//! The three semihosting services the bench needs, on `cortex-m-semihosting` (QEMU
//! `-semihosting-config enable=on,target=native`): text to the host's stdout, the
//! command line, and exit with a status.
//!
//! Note(unsafe): the crate has no wrapper for SYS_GET_CMDLINE; its `syscall1` passes a
//! pointer to a two-word block (buffer, length) that lives for the duration of the call
//! and that the emulator fills in.
#![allow(unsafe_code)]

use cortex_m_semihosting::{debug, hprint, nr};

/// Writes `s` to the host's stdout (the crate keeps the `:tt` handle open).
pub fn write(s: &str) {
    hprint!("{}", s);
}

/// Reads the command line into `buf`; returns the bytes read (without the NUL).
pub fn cmdline(buf: &mut [u8]) -> &[u8] {
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    // Note(unsafe): see the module docs.
    let r = unsafe { cortex_m_semihosting::syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    if r != 0 {
        return &[];
    }
    let n = block[1].min(buf.len());
    &buf[..n]
}

/// Ends the emulation: QEMU exits with 0 if `ok`, 1 otherwise.
pub fn exit(ok: bool) -> ! {
    loop {
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
    }
}
