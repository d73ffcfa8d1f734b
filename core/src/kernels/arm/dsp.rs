//! Cortex-M4/M7 DSP [`crate::kernels::pack::Pairs`] kernel: `SMLAD` adds both 16-bit
//! products of a packed word and a weight word to a 32-bit accumulator in one instruction.
//! Block: 2 channels × 2 pixels (4 accumulators in registers); one hand-scheduled loop over all
//! reduction steps (`LDR` step offset, `LDRD` pixels, `LDRD` weights with post-increment, four
//! `SMLAD`): 10 instructions per 8 multiply-accumulates.

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};

/// The 2×2 sums over `n` reduction steps. `px`: the two pixel words at step offset 0; `steps`:
/// 16-bit-element offsets of each step from `px`; `w`: the two weight words of step 0 (the next step's
/// are `4·NB` bytes on).
///
/// # Safety
/// `n ≥ 1`; `steps` holds `n` entries, and every `px + 2·steps[k]` (8 bytes) and `w + k·4·NB`
/// (8 bytes) must be readable and 4-aligned.
#[inline(always)]
unsafe fn block(px: *const u8, steps: *const u32, w: *const u32, n: usize) -> [i32; 4] {
    let (mut a00, mut a01, mut a10, mut a11) = (0i32, 0i32, 0i32, 0i32);
    core::arch::asm!(
        "2:",
        "ldr {p0}, [{steps}], #4",
        "add {p0}, {px}, {p0}, lsl #1",
        "ldrd {p0}, {p1}, [{p0}]",
        "ldrd {w0}, {w1}, [{w}], #16",
        "smlad {a00}, {p0}, {w0}, {a00}",
        "smlad {a01}, {p1}, {w0}, {a01}",
        "smlad {a10}, {p0}, {w1}, {a10}",
        "smlad {a11}, {p1}, {w1}, {a11}",
        "subs {n}, {n}, #1",
        "bne 2b",
        px = in(reg) px,
        steps = inout(reg) steps => _,
        w = inout(reg) w => _,
        n = inout(reg) n => _,
        p0 = out(reg) _,
        p1 = out(reg) _,
        w0 = out(reg) _,
        w1 = out(reg) _,
        a00 = inout(reg) a00,
        a01 = inout(reg) a01,
        a10 = inout(reg) a10,
        a11 = inout(reg) a11,
        options(nostack, readonly),
    );
    [a00, a01, a10, a11]
}

/// Same contract as [`crate::kernels::dot::portable`] for pairs; `false` if a read would
/// leave the slices or they are not 4-aligned.
pub fn pairs(t: &Task<i16, i16>, acc: &mut Acc) -> bool {
    const _: () = assert!(NB == 4 && PB.is_multiple_of(2));
    let n = t.steps.len();
    if !t.in_bounds(2)
        || n == 0
        || !(t.rows.as_ptr() as usize).is_multiple_of(4)
        || !(t.weights.as_ptr() as usize).is_multiple_of(4)
        || t.steps.iter().any(|&o| o % 2 != 0)
    {
        return false;
    }
    let w = t.weights.as_ptr() as *const u32;
    for jb in (0..NB).step_by(2) {
        for pb in (0..PB).step_by(2) {
            // SAFETY: `in_bounds` covers every pixel word up to ox0 + PB of every step and
            // every weight word of the block; all are 4-aligned (checked).
            let a = unsafe {
                let px = (t.rows.as_ptr() as *const u8).add(4 * (t.ox0 + pb));
                block(px, t.steps.as_ptr(), w.add(jb), n)
            };
            acc[jb * PB + pb] = a[0];
            acc[jb * PB + pb + 1] = a[1];
            acc[(jb + 1) * PB + pb] = a[2];
            acc[(jb + 1) * PB + pb + 1] = a[3];
        }
    }
    true
}
