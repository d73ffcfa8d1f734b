//! Cortex-M4/M7 DSP packing of [`crate::kernels::pack::Pairs`] rows: two int8 channel rows
//! into 16-bit `x − zp` pairs, four pixels per loop (`SXTB16` widens the even and odd bytes of
//! a word, `PKHBT`/`PKHTB` pair the two channels, `SSUB16` subtracts the zero point in both
//! halves): 20 instructions per four pixels. `x − zp` lies in −255..=255, so the 16-bit
//! subtraction is exact and the words equal the portable loop's.

/// Writes `out[2x] = a[x] − zp`, `out[2x + 1] = b[x] − zp` for the first `4·⌊n/4⌋` pixels,
/// `n = min(a.len(), b.len(), out.len() / 2)`; returns how many pixels it wrote (the caller
/// packs the rest).
pub fn interleave_pairs(a: &[i8], b: &[i8], zp: i32, out: &mut [i16]) -> usize {
    let n4 = a.len().min(b.len()).min(out.len() / 2) / 4;
    if n4 == 0 {
        return 0;
    }
    let z = (zp as u32 & 0xffff).wrapping_mul(0x1_0001);
    // SAFETY: the loop reads 4·n4 bytes of `a` and of `b` and writes 8·n4 halfwords of `out`,
    // all within the slices (n4 as computed above); Cortex-M4/M7 allow the unaligned word
    // loads and stores `LDR`/`STR` make here.
    unsafe {
        core::arch::asm!(
            "2:",
            "ldr {x}, [{a}], #4",
            "ldr {y}, [{b}], #4",
            "sxtb16 {p}, {x}",
            "sxtb16 {x}, {x}, ror #8",
            "sxtb16 {q}, {y}",
            "sxtb16 {y}, {y}, ror #8",
            "pkhbt {r}, {p}, {q}, lsl #16",
            "pkhtb {p}, {q}, {p}, asr #16",
            "ssub16 {r}, {r}, {z}",
            "ssub16 {p}, {p}, {z}",
            "pkhbt {q}, {x}, {y}, lsl #16",
            "pkhtb {x}, {y}, {x}, asr #16",
            "ssub16 {q}, {q}, {z}",
            "ssub16 {x}, {x}, {z}",
            "str {r}, [{o}], #4",
            "str {q}, [{o}], #4",
            "str {p}, [{o}], #4",
            "str {x}, [{o}], #4",
            "subs {n}, {n}, #1",
            "bne 2b",
            a = inout(reg) a.as_ptr() => _,
            b = inout(reg) b.as_ptr() => _,
            o = inout(reg) out.as_mut_ptr() => _,
            n = inout(reg) n4 => _,
            z = in(reg) z,
            x = out(reg) _,
            y = out(reg) _,
            p = out(reg) _,
            q = out(reg) _,
            r = out(reg) _,
            options(nostack),
        );
    }
    4 * n4
}

/// Writes `out[4·x] = src[x] − zp` (16-bit) for the first `4·⌊n/4⌋` pixels, `n =
/// min(src.len(), ⌈out.len() / 4⌉)`: one input row into its slot of the 3×3 depthwise strip
/// (`depthwise::ring3`, columns of four halfwords; `out` starts at the row's slot). Four pixels
/// per pass: one word load, `SXTB16` of the even and odd bytes, `SSUB16` of the zero point,
/// four `STRH` (13 instructions; the compiled loop took 20). `x − zp` lies in −255..=255: the
/// same halfwords. Returns how many pixels it wrote (the caller writes the rest).
pub fn strip_row(src: &[i8], zp: i32, out: &mut [i16]) -> usize {
    let n4 = src.len().min(out.len().div_ceil(4)) / 4;
    if n4 == 0 {
        return 0;
    }
    let z = (zp as u32 & 0xffff).wrapping_mul(0x1_0001);
    // SAFETY: the loop reads 4·n4 bytes of `src` and writes halfwords 0, 4, …, 16·n4 − 4 of
    // `out` (4·n4 ≤ ⌈out.len() / 4⌉, so 16·n4 − 4 < out.len()), all within the slices;
    // Cortex-M4/M7 allow the unaligned word load `LDR` makes here, and `out` is 2-aligned.
    unsafe {
        core::arch::asm!(
            "2:",
            "ldr {x}, [{s}], #4",
            "sxtb16 {e}, {x}",
            "sxtb16 {x}, {x}, ror #8",
            "ssub16 {e}, {e}, {z}",
            "ssub16 {x}, {x}, {z}",
            "strh {e}, [{o}], #32",
            "strh {x}, [{o}, #-24]",
            "lsr {e}, {e}, #16",
            "lsr {x}, {x}, #16",
            "strh {e}, [{o}, #-16]",
            "strh {x}, [{o}, #-8]",
            "subs {n}, {n}, #1",
            "bne 2b",
            s = inout(reg) src.as_ptr() => _,
            o = inout(reg) out.as_mut_ptr() => _,
            n = inout(reg) n4 => _,
            z = in(reg) z,
            x = out(reg) _,
            e = out(reg) _,
            options(nostack),
        );
    }
    4 * n4
}
