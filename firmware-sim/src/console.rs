//! Semihosting console: lines to the host's `stdout` and exit with a status code.

use core::fmt::Write;

/// Writes one line (`args` then `\n`) to the host's standard output. Output errors are ignored:
/// there is nowhere to report them.
pub fn println(args: core::fmt::Arguments<'_>) {
    if let Ok(mut out) = cortex_m_semihosting::hio::hstdout() {
        let _ = out.write_fmt(args);
        let _ = out.write_str("\n");
    }
}

/// Formats and prints a line through [`println`].
#[macro_export]
macro_rules! println {
    ($($arg:tt)*) => { $crate::console::println(format_args!($($arg)*)) };
}

/// Semihosting `SYS_EXIT_EXTENDED` (Arm semihosting specification v2, operation `0x20`).
const SYS_EXIT_EXTENDED: usize = 0x20;
/// `ADP_Stopped_ApplicationExit`: the reason code for a normal program exit.
const ADP_STOPPED_APPLICATION_EXIT: usize = 0x20026;

/// Ends the program; QEMU exits with status `code`.
///
/// Uses `SYS_EXIT_EXTENDED` with the block `{ADP_Stopped_ApplicationExit, code}`: QEMU's
/// semihosting (target/arm/arm-compat-semi.c) exits with the sub-code for that call even on
/// 32-bit Arm, whereas plain `SYS_EXIT` only distinguishes success from failure.
pub fn exit(code: u8) -> ! {
    let block = [ADP_STOPPED_APPLICATION_EXIT, usize::from(code)];
    // SAFETY: a semihosting call with a valid pointer to a two-word parameter block.
    unsafe {
        cortex_m_semihosting::syscall(SYS_EXIT_EXTENDED, &block);
    }
    // Only reached without a debugger/emulator that handles semihosting.
    loop {
        cortex_m::asm::bkpt();
    }
}
