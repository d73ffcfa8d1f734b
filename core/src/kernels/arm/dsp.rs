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
    // Only the blocks the row uses: the narrow layers of the encoder use a fraction of PB.
    let pixels = t.pixels.clamp(1, PB);
    for jb in (0..NB).step_by(2) {
        for pb in (0..pixels).step_by(2) {
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

/// Two weight rows against one pixel: `(a + Σ wa_k·x_k, b + Σ wb_k·x_k)` over `n4` groups of
/// four channels. `SXTB16` splits a weight word into its even and odd bytes as 16-bit pairs,
/// which meet the pixel's `[x0|x2]`, `[x1|x3]` words in `SMLAD`: 13 instructions per 8
/// multiply-accumulates.
///
/// # Safety
/// `n4 ≥ 1`; `n4` words of `wa` and `wb` and `2·n4` words of `x` must be readable and 4-aligned.
#[inline(always)]
unsafe fn rows2(
    wa: *const u32,
    wb: *const u32,
    x: *const u32,
    n4: usize,
    a: i32,
    b: i32,
) -> (i32, i32) {
    let (mut a, mut b) = (a, b);
    core::arch::asm!(
        "2:",
        "ldr {t}, [{wa}], #4",
        "ldr {u}, [{wb}], #4",
        "ldrd {x0}, {x1}, [{x}], #8",
        "sxtb16 {s}, {t}",
        "sxtb16 {t}, {t}, ror #8",
        "smlad {a}, {s}, {x0}, {a}",
        "smlad {a}, {t}, {x1}, {a}",
        "sxtb16 {s}, {u}",
        "sxtb16 {u}, {u}, ror #8",
        "smlad {b}, {s}, {x0}, {b}",
        "smlad {b}, {u}, {x1}, {b}",
        "subs {n}, {n}, #1",
        "bne 2b",
        wa = inout(reg) wa => _,
        wb = inout(reg) wb => _,
        x = inout(reg) x => _,
        n = inout(reg) n4 => _,
        t = out(reg) _,
        u = out(reg) _,
        s = out(reg) _,
        x0 = out(reg) _,
        x1 = out(reg) _,
        a = inout(reg) a,
        b = inout(reg) b,
        options(nostack, readonly),
    );
    (a, b)
}

/// `sums[r] += Σ_k weights[r·c + k] · x_k` for every row `r` of `c` int8 weights (the rows of
/// a 1×1 head), with the pixel's `x_k = code − zp` packed by [`pack_pixel`]. `false` (nothing
/// written) unless `c` is a positive multiple of 4, the weights are 4-aligned and the slices
/// hold `sums.len()` rows and `c / 2` words.
pub fn dot_rows(weights: &[i8], c: usize, x: &[u32], sums: &mut [i32]) -> bool {
    let rows = sums.len();
    if c == 0
        || !c.is_multiple_of(4)
        || !(weights.as_ptr() as usize).is_multiple_of(4)
        || rows.checked_mul(c).is_none_or(|n| weights.len() < n)
        || x.len() < c / 2
    {
        return false;
    }
    let w = weights.as_ptr() as *const u32;
    let words = c / 4;
    let mut r = 0;
    while r + 2 <= rows {
        // SAFETY: rows r and r + 1 (c bytes each, 4-aligned as c is a multiple of 4) lie in
        // `weights`, and `x` holds c/2 words (checked above).
        let (a, b) = unsafe {
            rows2(
                w.add(r * words),
                w.add((r + 1) * words),
                x.as_ptr(),
                words,
                sums[r],
                sums[r + 1],
            )
        };
        sums[r] = a;
        sums[r + 1] = b;
        r += 2;
    }
    if r < rows {
        let row = &weights[r * c..(r + 1) * c];
        for (k, &wk) in row.iter().enumerate() {
            let word = x[k / 4 * 2 + k % 2];
            let xk = if k % 4 < 2 {
                word as i16
            } else {
                (word >> 16) as i16
            };
            sums[r] = sums[r].wrapping_add(i32::from(wk) * i32::from(xk));
        }
    }
    true
}

/// Packs `x_k` (`k < 4·⌊len/4⌋`, 16-bit) as `[x0|x2], [x1|x3], [x4|x6], …` for [`dot_rows`].
pub fn pack_pixel(x: impl Iterator<Item = i32>, out: &mut [u32]) {
    let mut quad = [0u32; 4];
    for (k, v) in x.enumerate() {
        quad[k % 4] = (v as u32) & 0xFFFF;
        if k % 4 == 3 {
            if let Some(o) = out.get_mut(k / 4 * 2..k / 4 * 2 + 2) {
                o[0] = quad[0] | (quad[2] << 16);
                o[1] = quad[1] | (quad[3] << 16);
            }
        }
    }
}
