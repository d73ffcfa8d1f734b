//! AVX2 [`crate::kernels::pack::Pairs`] kernel: `vpmaddwd` multiplies 16-bit pairs and adds
//! each pair into one 32-bit lane (no saturation: 2·255·128 < 2³¹). Block: the 4 channels of
//! the weight block × 16 pixels (8 accumulators of 8 lanes), twice per call.

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};
use core::arch::x86_64::*;

/// Same contract as [`crate::kernels::dot::portable`] for pairs. Returns `false` (and does
/// nothing) if this CPU lacks AVX2 or a read would leave the slices.
pub fn pairs(t: &Task<i16, i16>, acc: &mut Acc) -> bool {
    if !crate::kernels::isa::Isa::Avx2.available() || !t.in_bounds(2) {
        return false;
    }
    // SAFETY: AVX2 is available and every read is in bounds (both checked).
    unsafe { pairs_avx2(t, acc) };
    true
}

/// # Safety
/// The CPU must have AVX2 and `t.in_bounds(2)` must hold (every row and weight read of the
/// block lies inside `t.rows` and `t.weights`); [`pairs`] checks both.
#[target_feature(enable = "avx2")]
unsafe fn pairs_avx2(t: &Task<i16, i16>, acc: &mut Acc) {
    const _: () = assert!(NB == 4 && PB.is_multiple_of(16));
    for half in 0..PB / 16 {
        let mut c = [_mm256_setzero_si256(); 8];
        let mut wq = t.weights.as_ptr() as *const i32;
        let row = t.rows.as_ptr().add(2 * (t.ox0 + 16 * half));
        for &step in t.steps.iter() {
            {
                let pr = row.add(step as usize);
                let x0 = _mm256_loadu_si256(pr as *const __m256i);
                let x1 = _mm256_loadu_si256(pr.add(16) as *const __m256i);
                for j in 0..NB {
                    let b = _mm256_set1_epi32(wq.add(j).read_unaligned());
                    c[2 * j] = _mm256_add_epi32(c[2 * j], _mm256_madd_epi16(x0, b));
                    c[2 * j + 1] = _mm256_add_epi32(c[2 * j + 1], _mm256_madd_epi16(x1, b));
                }
                wq = wq.add(NB);
            }
        }
        for j in 0..NB {
            let dst = acc.as_mut_ptr().add(j * PB + 16 * half) as *mut __m256i;
            _mm256_storeu_si256(dst, c[2 * j]);
            _mm256_storeu_si256(dst.add(1), c[2 * j + 1]);
        }
    }
}
