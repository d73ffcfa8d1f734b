//! NEON softmax weight, bit for bit `crate::fmath::softmax_exp` per lane: the same IEEE
//! operations in the same order (separate multiplies and adds, never fused), `FCVTZS`
//! truncating as Rust's `as` does (NaN → 0, saturating), the table's bytes read with `TBL`.

use crate::fmath::{EXP2_32THS, SOFTMAX_FLOOR, SOFTMAX_T, SOFTMAX_U};
use core::arch::aarch64::*;

/// `fmath`'s 2^(j/32) table at one address (it is a `const` there).
static TABLE: [u32; 32] = EXP2_32THS;

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
    // The table's 128 bytes read with `TBL`/`TBX` (64 bytes each): lane `i` takes bytes
    // `4j_i .. 4j_i + 4` (little-endian words), `4j < 128` so the byte products do not carry.
    let j = vreinterpretq_u32_s32(vandq_s32(n, vdupq_n_s32(31)));
    let bytes = vaddq_u32(
        vmulq_u32(j, vdupq_n_u32(0x0404_0404)),
        vdupq_n_u32(0x0302_0100),
    );
    let idx = vreinterpretq_u8_u32(bytes);
    let tp = TABLE.as_ptr() as *const u8;
    // SAFETY: the table is 32 words, 128 bytes, in a static; `u8` reads need no alignment.
    let (lo, hi) = unsafe { (vld1q_u8_x4(tp), vld1q_u8_x4(tp.add(64))) };
    let r = vqtbx4q_u8(vqtbl4q_u8(lo, idx), hi, vsubq_u8(idx, vdupq_n_u8(64)));
    let table = vreinterpretq_u32_u8(r);
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
