//! Cortex-M4F/M7 (FPv4-SP) loop of the bins head's softmax expectation
//! ([`crate::kernels::bins`]): per bin `e = softmax_exp(l − m)`, `S += e`, `D += e·c`, the f32
//! operations of [`crate::fmath`]'s `softmax_exp` and of the portable loop in the same order
//! (`VMLA` rounds its product before adding, as Rust's `a + b * c` does), so the bits are those
//! of every other path; the constants stay in registers: 29 instructions per bin (the compiled
//! loop took 38).

use crate::fmath::{EXP2_32THS, SOFTMAX_FLOOR, SOFTMAX_T, SOFTMAX_U};

/// `(S, D)` over the `n = min(logits.len(), centres.len())` bins, from `S = D = 0`:
/// `e_i = softmax_exp(logits[i] − m)`, `S += e_i`, `D += e_i · centres[i]`, in order.
pub fn sums(logits: &[f32], m: f32, centres: &[f32]) -> (f32, f32) {
    let n = logits.len().min(centres.len());
    let mut sd = [0f32; 2];
    if n == 0 {
        return (0.0, 0.0);
    }
    // s16 ..= s23: m, 32·log2 e, ln 2 / 32, 1/6, 0.5, 1, the floor, 0 (the weight below it).
    let k: [f32; 8] = [
        m,
        SOFTMAX_T,
        SOFTMAX_U,
        1.0 / 6.0,
        0.5,
        1.0,
        SOFTMAX_FLOOR,
        0.0,
    ];
    // SAFETY: `n ≥ 1` f32 of `logits` and `centres` are read (n ≤ both lengths), the table
    // index is `n & 31` of 32 words, and `sd` receives two f32. The FP registers are named in
    // the text (s16–s29, saved and restored here, as in `refine::four`): stable Rust offers no
    // `sreg` operands on targets without double precision.
    unsafe {
        core::arch::asm!(
            "vpush {{s16-s29}}",
            "vldmia {k}, {{s16-s23}}",
            "vmov.f32 s28, s23",
            "vmov.f32 s29, s23",
            "2:",
            "vldmia {l}!, {{s24}}",
            // x = l − m; below the floor (and not NaN) the weight is 0.
            "vsub.f32 s24, s24, s16",
            "vcmp.f32 s24, s22",
            "vmrs APSR_nzcv, fpscr",
            "bmi 3f",
            // t = x·T, n = t toward zero, u = (t − n)·U.
            "vmul.f32 s25, s24, s17",
            "vcvt.s32.f32 s26, s25",
            "vmov {n}, s26",
            "vcvt.f32.s32 s26, s26",
            "vsub.f32 s25, s25, s26",
            "vmul.f32 s25, s25, s18",
            // p = 1 + u·(1 + u·(0.5 + u·(1/6))).
            "vmov.f32 s26, s20",
            "vmla.f32 s26, s25, s19",
            "vmov.f32 s27, s21",
            "vmla.f32 s27, s25, s26",
            "vmov.f32 s26, s21",
            "vmla.f32 s26, s25, s27",
            // (T[n & 31] · p) · 2^q, q = n >> 5, as (T[n & 31] · 2^q) · p: T[j] · 2^q is
            // exact, the bits of T[j] plus q << 23 (= (n << 18) & 0xFF800000, modulo 2^32),
            // and both orders round T[j]·p·2^q once, the result being normal (q ≥ −116).
            "and {j}, {mask}, {n}, lsl #18",
            "and {n}, {n}, #31",
            "ldr {n}, [{tbl}, {n}, lsl #2]",
            "add {j}, {j}, {n}",
            "vmov s27, {j}",
            "vmul.f32 s26, s27, s26",
            "b 4f",
            "3:",
            "vmov.f32 s26, s23",
            "4:",
            // S += e, D += e·c.
            "vldmia {c}!, {{s27}}",
            "vadd.f32 s28, s28, s26",
            "vmla.f32 s29, s26, s27",
            "cmp {l}, {end}",
            "bne 2b",
            "vstmia {sd}, {{s28-s29}}",
            "vpop {{s16-s29}}",
            k = in(reg) k.as_ptr(),
            l = inout(reg) logits.as_ptr() => _,
            c = inout(reg) centres.as_ptr() => _,
            end = in(reg) logits.as_ptr().add(n),
            tbl = in(reg) EXP2_32THS.as_ptr(),
            mask = in(reg) 0xFF80_0000u32,
            sd = in(reg) sd.as_mut_ptr(),
            n = out(reg) _,
            j = out(reg) _,
        );
    }
    (sd[0], sd[1])
}
