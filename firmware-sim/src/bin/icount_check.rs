//! Scenario `icount_check`: verifies the instruction-counting method of
//! [`depthor_firmware_sim::cycles`]. Times a loop of exactly `2 · N` instructions (`subs`, `bne`)
//! long enough to wrap SysTick's 24-bit counter once, and requires the count from SysTick to
//! match within two ticks. Run it under the same runner (`-icount shift=0`):
//! `cargo run --release --bin icount_check`.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use depthor_firmware_sim::{console, cycles, println};

/// Loop iterations: `2 · N` = 700 M instructions = 17.5 M ticks > 2^24, so one wrap is crossed.
const N: u32 = 350_000_000;

#[entry]
fn main() -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        console::exit(depthor_replay::EXIT_PANIC);
    };
    depthor_firmware_sim::cpu::print(&peripherals.CPUID);
    cycles::start(peripherals.SYST);
    let overhead = {
        let t0 = cycles::ticks();
        cycles::ticks() - t0
    };
    let t0 = cycles::ticks();
    // SAFETY: a register-only countdown loop; touches no memory and no stack.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) N => _,
            // No `nomem`: the asm must stay between the two counter reads.
            options(nostack),
        );
    }
    let t1 = cycles::ticks();
    let ticks = (t1 - t0).saturating_sub(overhead);
    let measured = cycles::instructions(ticks);
    let expected = 2 * u64::from(N);
    let tolerance = 2 * u64::from(cycles::INSTRUCTIONS_PER_TICK);
    println!(
        "icount_check: {ticks} ticks -> {measured} instructions, loop has {expected} \
         (tolerance {tolerance}); {:.4} instructions per tick",
        expected as f64 / ticks as f64
    );
    if measured.abs_diff(expected) <= tolerance {
        println!("TEST OK");
        console::exit(0)
    } else {
        println!(
            "TEST FAILED: SysTick does not count one tick per {} instructions",
            cycles::INSTRUCTIONS_PER_TICK
        );
        console::exit(1)
    }
}
