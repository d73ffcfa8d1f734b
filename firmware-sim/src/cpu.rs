//! Which Cortex-M core runs the firmware, from `CPUID` (Armv7-M ARM, B4.1.2): the same ELF runs
//! on QEMU's `mps2-an386` (Cortex-M4, `cargo run --release`) and `mps2-an500` (Cortex-M7,
//! `cargo run-m7`), and prints the core it found.

use cortex_m::peripheral::CPUID;

/// The core's name from the `PARTNO` field of a `CPUID` value (`"unknown"` for another part).
pub fn name(cpuid: u32) -> &'static str {
    match (cpuid >> 4) & 0xfff {
        0xc20 => "Cortex-M0",
        0xc23 => "Cortex-M3",
        0xc24 => "Cortex-M4",
        0xc27 => "Cortex-M7",
        0xd21 => "Cortex-M33",
        _ => "unknown",
    }
}

/// Prints `cpu: <name> r<variant>p<revision> (CPUID 0x…)`.
pub fn print(cpuid: &CPUID) {
    let v = cpuid.base.read();
    crate::println!(
        "cpu: {} r{}p{} (CPUID {v:#010x})",
        name(v),
        (v >> 20) & 0xf,
        v & 0xf
    );
}
