//! RAM and flash use, from cortex-m-rt's linker symbols, and the stack's high-water mark by
//! painting.
//!
//! - **Statics**: `.data + .bss + .uninit`, i.e. `__sheap − __sdata` (cortex-m-rt places them at
//!   the start of `RAM`, in that order, and the heap start right after; there is no heap).
//! - **Stack**: [`paint_stack`] fills the free RAM between `__sheap` and the current stack
//!   pointer with [`PAINT`] early in `main`; [`stack_high_water`] later finds the lowest word no
//!   longer holding it. The stack grows down from `_stack_start` (the end of `RAM`). A function
//!   that leaves [`PAINT`] in a stack slot would hide up to that slot; the figure is a lower
//!   bound, exact to the first overwritten word.
//! - **Flash**: everything loaded into `FLASH`, up to the end of `.data`'s load image
//!   (`__sidata + (__edata − __sdata)`), counted from address 0 (vector table first).

use core::ptr::addr_of;

/// Word written into unused stack by [`paint_stack`].
pub const PAINT: u32 = 0xDEAD_C0DE;

/// Bytes below the stack pointer that [`paint_stack`] leaves alone (room for its own frame).
const PAINT_MARGIN: usize = 64;

// Linker symbols of cortex-m-rt's `link.x`: only their addresses are used, never their values.
extern "C" {
    static __sdata: u32;
    static __edata: u32;
    static __sidata: u32;
    static __sheap: u32;
    static _stack_start: u32;
}

fn sdata() -> usize {
    addr_of!(__sdata) as usize
}

fn sheap() -> usize {
    addr_of!(__sheap) as usize
}

fn stack_start() -> usize {
    addr_of!(_stack_start) as usize
}

/// Bytes of statics (`.data`, `.bss`, `.uninit`).
pub fn statics_bytes() -> usize {
    sheap() - sdata()
}

/// Bytes of flash in use, from address 0 to the end of `.data`'s load image.
pub fn flash_bytes() -> usize {
    let (sidata, edata) = (addr_of!(__sidata) as usize, addr_of!(__edata) as usize);
    sidata + (edata - sdata())
}

/// Bytes of RAM between the statics and the top of the stack (the stack's region).
pub fn stack_region_bytes() -> usize {
    stack_start() - sheap()
}

/// Fills the unused stack with [`PAINT`]. Call once, first thing in `main`, with no interrupt
/// enabled yet.
pub fn paint_stack() {
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = sheap();
    let end = sp.saturating_sub(PAINT_MARGIN);
    while p + 4 <= end {
        // SAFETY: `[__sheap, sp − margin)` is RAM that no live object occupies (below the
        // stack pointer, above the statics, no heap); volatile so the stores are not elided.
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Deepest stack use since [`paint_stack`], in bytes from `_stack_start`.
pub fn stack_high_water() -> usize {
    let mut p = sheap();
    let top = stack_start();
    // SAFETY: reads of RAM words inside `[__sheap, _stack_start)`.
    while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    top - p
}
