//! # depthor-firmware-sim
//!
//! Board support for running depthor on an emulated Cortex-M4F: QEMU's `mps2-an386` board
//! (memory map in `memory.x`), with semihosting for output and exit status. The binaries in
//! `src/bin/` are the scenarios, each printing `TEST OK` and exiting 0 on success:
//!
//! - `replay` (default): the per-frame loop of [`depthor_replay::pipeline`] over the replay
//!   image embedded at build time (see `build.rs`), then RAM, flash and instructions per frame;
//! - `icount_check`: checks the instruction-counting method of [`cycles`] against a loop of
//!   known length.
//!
//! What's here: [`console`] (semihosting `stdout`, exit with a status), [`cpu`] (which core runs:
//! the same ELF runs on QEMU's `mps2-an386`, a Cortex-M4, and `mps2-an500`, a Cortex-M7), [`cycles`] (instruction
//! counts from SysTick under `-icount shift=0`), [`memory`] (RAM and flash use from the linker
//! symbols, stack high-water by painting), and the panic handler (prints the message, exits
//! with [`depthor_replay::EXIT_PANIC`]).
#![no_std]
#![warn(missing_docs)]

pub mod console;
pub mod cpu;
pub mod cycles;
pub mod memory;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    console::println(format_args!("PANIC: {info}"));
    console::exit(depthor_replay::EXIT_PANIC)
}
