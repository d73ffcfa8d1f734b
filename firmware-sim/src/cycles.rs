//! Instruction counts from SysTick under QEMU's `-icount shift=0`.
//!
//! # Method
//!
//! QEMU emulates instructions, not a pipeline: there are no cycle counts to read (its DWT has no
//! working `CYCCNT`). With `-icount shift=N` QEMU instead derives its *virtual clock* from the
//! number of guest instructions executed: every instruction advances it by exactly `2^N` ns
//! (`N = 0`: 1 ns). SysTick, clocked from the processor clock (`CLKSOURCE = 1`), counts that
//! virtual time at the board's `SYSCLK` of 25 MHz (QEMU `hw/arm/mps2.c`, `SYSCLK_FRQ`), i.e. one
//! tick per 40 ns. So under `-icount shift=0`:
//!
//! `instructions = ticks · (1e9 / 25e6) / 2^0 = 40 · ticks`, to ±40 instructions.
//!
//! SysTick is a 24-bit down-counter; [`start`] runs it free with the largest reload and counts
//! wraps in its exception, so [`ticks`] is a 64-bit monotonic count. The method is checked by the
//! `icount_check` scenario, which times a loop of a known number of instructions.
//!
//! These are **instructions** (Thumb-2, as compiled for the M4F, soft-float `f64` included), not
//! cycles: a Cortex-M4 takes 1–3 cycles for most instructions and more for loads on slow memory,
//! a Cortex-M7 can issue two per cycle. Without `-icount` the virtual clock follows the host's
//! real time and the figures are meaningless; the `.cargo/config.toml` runner and the tests pass
//! `-icount shift=0`.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;

/// `SYSCLK` of the MPS2 board model, Hz (QEMU `hw/arm/mps2.c`, `SYSCLK_FRQ`).
pub const SYSCLK_HZ: u32 = 25_000_000;
/// The `-icount` shift the runner uses: virtual ns per instruction is `2^ICOUNT_SHIFT`.
pub const ICOUNT_SHIFT: u32 = 0;
/// Instructions per SysTick tick under `-icount shift=ICOUNT_SHIFT` (40).
pub const INSTRUCTIONS_PER_TICK: u32 = (1_000_000_000 / SYSCLK_HZ) >> ICOUNT_SHIFT;

/// SysTick period: the counter's full 24-bit range.
const PERIOD: u64 = 1 << 24;

static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Starts SysTick free-running on the processor clock with its wrap interrupt enabled.
pub fn start(mut syst: SYST) {
    syst.disable_counter();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload((PERIOD - 1) as u32);
    syst.clear_current();
    syst.enable_counter();
    // Writing CVR clears it to 0; the first tick reloads it. Start counting from that reload,
    // so the initial 0 → reload step is neither a tick nor a wrap.
    while SYST::get_current() == 0 {}
    SCB::clear_pendst();
    WRAPS.store(0, Ordering::Release);
    syst.enable_interrupt();
}

/// Ticks since [`start`] (monotonic, 64-bit).
///
/// Reads the counter twice around the pending flag so that a wrap whose exception has not been
/// taken yet is still counted, and retries when the wrap count changed meanwhile.
pub fn ticks() -> u64 {
    loop {
        let w0 = WRAPS.load(Ordering::Acquire);
        let c0 = SYST::get_current();
        let pending = SCB::is_pendst_pending();
        let c1 = SYST::get_current();
        let w1 = WRAPS.load(Ordering::Acquire);
        // `c1 <= c0`: no reload between the two reads, so `pending` says whether the reload
        // before `c0` is already counted.
        if w0 == w1 && c1 <= c0 {
            let wraps = u64::from(w0) + u64::from(pending);
            return wraps * PERIOD + (PERIOD - 1 - u64::from(c0));
        }
    }
}

/// Instructions corresponding to `ticks` (see the module doc).
pub fn instructions(ticks: u64) -> u64 {
    ticks * u64::from(INSTRUCTIONS_PER_TICK)
}
