//! Cortex-M4F/M7 (FPv4-SP) loop of the refinement step's interior chunks: four neighbours per
//! pass over a chunk, the f32 operations of `refine::step` in the same order (`VMUL`, `VADD`,
//! and `VMLA`, which rounds the product before adding, as Rust's `acc + r * d` does), so the
//! bits are those of every other path. 32 instructions per pixel and four neighbours.

/// Sums and accumulators of one chunk: `s[i]` at `sums + i`, `acc[i]` at `sums + CHUNK + i`.
pub const CHUNK: usize = 64;

/// For `i < n`: `r_j = lut[q_j[i]] · g_j`, `s[i] = (((s[i] + r0) + r1) + r2) + r3`,
/// `acc[i] = (((acc[i] + r0·d0[i]) + r1·d1[i]) + r2·d2[i]) + r3·d3[i]`.
///
/// # Safety
/// `n ≥ 1`; `q[j]` (n bytes), `d[j]` (n f32) are readable, `sums` holds `CHUNK + n` f32 with
/// `n ≤ CHUNK`, 4-aligned.
#[inline(always)]
pub unsafe fn four(
    q: [*const i8; 4],
    d: [*const f32; 4],
    g: [f32; 4],
    lut: &[f32; 256],
    sums: *mut f32,
    n: usize,
) {
    // The FP registers are named in the text (s16–s26, saved and restored here): stable Rust
    // offers no `sreg` operands on targets without double precision (the M4F's FPv4-SP).
    core::arch::asm!(
        "vpush {{s16-s26}}",
        "vldmia {g}, {{s16-s19}}",
        "2:",
        "ldrb {t}, [{q0}], #1",
        "add {t}, {lut}, {t}, lsl #2",
        "vldr s20, [{t}]",
        "vmul.f32 s20, s20, s16",
        "ldrb {t}, [{q1}], #1",
        "add {t}, {lut}, {t}, lsl #2",
        "vldr s21, [{t}]",
        "vmul.f32 s21, s21, s17",
        "ldrb {t}, [{q2}], #1",
        "add {t}, {lut}, {t}, lsl #2",
        "vldr s22, [{t}]",
        "vmul.f32 s22, s22, s18",
        "ldrb {t}, [{q3}], #1",
        "add {t}, {lut}, {t}, lsl #2",
        "vldr s23, [{t}]",
        "vmul.f32 s23, s23, s19",
        "vldr s24, [{p}]",
        "vldr s25, [{p}, #{acc_off}]",
        "vldmia {d0}!, {{s26}}",
        "vadd.f32 s24, s24, s20",
        "vmla.f32 s25, s20, s26",
        "vldmia {d1}!, {{s26}}",
        "vadd.f32 s24, s24, s21",
        "vmla.f32 s25, s21, s26",
        "vldmia {d2}!, {{s26}}",
        "vadd.f32 s24, s24, s22",
        "vmla.f32 s25, s22, s26",
        "vldmia {d3}!, {{s26}}",
        "vadd.f32 s24, s24, s23",
        "vmla.f32 s25, s23, s26",
        "vstr s25, [{p}, #{acc_off}]",
        "vstmia {p}!, {{s24}}",
        "cmp {p}, {end}",
        "bne 2b",
        "vpop {{s16-s26}}",
        acc_off = const CHUNK * 4,
        g = in(reg) g.as_ptr(),
        q0 = inout(reg) q[0] => _,
        q1 = inout(reg) q[1] => _,
        q2 = inout(reg) q[2] => _,
        q3 = inout(reg) q[3] => _,
        d0 = inout(reg) d[0] => _,
        d1 = inout(reg) d[1] => _,
        d2 = inout(reg) d[2] => _,
        d3 = inout(reg) d[3] => _,
        lut = in(reg) lut.as_ptr(),
        p = inout(reg) sums => _,
        end = in(reg) sums.add(n),
        t = out(reg) _,
    );
}
