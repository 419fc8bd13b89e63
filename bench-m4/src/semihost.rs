//! The three ARM semihosting calls the bench needs (QEMU `-semihosting-config
//! enable=on,target=native`): write a string to the host's stdout, read the command line,
//! and exit with a status. One `bkpt 0xAB` per call: r0 = operation, r1 = argument block.
//!
//! Note(unsafe): semihosting is a breakpoint the emulator services; each call passes a
//! pointer to a block that lives for the duration of the call and is never retained.
#![allow(unsafe_code)]

use core::arch::asm;

/// SYS_WRITE0: write a NUL-terminated string to the debug console.
const SYS_WRITE0: usize = 0x04;
/// SYS_GET_CMDLINE: the program's command line.
const SYS_GET_CMDLINE: usize = 0x15;
/// SYS_EXIT (angel_SWIReason_ReportException).
const SYS_EXIT: usize = 0x18;
/// ADS_Stopped_ApplicationExit: normal exit; QEMU exits with status 0.
const ADP_STOPPED_APPLICATION_EXIT: usize = 0x2_0026;
/// ADS_Stopped_RunTimeErrorUnknown: QEMU exits with status 1.
const ADP_STOPPED_RUN_TIME_ERROR: usize = 0x2_0023;

/// One semihosting call.
fn call(op: usize, arg: usize) -> isize {
    let r: isize;
    // Note(unsafe): see the module docs; `arg` points to a live block or is a code.
    unsafe {
        asm!("bkpt 0xAB", inout("r0") op => r, in("r1") arg, options(nostack));
    }
    r
}

/// Writes `bytes` (must end with a NUL byte) to the host's stdout.
pub fn write0(bytes: &[u8]) {
    if bytes.last() == Some(&0) {
        call(SYS_WRITE0, bytes.as_ptr() as usize);
    }
}

/// Reads the command line into `buf`; returns the bytes read (without the NUL).
pub fn cmdline(buf: &mut [u8]) -> &[u8] {
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    if call(SYS_GET_CMDLINE, block.as_mut_ptr() as usize) != 0 {
        return &[];
    }
    let n = block[1].min(buf.len());
    &buf[..n]
}

/// Ends the emulation: QEMU exits with 0 if `ok`, 1 otherwise.
pub fn exit(ok: bool) -> ! {
    let code = if ok {
        ADP_STOPPED_APPLICATION_EXIT
    } else {
        ADP_STOPPED_RUN_TIME_ERROR
    };
    loop {
        call(SYS_EXIT, code);
    }
}
