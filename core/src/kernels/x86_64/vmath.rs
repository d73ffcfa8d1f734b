//! AVX2 softmax weight, bit for bit `crate::fmath::softmax_exp` per lane: the same IEEE
//! operations in the same order (no FMA), the table read by a gather.

use crate::fmath::{EXP2_32THS, SOFTMAX_FLOOR, SOFTMAX_T, SOFTMAX_U};
use core::arch::x86_64::*;

/// `softmax_exp` of 8 lanes (`x = l − max ≤ 0`, or NaN).
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn softmax_exp_ps(x: __m256) -> __m256 {
    let set = _mm256_set1_ps;
    let t = _mm256_mul_ps(x, set(SOFTMAX_T));
    // Truncation toward zero as Rust's `as` (they differ only for NaN and |t| ≥ 2^31, which give
    // a NaN lane or lie below the floor here).
    let n = _mm256_cvttps_epi32(t);
    let u = _mm256_mul_ps(_mm256_sub_ps(t, _mm256_cvtepi32_ps(n)), set(SOFTMAX_U));
    let mut p = _mm256_add_ps(set(0.5), _mm256_mul_ps(u, set(1.0 / 6.0)));
    p = _mm256_add_ps(set(1.0), _mm256_mul_ps(u, p));
    p = _mm256_add_ps(set(1.0), _mm256_mul_ps(u, p));
    let j = _mm256_and_si256(n, _mm256_set1_epi32(31));
    // SAFETY: every index is in 0..32, inside the table.
    let table = _mm256_i32gather_ps::<4>(EXP2_32THS.as_ptr() as *const f32, j);
    let q = _mm256_srai_epi32::<5>(n);
    let pow2 = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(
        q,
        _mm256_set1_epi32(127),
    )));
    let y = _mm256_mul_ps(_mm256_mul_ps(table, p), pow2);
    let below = _mm256_cmp_ps::<_CMP_LT_OQ>(x, set(SOFTMAX_FLOOR));
    _mm256_andnot_ps(below, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_equal_the_scalar_softmax_weight_bit_for_bit() {
        if !crate::kernels::isa::Isa::Avx2.available() {
            std::eprintln!("no AVX2 on this CPU: AVX2 softmax weight not tested here");
            return;
        }
        let mut xs = std::vec::Vec::new();
        let mut x = -85.0f32;
        while x <= 0.0 {
            xs.push(x);
            x += 0.000_731;
        }
        xs.extend([0.0, -0.0, f32::NAN, f32::NEG_INFINITY, -80.0, -80.000_01]);
        while xs.len() % 8 != 0 {
            xs.push(-1.0);
        }
        for c in xs.chunks_exact(8) {
            let mut got = [0f32; 8];
            // SAFETY: AVX2 is available (checked above).
            unsafe {
                _mm256_storeu_ps(
                    got.as_mut_ptr(),
                    softmax_exp_ps(_mm256_loadu_ps(c.as_ptr())),
                )
            };
            for (g, &x) in got.iter().zip(c) {
                let want = crate::fmath::softmax_exp(x);
                assert!(
                    g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan()),
                    "softmax_exp({x}) = {g} vs {want}"
                );
            }
        }
    }
}
