//! Cortex-M4/M7 DSP [`crate::kernels::pack::Pairs`] kernel: `SMLAD` adds both 16-bit
//! products of a packed word and a weight word to a 32-bit accumulator in one instruction.
//! Block: 2 channels × 2 pixels (4 accumulators in registers).

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};

/// `acc + lo(a)·lo(b) + hi(a)·hi(b)` (signed 16-bit halves).
#[inline(always)]
fn smlad(a: u32, b: u32, acc: i32) -> i32 {
    let r: i32;
    // SAFETY: SMLAD only reads its three registers and writes one.
    unsafe {
        core::arch::asm!(
            "smlad {r}, {a}, {b}, {c}",
            r = lateout(reg) r,
            a = in(reg) a,
            b = in(reg) b,
            c = in(reg) acc,
            options(pure, nomem, nostack, preserves_flags)
        );
    }
    r
}

/// Same contract as [`crate::kernels::dot::portable`] for pairs; `false` if a read would
/// leave the slices or they are not 4-aligned.
pub fn pairs(t: &Task<i16, i16>, acc: &mut Acc) -> bool {
    if !t.in_bounds(2) {
        return false;
    }
    let (Some(rows), Some(w)) = (words(t.rows), words(t.weights)) else {
        return false;
    };
    let n_taps = t.taps.len();
    for jb in (0..NB).step_by(2) {
        for pb in (0..PB).step_by(2) {
            let (mut a00, mut a01, mut a10, mut a11) = (0i32, 0i32, 0i32, 0i32);
            for cg in 0..t.n_cg {
                let row = (cg * t.cg_stride) / 2 + t.ox0 + pb;
                let wrow = cg * n_taps * NB + jb;
                for (k, &tap) in t.taps.iter().enumerate() {
                    let at = row + tap as usize / 2;
                    let wat = wrow + k * NB;
                    // SAFETY: `in_bounds` covers every pixel word up to ox0 + PB and every
                    // weight word of the block.
                    let (p0, p1, w0, w1) = unsafe {
                        (
                            *rows.get_unchecked(at),
                            *rows.get_unchecked(at + 1),
                            *w.get_unchecked(wat),
                            *w.get_unchecked(wat + 1),
                        )
                    };
                    a00 = smlad(p0, w0, a00);
                    a01 = smlad(p1, w0, a01);
                    a10 = smlad(p0, w1, a10);
                    a11 = smlad(p1, w1, a11);
                }
            }
            acc[jb * PB + pb] = a00;
            acc[jb * PB + pb + 1] = a01;
            acc[(jb + 1) * PB + pb] = a10;
            acc[(jb + 1) * PB + pb + 1] = a11;
        }
    }
    true
}

/// The 16-bit pairs of `s` as 32-bit words (low half = even element), if `s` is 4-aligned.
fn words(s: &[i16]) -> Option<&[u32]> {
    // SAFETY: every bit pattern is a valid u32; `align_to` yields only the aligned middle.
    let (head, mid, tail) = unsafe { s.align_to::<u32>() };
    (head.is_empty() && tail.is_empty()).then_some(mid)
}
