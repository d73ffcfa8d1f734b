//! NEON columns of the int8 bilinear resize into other parameters (`resize::narrow_row` with a
//! 32-bit rescale): per output column the two blended input columns read as one pair, then
//! `n = v[x0]·(den − f) + v[x0 + 1]·f`, `((n·k + bias) >> 32) >> shift_hi` (`SMULL` and
//! `ADDHN`, the high word of the 64-bit sum), the zero point and the int8 clamp (saturating
//! narrows): the scalar integers exactly.

use core::arch::aarch64::*;

/// The constants of the 32-bit rescale: `k`, `bias`, `shift_hi` (`0..32`), output zero point.
pub type Rescale = (i32, i64, u32, i32);

/// `orow[o]` for the leading multiple of 8 columns, `taps[o] = x0 | f << 16` with `x0` read
/// through `mask` (`v.len() > mask + 1`, else nothing is done); returns how many it did.
pub fn rescaled_cols(
    v: &[i32],
    taps: &[u32],
    mask: usize,
    den: i32,
    r: Rescale,
    orow: &mut [i8],
) -> usize {
    let n = orow.len().min(taps.len()) / 8 * 8;
    if !crate::kernels::isa::Isa::Neon.available() || v.len() <= mask + 1 || r.2 >= 32 {
        return 0;
    }
    // SAFETY: NEON is available; every column read is `x0 & mask` and the one after it, inside
    // `v` (checked); `n` taps and outputs exist. The resize's mask (255) as a constant: the
    // mask and the scaling of a column index are then one `UBFIZ`.
    unsafe {
        if mask == 255 {
            cols_neon(v, taps, Mask::<255>, den, r, &mut orow[..n])
        } else {
            cols_neon(v, taps, mask, den, r, &mut orow[..n])
        }
    };
    n
}

/// A column mask, known when compiling ([`Mask`]) or not (`usize`).
trait ColMask: Copy {
    /// The mask's value.
    fn get(self) -> usize;
}

impl ColMask for usize {
    #[inline(always)]
    fn get(self) -> usize {
        self
    }
}

/// The mask `M` as a constant.
#[derive(Clone, Copy)]
struct Mask<const M: usize>;

impl<const M: usize> ColMask for Mask<M> {
    #[inline(always)]
    fn get(self) -> usize {
        M
    }
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn cols_neon(
    v: &[i32],
    taps: &[u32],
    mask: impl ColMask,
    den: i32,
    r: Rescale,
    out: &mut [i8],
) {
    let mask = mask.get();
    let (k, bias, shift_hi, zp) = r;
    let (denv, biasv) = (vdupq_n_s32(den), vdupq_n_s64(bias));
    let (shift, zpv) = (vdupq_n_s32(-(shift_hi as i32)), vdupq_n_s32(zp));
    let vp = v.as_ptr();
    let four = |o: usize| -> int32x4_t {
        let tp = taps.as_ptr().add(o);
        let pair = |i: usize| vld1_s32(vp.add(*tp.add(i) as usize & mask));
        let (ab01, ab23) = (
            vcombine_s32(pair(0), pair(1)),
            vcombine_s32(pair(2), pair(3)),
        );
        let (a, b) = (vuzp1q_s32(ab01, ab23), vuzp2q_s32(ab01, ab23));
        let f = vreinterpretq_s32_u32(vshrq_n_u32::<16>(vld1q_u32(tp)));
        let n = vmlaq_s32(vmulq_s32(a, vsubq_s32(denv, f)), b, f);
        let lo = vaddhn_s64(vmull_n_s32(vget_low_s32(n), k), biasv);
        let hi = vaddhn_high_s64(lo, vmull_high_n_s32(n, k), biasv);
        vaddq_s32(vshlq_s32(hi, shift), zpv)
    };
    let mut o = 0;
    while o + 8 <= out.len() {
        let h = vcombine_s16(vqmovn_s32(four(o)), vqmovn_s32(four(o + 4)));
        vst1_s8(out.as_mut_ptr().add(o), vqmovn_s16(h));
        o += 8;
    }
}

/// `orow[o]` of the resize into the input's own parameters (`resize::narrow_row_same`): `n` as
/// in [`rescaled_cols`], then `n / d` rounded half away from zero (`(|n| + ⌊d/2⌋) / d` with the
/// sign put back) and clamped to int8, for the leading multiple of 8 columns; returns how many
/// it did (0 without NEON, where `v.len() ≤ mask + 1`, or where `d` is not in `1 ..= 65535`).
/// The quotient is an f32 `FDIV` truncated (`FCVTZS`), which is the integer quotient exactly:
/// `a = |n| + ⌊d/2⌋ ≤ 128.5·d < 2^24` is exact in f32, and where `a/d` is not an integer it lies
/// at least `1/d > 2^−16` below the next one while the rounding error of a quotient below 256
/// is at most `2^−17`.
pub fn same_cols(v: &[i32], taps: &[u32], mask: usize, den: i32, d: i32, orow: &mut [i8]) -> usize {
    let n = orow.len().min(taps.len()) / 8 * 8;
    if !crate::kernels::isa::Isa::Neon.available()
        || v.len() <= mask + 1
        || !(1..=65535).contains(&d)
    {
        return 0;
    }
    // SAFETY: NEON is available; every column read is `x0 & mask` and the one after it, inside
    // `v` (checked); `n` taps and outputs exist.
    unsafe {
        if mask == 255 {
            same_neon(v, taps, Mask::<255>, den, d, &mut orow[..n])
        } else {
            same_neon(v, taps, mask, den, d, &mut orow[..n])
        }
    };
    n
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn same_neon(v: &[i32], taps: &[u32], mask: impl ColMask, den: i32, d: i32, out: &mut [i8]) {
    let mask = mask.get();
    let denv = vdupq_n_s32(den);
    let (dv, half) = (vdupq_n_f32(d as f32), vdupq_n_s32(d / 2));
    let vp = v.as_ptr();
    let four = |o: usize| -> int32x4_t {
        let tp = taps.as_ptr().add(o);
        let pair = |i: usize| vld1_s32(vp.add(*tp.add(i) as usize & mask));
        let (ab01, ab23) = (
            vcombine_s32(pair(0), pair(1)),
            vcombine_s32(pair(2), pair(3)),
        );
        let (a, b) = (vuzp1q_s32(ab01, ab23), vuzp2q_s32(ab01, ab23));
        let f = vreinterpretq_s32_u32(vshrq_n_u32::<16>(vld1q_u32(tp)));
        let n = vmlaq_s32(vmulq_s32(a, vsubq_s32(denv, f)), b, f);
        let sign = vshrq_n_s32::<31>(n);
        let a = vaddq_s32(vsubq_s32(veorq_s32(n, sign), sign), half);
        let q = vcvtq_s32_f32(vdivq_f32(vcvtq_f32_s32(a), dv));
        vsubq_s32(veorq_s32(q, sign), sign)
    };
    let mut o = 0;
    while o + 8 <= out.len() {
        let h = vcombine_s16(vqmovn_s32(four(o)), vqmovn_s32(four(o + 4)));
        vst1_s8(out.as_mut_ptr().add(o), vqmovn_s16(h));
        o += 8;
    }
}
