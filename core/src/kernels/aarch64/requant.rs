//! NEON conv requantisation, 8 accumulators per pass: the scalar `requant_row` of
//! [`crate::kernels::conv`] (TFLite `MultiplyByQuantizedMultiplier` for right shifts, LeakyReLU's
//! second multiplier for negative sums, zero point, clamp) in exact integer arithmetic.
//! `SQRDMULH` is `⌊(x·m + 2³⁰) / 2³¹⌋` exactly (it saturates only for `x = m = −2³¹`, and
//! `m ≥ 0` here); `SRSHL` by `−e` is `⌊(q + 2^(e−1)) / 2^e⌋` without overflow, so subtracting
//! 1 from negative `q` first (`q > −2³¹` since `m < 2³¹`) rounds half away from zero as
//! `RoundingDivideByPOT` does.

use crate::kernels::conv::RowQuant;
use core::arch::aarch64::*;

/// Requantises each of the `consts.len()` rows of `acc` (row `j` at `j·acc_stride`, `n` sums)
/// into `out` at `at + j·out_stride`: 8 at a time with NEON, the last `n mod 8` through `tail`.
/// Returns `false` (and does nothing) where a row is not `simple` or a slice is short.
#[allow(clippy::too_many_arguments)]
pub fn block(
    consts: &[RowQuant],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    tail: impl Fn(&RowQuant, i32) -> i8,
) -> bool {
    let rows = consts.len();
    let fits = rows == 0
        || ((rows - 1) * acc_stride + n <= acc.len()
            && at + (rows - 1) * out_stride + n <= out.len());
    if !crate::kernels::isa::Isa::Neon.available() || !fits || !consts.iter().all(|k| k.simple) {
        return false;
    }
    for (j, k) in consts.iter().enumerate() {
        let a = &acc[j * acc_stride..j * acc_stride + n];
        let o = &mut out[at + j * out_stride..at + j * out_stride + n];
        // SAFETY: NEON is available (checked); `row` reads and writes whole groups of 8 inside
        // `a` and `o`, which hold `n` each.
        let done = unsafe { row(k, a, o) };
        for (d, &v) in o[done..].iter_mut().zip(&a[done..]) {
            *d = tail(k, v);
        }
    }
    true
}

/// Requantises the leading multiple of 8 of `acc` (`k.base` added) into `out` (`acc.len() ≥
/// out.len()`); returns how many it did.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
unsafe fn row(k: &RowQuant, acc: &[i32], out: &mut [i8]) -> usize {
    let n = out.len().min(acc.len()) / 8 * 8;
    let base = vdupq_n_s32(k.base);
    let (pm, nm) = (vdupq_n_s32(k.pos_m), vdupq_n_s32(k.neg_m));
    let (pe, ne) = (vdupq_n_s32(-k.pos_r), vdupq_n_s32(-k.neg_r));
    let (zp, lo, hi) = (vdupq_n_s32(k.zp), vdupq_n_s32(k.min), vdupq_n_s32(k.max));
    let one = |v: int32x4_t| -> int32x4_t {
        let x = vaddq_s32(base, v);
        let neg = vcltzq_s32(x);
        let m = vbslq_s32(neg, nm, pm);
        let e = vbslq_s32(neg, ne, pe);
        let q = vqrdmulhq_s32(x, m);
        // −1 where q < 0 and there is a shift (e < 0 here is a right shift).
        let adj = vandq_u32(vcltzq_s32(q), vcltzq_s32(e));
        let q = vaddq_s32(q, vreinterpretq_s32_u32(adj));
        let r = vrshlq_s32(q, e);
        vminq_s32(vmaxq_s32(vqaddq_s32(r, zp), lo), hi)
    };
    let mut i = 0;
    while i < n {
        let p = acc.as_ptr().add(i);
        let r0 = one(vld1q_s32(p));
        let r1 = one(vld1q_s32(p.add(4)));
        let h = vcombine_s16(vmovn_s32(r0), vmovn_s32(r1));
        vst1_s8(out.as_mut_ptr().add(i), vmovn_s16(h));
        i += 8;
    }
    n
}
