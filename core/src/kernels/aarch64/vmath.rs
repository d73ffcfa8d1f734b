//! NEON softmax weight, bit for bit `crate::fmath::softmax_exp` per lane: the same IEEE
//! operations in the same order (separate multiplies and adds, never fused), `FCVTZS`
//! truncating as Rust's `as` does (NaN → 0, saturating), the table read lane by lane.

use crate::fmath::{EXP2_32THS, SOFTMAX_FLOOR, SOFTMAX_T, SOFTMAX_U};
use core::arch::aarch64::*;

/// `softmax_exp` of 4 lanes (`x = l − max ≤ 0`, or NaN).
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
#[inline]
pub unsafe fn softmax_exp_f32x4(x: float32x4_t) -> float32x4_t {
    let t = vmulq_f32(x, vdupq_n_f32(SOFTMAX_T));
    let n = vcvtq_s32_f32(t);
    let u = vmulq_f32(vsubq_f32(t, vcvtq_f32_s32(n)), vdupq_n_f32(SOFTMAX_U));
    let mut p = vaddq_f32(vdupq_n_f32(0.5), vmulq_f32(u, vdupq_n_f32(1.0 / 6.0)));
    p = vaddq_f32(vdupq_n_f32(1.0), vmulq_f32(u, p));
    p = vaddq_f32(vdupq_n_f32(1.0), vmulq_f32(u, p));
    let j = vandq_s32(n, vdupq_n_s32(31));
    let mut table = vdupq_n_u32(0);
    table = vsetq_lane_u32::<0>(EXP2_32THS[vgetq_lane_s32::<0>(j) as usize & 31], table);
    table = vsetq_lane_u32::<1>(EXP2_32THS[vgetq_lane_s32::<1>(j) as usize & 31], table);
    table = vsetq_lane_u32::<2>(EXP2_32THS[vgetq_lane_s32::<2>(j) as usize & 31], table);
    table = vsetq_lane_u32::<3>(EXP2_32THS[vgetq_lane_s32::<3>(j) as usize & 31], table);
    let q = vshrq_n_s32::<5>(n);
    let pow2 = vreinterpretq_f32_s32(vshlq_n_s32::<23>(vaddq_s32(q, vdupq_n_s32(127))));
    let y = vmulq_f32(vmulq_f32(vreinterpretq_f32_u32(table), p), pow2);
    let below = vcltq_f32(x, vdupq_n_f32(SOFTMAX_FLOOR));
    vreinterpretq_f32_u32(vbicq_u32(vreinterpretq_u32_f32(y), below))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_equal_the_scalar_softmax_weight_bit_for_bit() {
        let mut xs = std::vec::Vec::new();
        let mut x = -85.0f32;
        while x <= 0.0 {
            xs.push(x);
            x += 0.000_731;
        }
        xs.extend([0.0, -0.0, f32::NAN, f32::NEG_INFINITY, -80.0, -80.000_01]);
        while xs.len() % 4 != 0 {
            xs.push(-1.0);
        }
        for c in xs.chunks_exact(4) {
            let mut got = [0f32; 4];
            // SAFETY: NEON is part of every aarch64 target these tests run on.
            unsafe { vst1q_f32(got.as_mut_ptr(), softmax_exp_f32x4(vld1q_f32(c.as_ptr()))) };
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
