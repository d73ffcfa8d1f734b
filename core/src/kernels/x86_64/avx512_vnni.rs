//! AVX-512 VNNI [`crate::kernels::pack::Quads`] kernel: `vpdpbusd` multiplies four unsigned
//! packed bytes (`x + 128`) by four signed weights and adds them into one 32-bit lane, without
//! saturation. Block: the 4 channels of the weight block × 32 pixels (8 accumulators of 16
//! lanes).

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};
use core::arch::x86_64::*;

/// Same contract as [`crate::kernels::dot::portable`] for quads. Returns `false` (and does
/// nothing) if this CPU lacks AVX-512 VNNI or a read would leave the slices.
pub fn quads(t: &Task<u8, i8>, acc: &mut Acc) -> bool {
    if !crate::kernels::isa::Isa::Avx512Vnni.available() || !t.in_bounds(4) {
        return false;
    }
    // SAFETY: the features are available and every read is in bounds (both checked).
    unsafe { quads_vnni(t, acc) };
    true
}

/// # Safety
/// The CPU must have AVX-512 F, BW and VNNI and `t.in_bounds(4)` must hold (every row and
/// weight read lies inside `t.rows` and `t.weights`); [`quads`] checks both.
#[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
unsafe fn quads_vnni(t: &Task<u8, i8>, acc: &mut Acc) {
    const _: () = assert!(NB == 4 && PB == 32);
    let mut c = [_mm512_setzero_si512(); 8];
    let mut wq = t.weights.as_ptr() as *const i32;
    let row = t.rows.as_ptr().add(4 * t.ox0);
    for &step in t.steps.iter() {
        {
            let pr = row.add(step as usize);
            let x0 = _mm512_loadu_si512(pr as *const __m512i);
            let x1 = _mm512_loadu_si512(pr.add(64) as *const __m512i);
            for j in 0..NB {
                let b = _mm512_set1_epi32(wq.add(j).read_unaligned());
                c[2 * j] = _mm512_dpbusd_epi32(c[2 * j], x0, b);
                c[2 * j + 1] = _mm512_dpbusd_epi32(c[2 * j + 1], x1, b);
            }
            wq = wq.add(NB);
        }
    }
    for j in 0..NB {
        let dst = acc.as_mut_ptr().add(j * PB) as *mut __m512i;
        _mm512_storeu_si512(dst, c[2 * j]);
        _mm512_storeu_si512(dst.add(1), c[2 * j + 1]);
    }
}
