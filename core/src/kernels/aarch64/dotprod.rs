//! NEON dot-product [`crate::kernels::pack::SignedQuads`] kernel (ARMv8.2 `SDOT`): by element,
//! four signed codes of one pixel times the four signed weights of one output channel, added
//! into that pixel's 32-bit lane (exact: 4·128·128 per instruction). Block: the 4 channels of
//! the weight block × 16 pixels (16 accumulators of 4 lanes), once per 16 pixels the call uses.
//! `SDOT` is written with `asm!` (its intrinsics are unstable in Rust 1.95); the assembler
//! accepts it inside the `#[target_feature(enable = "dotprod")]` function it is inlined into.

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};
use core::arch::aarch64::*;

/// Same contract as [`crate::kernels::dot::portable`] for signed quads. Returns `false` (and
/// does nothing) if this CPU lacks the dot product or a read would leave the slices.
pub fn quads(t: &Task<i8, i8>, acc: &mut Acc) -> bool {
    if !crate::kernels::isa::Isa::NeonDot.available() || !t.in_bounds(4) {
        return false;
    }
    // SAFETY: NEON and the dot product are available and every read is in bounds (checked);
    // `acc` holds the `NB` rows of `PB` the kernel writes.
    unsafe { dispatch(t, acc.as_mut_ptr(), PB) };
    true
}

/// As [`quads`], each used channel `j`'s sums written to `dst + j·stride` instead of `acc`
/// (the rest of a 16-pixel group included: `16·⌈pixels/16⌉` sums per channel).
///
/// # Safety
/// `dst + j·stride + i` must be valid for writes for `j < t.channels`, `i < 16·⌈pixels/16⌉`.
pub unsafe fn quads_into(t: &Task<i8, i8>, dst: *mut i32, stride: usize) -> bool {
    if !crate::kernels::isa::Isa::NeonDot.available() || !t.in_bounds(4) {
        return false;
    }
    // SAFETY: as in `quads`; the writes are the caller's contract.
    unsafe { dispatch(t, dst, stride) };
    true
}

/// [`quads_dot`] for the task's channel count.
///
/// # Safety
/// As [`quads_dot`].
#[inline(always)]
unsafe fn dispatch(t: &Task<i8, i8>, dst: *mut i32, stride: usize) {
    match t.channels {
        1 => quads_dot::<1>(t, dst, stride),
        2 => quads_dot::<2>(t, dst, stride),
        3 => quads_dot::<3>(t, dst, stride),
        _ => quads_dot::<4>(t, dst, stride),
    }
}

/// `a += SDOT(x, w.4b[J])`: lane `p` of `a` gains `Σ_l x[4p + l] · w[4J + l]`.
///
/// # Safety
/// Only inside a function built with the `dotprod` target feature, run on a CPU that has it.
#[inline(always)]
unsafe fn sdot<const J: i32>(a: &mut int32x4_t, x: int8x16_t, w: int8x16_t) {
    // SAFETY (caller): the CPU executes SDOT; registers only, no memory, flags untouched.
    core::arch::asm!(
        "sdot {a:v}.4s, {x:v}.16b, {w:v}.4b[{j}]",
        a = inout(vreg) *a,
        x = in(vreg) x,
        w = in(vreg) w,
        j = const J,
        options(pure, nomem, nostack, preserves_flags)
    );
}

/// The first `C` channels of the block only (the others' accumulators are left as they were:
/// a one-channel conv runs 4 `SDOT` per step instead of 16).
///
/// # Safety
/// The CPU must have NEON and the dot-product extension (`FEAT_DotProd`), and the task's
/// slices must hold the block the task names; the safe wrappers check both. Channel `j`'s sums
/// go to `dst + j·stride`, `16·⌈pixels/16⌉` of them, which must be valid for writes.
#[target_feature(enable = "neon,dotprod")]
unsafe fn quads_dot<const C: usize>(t: &Task<i8, i8>, dst: *mut i32, stride: usize) {
    const _: () = assert!(NB == 4 && PB.is_multiple_of(16));
    for half in 0..t.pixels.clamp(1, PB).div_ceil(16) {
        let mut c = [vdupq_n_s32(0); 16];
        let mut wq = t.weights.as_ptr();
        let row = t.rows.as_ptr().add(4 * (t.ox0 + 16 * half));
        for &step in t.steps.iter() {
            let pr = row.add(step as usize);
            let w = vld1q_s8(wq);
            for q in 0..4 {
                let x = vld1q_s8(pr.add(16 * q));
                sdot::<0>(&mut c[q], x, w);
                if C > 1 {
                    sdot::<1>(&mut c[4 + q], x, w);
                }
                if C > 2 {
                    sdot::<2>(&mut c[8 + q], x, w);
                }
                if C > 3 {
                    sdot::<3>(&mut c[12 + q], x, w);
                }
            }
            wq = wq.add(4 * NB);
        }
        for j in 0..C.min(NB) {
            let dst = dst.add(j * stride + 16 * half);
            for q in 0..4 {
                vst1q_s32(dst.add(4 * q), c[4 * j + q]);
            }
        }
    }
}
