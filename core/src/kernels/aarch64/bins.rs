//! NEON adaptive-bins head, 8 pixels per pass: [`crate::kernels::bins::bins_head_i8`]'s
//! per-pixel logits (exact integer sums, `SMLAL` by a scalar weight on 16-bit `x − zp`), max
//! (the scalar fold's `if l > m`), exponentials and sums in its order, so the bits equal the
//! scalar path's.

use super::vmath::softmax_exp_f32x4;
use crate::kernels::bins::{BinChannel, MAX_BINS, MAX_BIN_FEATURES};
use core::arch::aarch64::*;

/// The head for the first `⌊p/8⌋·8` pixels; returns how many it did (0 without NEON or where
/// a length does not hold: `features` `c × p` codes, `weights` `n × c`, `centres` `n`,
/// `c ≤ MAX_BIN_FEATURES`, `n ≤ MAX_BINS`, `out` `p`).
#[allow(clippy::too_many_arguments)]
pub fn head(
    features: &[i8],
    p: usize,
    c: usize,
    zp: i32,
    weights: &[i8],
    channels: &[BinChannel],
    centres: &[f32],
    out: &mut [f32],
) -> usize {
    let n = channels.len();
    let ok = n <= MAX_BINS
        && c <= MAX_BIN_FEATURES
        && centres.len() >= n
        && weights.len() >= n * c
        && features.len() >= c * p
        && out.len() >= p
        && i16::try_from(zp).is_ok();
    if !crate::kernels::isa::Isa::Neon.available() || !ok {
        return 0;
    }
    // SAFETY: NEON is available and the lengths hold (both checked).
    unsafe { head_neon(features, p, c, zp, weights, channels, centres, out) }
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn head_neon(
    features: &[i8],
    p: usize,
    c: usize,
    zp: i32,
    weights: &[i8],
    channels: &[BinChannel],
    centres: &[f32],
    out: &mut [f32],
) -> usize {
    let n = channels.len();
    let mut x = [vdupq_n_s16(0); MAX_BIN_FEATURES];
    let mut logits = [[vdupq_n_f32(0.0); 2]; MAX_BINS];
    let zpv = vdupq_n_s16(zp as i16);
    // Each bin's last `c mod 8` weights widened and padded with zeros to eight lanes (zero
    // weights add nothing), so the last channels take one more lane group too; `x` past `c`
    // stays zero and inside the array (`c ≤ MAX_BIN_FEATURES`, a multiple of 8).
    let full = c / 8 * 8;
    let mut tails = [[0i16; 8]; MAX_BINS];
    for (t, wrow) in tails[..n].iter_mut().zip(weights.chunks_exact(c.max(1))) {
        for (t, &w) in t.iter_mut().zip(&wrow[full..]) {
            *t = i16::from(w);
        }
    }
    let mut i = 0;
    while i + 8 <= p {
        for (k, xk) in x[..c].iter_mut().enumerate() {
            // |x − zp| ≤ 255: exact in 16 bits.
            *xk = vsubq_s16(vmovl_s8(vld1_s8(features.as_ptr().add(k * p + i))), zpv);
        }
        for (((lg, ch), wrow), tail) in logits[..n]
            .iter_mut()
            .zip(channels)
            .zip(weights.chunks_exact(c.max(1)))
            .zip(&tails)
        {
            let (mut lo, mut hi) = (vdupq_n_s32(ch.bias), vdupq_n_s32(ch.bias));
            // Eight channels at a time with their weights widened into one register and read
            // by lane (integer sums: exact in any order), the last group's from `tails`.
            let mut k = 0;
            while k < c {
                let w8 = if k < full {
                    vmovl_s8(vld1_s8(wrow.as_ptr().add(k)))
                } else {
                    vld1q_s16(tail.as_ptr())
                };
                let xs = &x[k..k + 8];
                macro_rules! lane {
                    ($l:literal) => {
                        mla8_lane::<$l>(&mut lo, &mut hi, xs[$l], w8)
                    };
                }
                lane!(0);
                lane!(1);
                lane!(2);
                lane!(3);
                // A last group of at most 4 channels: its other lanes' weights are zero.
                if c - k > 4 {
                    lane!(4);
                    lane!(5);
                    lane!(6);
                    lane!(7);
                }
                k += 8;
            }
            lg[0] = vmulq_n_f32(vcvtq_f32_s32(lo), ch.scale);
            lg[1] = vmulq_n_f32(vcvtq_f32_s32(hi), ch.scale);
        }
        for half in 0..2 {
            let mut m = vdupq_n_f32(f32::NEG_INFINITY);
            for lg in &logits[..n] {
                m = vbslq_f32(vcgtq_f32(lg[half], m), lg[half], m);
            }
            let (mut s, mut d) = (vdupq_n_f32(0.0), vdupq_n_f32(0.0));
            for (lg, &cb) in logits[..n].iter().zip(centres) {
                let e = softmax_exp_f32x4(vsubq_f32(lg[half], m));
                s = vaddq_f32(s, e);
                d = vaddq_f32(d, vmulq_n_f32(e, cb));
            }
            let pos = vcgtq_f32(s, vdupq_n_f32(0.0));
            let r = vreinterpretq_f32_u32(vandq_u32(vreinterpretq_u32_f32(vdivq_f32(d, s)), pos));
            vst1q_f32(out.as_mut_ptr().add(i + 4 * half), r);
        }
        i += 8;
    }
    i
}

/// `lo += x[0..4] · w[L]`, `hi += x[4..8] · w[L]` (`SMLAL`/`SMLAL2` by element, with `asm!`:
/// LLVM turns the high half of a lane-broadcast weight into a lane move and a low `SMLAL`).
///
/// # Safety
/// The CPU must have NEON.
#[inline(always)]
unsafe fn mla8_lane<const L: i32>(
    lo: &mut int32x4_t,
    hi: &mut int32x4_t,
    x: int16x8_t,
    w: int16x8_t,
) {
    // SAFETY (caller): the CPU has NEON; registers only, no memory, flags untouched.
    core::arch::asm!(
        "smlal {lo:v}.4s, {x:v}.4h, {w:v}.h[{l}]",
        "smlal2 {hi:v}.4s, {x:v}.8h, {w:v}.h[{l}]",
        lo = inout(vreg) *lo,
        hi = inout(vreg) *hi,
        x = in(vreg) x,
        w = in(vreg_low16) w,
        l = const L,
        options(pure, nomem, nostack, preserves_flags)
    );
}
