//! NEON `e^x` and `ln x`, bit for bit the scalar routines per lane: the softmax weight
//! (`crate::fmath::softmax_exp`), the general `crate::fmath::exp_f32` and `crate::fmath::ln_f32`. The same IEEE
//! operations in the same order (separate multiplies and adds, never fused), `FCVTZS`
//! truncating as Rust's `as` does (NaN → 0, saturating), the softmax table's bytes read with
//! `TBL`.

use crate::fmath::{
    EXP2_32THS, EXP_MAX, EXP_MIN, LN2_HI, LN2_LO, LOG2_E, SOFTMAX_FLOOR, SOFTMAX_T, SOFTMAX_U,
};
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

/// `exp_f32` of 4 lanes (any input: NaN, infinities and both range limits as the scalar
/// routine treats them), written as `crate::fmath::exp_f32_lanes` writes it.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
#[inline]
pub unsafe fn exp_f32x4(x: float32x4_t) -> float32x4_t {
    let xc = vminq_f32(vmaxq_f32(x, vdupq_n_f32(EXP_MIN)), vdupq_n_f32(EXP_MAX));
    let kf = vmulq_f32(xc, vdupq_n_f32(LOG2_E));
    // `kf ± 0.5`, the sign taken from `kf`.
    let half = vbslq_f32(vdupq_n_u32(0x8000_0000), kf, vdupq_n_f32(0.5));
    let k = vcvtq_s32_f32(vaddq_f32(kf, half));
    let kfl = vcvtq_f32_s32(k);
    let r = vsubq_f32(
        vsubq_f32(xc, vmulq_f32(kfl, vdupq_n_f32(LN2_HI))),
        vmulq_f32(kfl, vdupq_n_f32(LN2_LO)),
    );
    // The degree-7 Horner polynomial of `exp_poly`, innermost first.
    let mut p = vaddq_f32(
        vdupq_n_f32(1.0 / 720.0),
        vmulq_f32(r, vdupq_n_f32(1.0 / 5040.0)),
    );
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0] {
        p = vaddq_f32(vdupq_n_f32(c), vmulq_f32(r, p));
    }
    // 2^k in two steps: k1 = k / 2 (toward zero), k2 = k − k1.
    let sign = vreinterpretq_s32_u32(vshrq_n_u32::<31>(vreinterpretq_u32_s32(k)));
    let k1 = vshrq_n_s32::<1>(vaddq_s32(k, sign));
    let k2 = vsubq_s32(k, k1);
    let pow2 =
        |e: int32x4_t| vreinterpretq_f32_s32(vshlq_n_s32::<23>(vaddq_s32(e, vdupq_n_s32(127))));
    let v = vmulq_f32(vmulq_f32(p, pow2(k1)), pow2(k2));
    let v = vreinterpretq_f32_u32(vbicq_u32(
        vreinterpretq_u32_f32(v),
        vcltq_f32(x, vdupq_n_f32(EXP_MIN)),
    ));
    let v = vbslq_f32(
        vcgtq_f32(x, vdupq_n_f32(EXP_MAX)),
        vdupq_n_f32(f32::INFINITY),
        v,
    );
    // NaN lanes (the only ones unequal to themselves) return themselves.
    vbslq_f32(vceqq_f32(x, x), v, x)
}

/// `ln_f32` of 4 lanes (NaN for NaN, zero, negative or subnormal lanes, `+inf` for `+inf`).
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
#[inline]
pub unsafe fn ln_f32x4(x: float32x4_t) -> float32x4_t {
    let bits = vreinterpretq_u32_f32(x);
    let e = vsubq_s32(
        vreinterpretq_s32_u32(vandq_u32(vshrq_n_u32::<23>(bits), vdupq_n_u32(0xff))),
        vdupq_n_s32(127),
    );
    let m = vreinterpretq_f32_u32(vorrq_u32(
        vandq_u32(bits, vdupq_n_u32(0x007f_ffff)),
        vdupq_n_u32(0x3f80_0000),
    ));
    // m > √2: halve it and count one more in the exponent (the mask is −1).
    let big = vcgtq_f32(m, vdupq_n_f32(core::f32::consts::SQRT_2));
    let m = vbslq_f32(big, vmulq_f32(m, vdupq_n_f32(0.5)), m);
    let e = vsubq_s32(e, vreinterpretq_s32_u32(big));
    let one = vdupq_n_f32(1.0);
    let s = vdivq_f32(vsubq_f32(m, one), vaddq_f32(m, one));
    let s2 = vmulq_f32(s, s);
    let mut t = vaddq_f32(
        vdupq_n_f32(2.0 / 7.0),
        vmulq_f32(s2, vdupq_n_f32(2.0 / 9.0)),
    );
    for c in [0.4, 2.0 / 3.0, 2.0] {
        t = vaddq_f32(vdupq_n_f32(c), vmulq_f32(s2, t));
    }
    let series = vmulq_f32(s, t);
    let ef = vcvtq_f32_s32(e);
    let v = vaddq_f32(
        vmulq_f32(ef, vdupq_n_f32(LN2_HI)),
        vaddq_f32(series, vmulq_f32(ef, vdupq_n_f32(LN2_LO))),
    );
    let v = vbslq_f32(vceqq_f32(x, vdupq_n_f32(f32::INFINITY)), x, v);
    // Not ≥ the smallest normal (NaN included): NaN.
    vbslq_f32(
        vcgeq_f32(x, vdupq_n_f32(f32::MIN_POSITIVE)),
        v,
        vdupq_n_f32(f32::NAN),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmath::tests::{bit_sweep, EXP_EDGES};

    /// Runs `lanes` on `xs` 4 at a time (padded with `pad`) and compares each lane with
    /// `scalar` bit for bit (any NaN equals any NaN).
    fn assert_lanes_equal(
        mut xs: std::vec::Vec<f32>,
        pad: f32,
        // SAFETY: a NEON routine, called below on the aarch64 targets these tests run on.
        lanes: unsafe fn(float32x4_t) -> float32x4_t,
        scalar: fn(f32) -> f32,
    ) {
        while !xs.len().is_multiple_of(4) {
            xs.push(pad);
        }
        for c in xs.chunks_exact(4) {
            let mut got = [0f32; 4];
            // SAFETY: NEON is part of every aarch64 target these tests run on; `got` and `c`
            // hold 4 floats each.
            unsafe { vst1q_f32(got.as_mut_ptr(), lanes(vld1q_f32(c.as_ptr()))) };
            for (g, &x) in got.iter().zip(c) {
                let want = scalar(x);
                assert!(
                    g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan()),
                    "f({x:e}) = {g:e} vs {want:e}"
                );
            }
        }
    }

    #[test]
    fn ln_lanes_equal_the_scalar_ln_bit_for_bit() {
        let edges = [
            f32::MIN_POSITIVE,
            core::f32::consts::SQRT_2,
            1.0,
            f32::INFINITY,
            0.0,
        ];
        let mut xs = bit_sweep(4099, &edges);
        let mut x = 0.05f32;
        while x < 20.0 {
            xs.push(x);
            x *= 1.000_13;
        }
        xs.extend([-1.0, -0.0, f32::NEG_INFINITY]);
        assert_lanes_equal(xs, 1.0, ln_f32x4, crate::fmath::ln_f32);
    }

    #[test]
    fn exp_lanes_equal_the_scalar_exp_bit_for_bit() {
        let mut xs = bit_sweep(4099, &EXP_EDGES);
        let mut x = -110.0f32;
        while x < 90.0 {
            xs.push(x);
            x += 0.000_917;
        }
        assert_lanes_equal(xs, -1.0, exp_f32x4, crate::fmath::exp_f32);
    }

    #[test]
    fn lanes_equal_the_scalar_softmax_weight_bit_for_bit() {
        let mut xs = std::vec::Vec::new();
        let mut x = -85.0f32;
        while x <= 0.0 {
            xs.push(x);
            x += 0.000_731;
        }
        xs.extend([0.0, -0.0, f32::NAN, f32::NEG_INFINITY, -80.0, -80.000_01]);
        assert_lanes_equal(xs, -1.0, softmax_exp_f32x4, crate::fmath::softmax_exp);
    }
}
