//! AVX2 conv requantisation, 8 accumulators per vector: the scalar `requant_row` of
//! [`crate::kernels::conv`] (TFLite `MultiplyByQuantizedMultiplier` for right shifts, LeakyReLU's
//! second multiplier for negative sums, zero point, clamp) in exact integer arithmetic.

use core::arch::x86_64::*;

pub use crate::kernels::conv::RowQuant as RowConsts;

/// `trunc((a·b + nudge) / 2³¹)` of the even 32-bit lanes (`b ≥ 0`), in the low half of each
/// 64-bit lane.
///
/// # Safety
/// The CPU must have AVX2 (register-only arithmetic, no memory access).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn srdhm_even(a: __m256i, b: __m256i) -> __m256i {
    let ab = _mm256_mul_epi32(a, b);
    let neg = _mm256_cmpgt_epi64(_mm256_setzero_si256(), ab);
    let nudge = _mm256_blendv_epi8(
        _mm256_set1_epi64x(1 << 30),
        _mm256_set1_epi64x(1 - (1 << 30)),
        neg,
    );
    let t = _mm256_add_epi64(ab, nudge);
    let sign = _mm256_cmpgt_epi64(_mm256_setzero_si256(), t);
    let mag = _mm256_sub_epi64(_mm256_xor_si256(t, sign), sign);
    let q = _mm256_srli_epi64::<31>(mag);
    _mm256_sub_epi64(_mm256_xor_si256(q, sign), sign)
}

/// [`row`] for each of `consts.len()` channels: `acc` row `j` (stride `acc_stride`) into `out`
/// at `at + j·out_stride`, `n` elements each; the last `n mod 8` of each row through `tail`.
///
/// # Safety
/// The CPU must have AVX2; `acc` must hold `consts.len()` rows of `n`, and `out` every
/// `at + j·out_stride .. + n`.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn block(
    consts: &[RowConsts],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    tail: impl Fn(&RowConsts, i32) -> i8,
) {
    let rows = |k: &RowConsts, a: &[i32], o: &mut [i8]| row(k, a, o);
    block_with(consts, acc, acc_stride, n, out, at, out_stride, rows, tail)
}

/// [`block`] with 16 lanes first (AVX-512 F+BW): the same integer function, so the same bits.
///
/// # Safety
/// The CPU must have AVX-512 F and BW; the slice conditions of [`block`] hold.
#[target_feature(enable = "avx512f,avx512bw,avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn block512(
    consts: &[RowConsts],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    tail: impl Fn(&RowConsts, i32) -> i8,
) {
    let rows = |k: &RowConsts, a: &[i32], o: &mut [i8]| {
        let done = row512(k, a, o);
        done + row(k, &a[done..], &mut o[done..])
    };
    block_with(consts, acc, acc_stride, n, out, at, out_stride, rows, tail)
}

/// The loop of [`block`] / [`block512`] over channel rows with a given vector row function.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn block_with(
    consts: &[RowConsts],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    rows: impl Fn(&RowConsts, &[i32], &mut [i8]) -> usize,
    tail: impl Fn(&RowConsts, i32) -> i8,
) {
    for (j, k) in consts.iter().enumerate() {
        let a = &acc[j * acc_stride..j * acc_stride + n];
        let o = &mut out[at + j * out_stride..at + j * out_stride + n];
        let done = rows(k, a, o);
        for (d, &v) in o[done..].iter_mut().zip(&a[done..]) {
            *d = tail(k, v);
        }
    }
}

/// Requantises `acc` (`base` added) into `out`; `acc.len() ≥ out.len()`. Returns how many
/// leading elements it did (a multiple of 8); the caller finishes the rest.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn row(k: &RowConsts, acc: &[i32], out: &mut [i8]) -> usize {
    let n = out.len().min(acc.len()) / 8 * 8;
    let base = _mm256_set1_epi32(k.base);
    let (pm, nm) = (_mm256_set1_epi32(k.pos_m), _mm256_set1_epi32(k.neg_m));
    let (pr, nr) = (_mm256_set1_epi32(k.pos_r), _mm256_set1_epi32(k.neg_r));
    let one = _mm256_set1_epi32(1);
    let zero = _mm256_setzero_si256();
    let lim = _mm256_set1_epi32(1 << 24);
    let nlim = _mm256_set1_epi32(-(1 << 24));
    let (zp, lo, hi) = (
        _mm256_set1_epi32(k.zp),
        _mm256_set1_epi32(k.min),
        _mm256_set1_epi32(k.max),
    );
    let pick = _mm256_setr_epi32(0, 4, 0, 0, 0, 0, 0, 0);
    let mut i = 0;
    while i < n {
        let x = _mm256_add_epi32(
            base,
            _mm256_loadu_si256(acc.as_ptr().add(i) as *const __m256i),
        );
        let neg = _mm256_cmpgt_epi32(zero, x);
        let m = _mm256_blendv_epi8(pm, nm, neg);
        let e = _mm256_blendv_epi8(pr, nr, neg);
        let qe = srdhm_even(x, m);
        let qo = srdhm_even(_mm256_srli_epi64::<32>(x), _mm256_srli_epi64::<32>(m));
        let q = _mm256_blend_epi32::<0b1010_1010>(qe, _mm256_slli_epi64::<32>(qo));
        // RoundingDivideByPOT(q, e).
        let mask = _mm256_sub_epi32(_mm256_sllv_epi32(one, e), one);
        let rem = _mm256_and_si256(q, mask);
        let threshold = _mm256_sub_epi32(_mm256_srai_epi32::<1>(mask), _mm256_cmpgt_epi32(zero, q));
        let r = _mm256_sub_epi32(_mm256_srav_epi32(q, e), _mm256_cmpgt_epi32(rem, threshold));
        // saturating_add(zp) then clamp: clamping r to ±2^24 first changes nothing.
        let r = _mm256_min_epi32(_mm256_max_epi32(r, nlim), lim);
        let r = _mm256_min_epi32(_mm256_max_epi32(_mm256_add_epi32(r, zp), lo), hi);
        let w = _mm256_packs_epi32(r, r);
        let b = _mm256_packs_epi16(w, w);
        let b = _mm256_permutevar8x32_epi32(b, pick);
        _mm_storel_epi64(
            out.as_mut_ptr().add(i) as *mut __m128i,
            _mm256_castsi256_si128(b),
        );
        i += 8;
    }
    n
}

/// `trunc((a·b + nudge) / 2³¹)` of the even 32-bit lanes (`b ≥ 0`), 64-bit lanes.
///
/// # Safety
/// The CPU must have AVX-512 F (register-only arithmetic, no memory access).
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn srdhm_even512(a: __m512i, b: __m512i) -> __m512i {
    let ab = _mm512_mul_epi32(a, b);
    let neg = _mm512_cmplt_epi64_mask(ab, _mm512_setzero_si512());
    let nudge = _mm512_mask_blend_epi64(
        neg,
        _mm512_set1_epi64(1 << 30),
        _mm512_set1_epi64(1 - (1 << 30)),
    );
    let t = _mm512_add_epi64(ab, nudge);
    // Division by 2^31 toward zero: add 2^31 − 1 to negative values, then shift.
    let tneg = _mm512_cmplt_epi64_mask(t, _mm512_setzero_si512());
    let t = _mm512_mask_add_epi64(t, tneg, t, _mm512_set1_epi64((1 << 31) - 1));
    _mm512_srai_epi64::<31>(t)
}

/// [`row`] with 16 lanes; returns how many leading elements it did (a multiple of 16).
///
/// # Safety
/// The CPU must have AVX-512 F and BW; it reads and writes only the first
/// `min(out.len(), acc.len())` rounded down to 16 elements of each slice.
#[target_feature(enable = "avx512f,avx512bw")]
#[inline]
unsafe fn row512(k: &RowConsts, acc: &[i32], out: &mut [i8]) -> usize {
    let n = out.len().min(acc.len()) / 16 * 16;
    let base = _mm512_set1_epi32(k.base);
    let (pm, nm) = (_mm512_set1_epi32(k.pos_m), _mm512_set1_epi32(k.neg_m));
    let (pr, nr) = (_mm512_set1_epi32(k.pos_r), _mm512_set1_epi32(k.neg_r));
    let one = _mm512_set1_epi32(1);
    let zero = _mm512_setzero_si512();
    let (zp, lo, hi) = (
        _mm512_set1_epi32(k.zp),
        _mm512_set1_epi32(k.min),
        _mm512_set1_epi32(k.max),
    );
    let mut i = 0;
    while i < n {
        let x = _mm512_add_epi32(
            base,
            _mm512_loadu_si512(acc.as_ptr().add(i) as *const __m512i),
        );
        let neg = _mm512_cmplt_epi32_mask(x, zero);
        let m = _mm512_mask_blend_epi32(neg, pm, nm);
        let e = _mm512_mask_blend_epi32(neg, pr, nr);
        let qe = srdhm_even512(x, m);
        let qo = srdhm_even512(_mm512_srli_epi64::<32>(x), _mm512_srli_epi64::<32>(m));
        let q = _mm512_mask_blend_epi32(0xAAAA, qe, _mm512_slli_epi64::<32>(qo));
        let mask = _mm512_sub_epi32(_mm512_sllv_epi32(one, e), one);
        let rem = _mm512_and_si512(q, mask);
        let qneg = _mm512_cmplt_epi32_mask(q, zero);
        let threshold = _mm512_mask_add_epi32(
            _mm512_srai_epi32::<1>(mask),
            qneg,
            _mm512_srai_epi32::<1>(mask),
            one,
        );
        let up = _mm512_cmpgt_epi32_mask(rem, threshold);
        let r = _mm512_srav_epi32(q, e);
        let r = _mm512_mask_add_epi32(r, up, r, one);
        // saturating_add(zp) then clamp: clamping r to ±2^24 first changes nothing.
        let r = _mm512_min_epi32(
            _mm512_max_epi32(r, _mm512_set1_epi32(-(1 << 24))),
            _mm512_set1_epi32(1 << 24),
        );
        let r = _mm512_min_epi32(_mm512_max_epi32(_mm512_add_epi32(r, zp), lo), hi);
        _mm_storeu_si128(
            out.as_mut_ptr().add(i) as *mut __m128i,
            _mm512_cvtepi32_epi8(r),
        );
        i += 16;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::requant::Requant;

    #[test]
    fn equals_requant_apply_over_the_whole_range() {
        if !crate::kernels::isa::Isa::Avx2.available() {
            std::eprintln!("no AVX2 on this CPU: AVX2 requantisation not tested here");
            return;
        }
        let mut s = 99u64;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 32) as u32
        };
        for case in 0..400 {
            let pos = Requant {
                multiplier: (1 << 30) + (next() >> 2) as i32,
                shift: -((next() % 32) as i32),
            };
            let neg = Requant {
                multiplier: if case % 3 == 0 {
                    pos.multiplier
                } else {
                    (1 << 30) + (next() >> 2) as i32
                },
                shift: if case % 3 == 0 {
                    pos.shift
                } else {
                    -((next() % 32) as i32)
                },
            };
            let k = RowConsts {
                simple: true,
                base: next() as i32 >> (next() % 32),
                pos_m: pos.multiplier,
                neg_m: neg.multiplier,
                pos_r: -pos.shift,
                neg_r: -neg.shift,
                zp: (next() % 256) as i32 - 128,
                min: -128 + (next() % 64) as i32,
                max: 127,
                narrow: false,
            };
            let mut acc: std::vec::Vec<i32> =
                (0..64).map(|_| (next() as i32) >> (next() % 32)).collect();
            acc[0] = i32::MIN.wrapping_sub(k.base);
            acc[1] = i32::MAX.wrapping_sub(k.base);
            acc[2] = -k.base;
            let mut out = [0i8; 64];
            // SAFETY: AVX2 is available (checked above).
            assert_eq!(unsafe { row(&k, &acc, &mut out) }, 64);
            let mut out512 = [0i8; 64];
            if crate::kernels::isa::Isa::Avx512Vnni.available() {
                // SAFETY: AVX-512 F/BW are available (checked).
                assert_eq!(unsafe { row512(&k, &acc, &mut out512) }, 64);
                assert_eq!(out512, out, "16-lane requantisation differs from 8-lane");
            }
            for (o, &a) in out.iter().zip(&acc) {
                let x = k.base.wrapping_add(a);
                let r = if x >= 0 { pos.apply(x) } else { neg.apply(x) };
                let want = r.saturating_add(k.zp).clamp(k.min, k.max) as i8;
                assert_eq!(*o, want, "x={x} pos={pos:?} neg={neg:?}");
            }
        }
    }
}
