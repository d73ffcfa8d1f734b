//! AVX2 `exp`, bit for bit `crate::fmath::exp_f32` per lane: the same IEEE operations in the
//! same order (no FMA), the special cases blended in at the end.

use core::arch::x86_64::*;

/// `exp` of 8 lanes.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn exp_ps(x: __m256) -> __m256 {
    const LOG2_E: f32 = core::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let set = _mm256_set1_ps;
    let kf = _mm256_mul_ps(x, set(LOG2_E));
    let nonneg = _mm256_cmp_ps::<_CMP_GE_OQ>(kf, _mm256_setzero_ps());
    let t = _mm256_blendv_ps(
        _mm256_sub_ps(kf, set(0.5)),
        _mm256_add_ps(kf, set(0.5)),
        nonneg,
    );
    let k = _mm256_cvttps_epi32(t);
    let kfl = _mm256_cvtepi32_ps(k);
    let r = _mm256_sub_ps(
        _mm256_sub_ps(x, _mm256_mul_ps(kfl, set(LN2_HI))),
        _mm256_mul_ps(kfl, set(LN2_LO)),
    );
    let mut p = _mm256_mul_ps(r, set(1.0 / 5040.0));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(1.0 / 720.0), p));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(1.0 / 120.0), p));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(1.0 / 24.0), p));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(1.0 / 6.0), p));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(0.5), p));
    p = _mm256_mul_ps(r, _mm256_add_ps(set(1.0), p));
    p = _mm256_add_ps(set(1.0), p);
    // k1 = k / 2 (toward zero), k2 = k − k1.
    let k1 = _mm256_srai_epi32::<1>(_mm256_add_epi32(k, _mm256_srli_epi32::<31>(k)));
    let k2 = _mm256_sub_epi32(k, k1);
    let pow2 = |e: __m256i| {
        _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(
            e,
            _mm256_set1_epi32(127),
        )))
    };
    let mut y = _mm256_mul_ps(_mm256_mul_ps(p, pow2(k1)), pow2(k2));
    let under = _mm256_cmp_ps::<_CMP_LT_OQ>(x, set(-103.972_08));
    let over = _mm256_cmp_ps::<_CMP_GT_OQ>(x, set(88.722_84));
    let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(x, x);
    y = _mm256_blendv_ps(y, _mm256_setzero_ps(), under);
    y = _mm256_blendv_ps(y, set(f32::INFINITY), over);
    _mm256_blendv_ps(y, x, nan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_equal_the_scalar_exp_bit_for_bit() {
        if !crate::kernels::isa::Isa::Avx2.available() {
            std::eprintln!("no AVX2 on this CPU: AVX2 exp not tested here");
            return;
        }
        let mut xs = std::vec::Vec::new();
        let mut x = -110.0f32;
        while x < 95.0 {
            xs.push(x);
            x += 0.000_731;
        }
        xs.extend([
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            88.722_84,
            -103.972_08,
        ]);
        while xs.len() % 8 != 0 {
            xs.push(1.0);
        }
        for c in xs.chunks_exact(8) {
            let mut got = [0f32; 8];
            // SAFETY: AVX2 is available (checked above).
            unsafe { _mm256_storeu_ps(got.as_mut_ptr(), exp_ps(_mm256_loadu_ps(c.as_ptr()))) };
            for (g, &x) in got.iter().zip(c) {
                let want = crate::fmath::exp_f32(x);
                assert!(
                    g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan()),
                    "exp({x}) = {g} vs {want}"
                );
            }
        }
    }
}
