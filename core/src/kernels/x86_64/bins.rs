//! AVX2 adaptive-bins head, 8 pixels per vector: [`crate::kernels::bins::bins_head_i8`]'s
//! per-pixel logits (exact integer sums, `vpmaddwd` on channel pairs), max, exponentials and
//! sums in its order, so the bits equal the scalar path's.

use super::vmath::softmax_exp_ps;
use crate::kernels::bins::{BinChannel, MAX_BINS, MAX_BIN_FEATURES};
use core::arch::x86_64::*;

/// The head for the first `⌊p/8⌋·8` pixels; returns how many it did. Callers check
/// `features` holds `c × p` codes, `weights` `n × c`, `centres` and `channels` `n ≤ MAX_BINS`,
/// `c ≤ MAX_BIN_FEATURES`, `out` `p`.
///
/// # Safety
/// The CPU must have AVX2 and the lengths above must hold.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn head(
    features: &[i8],
    p: usize,
    c: usize,
    zp: i32,
    weights: &[i8],
    channels: &[BinChannel],
    centres: &[f32],
    out: &mut [f32],
) -> usize {
    let n = channels.len().min(centres.len()).min(MAX_BINS);
    let c = c.min(MAX_BIN_FEATURES);
    let pairs = c.div_ceil(2);
    // Weight pairs (w[b][2k], w[b][2k+1]) as i32 words: all bins' built once where they fit
    // `all` (16 KiB of stack), otherwise each bin's per chunk of pixels into `wp`.
    let pair_words = |b: usize, wp: &mut [i32]| {
        let row = &weights[b * c..(b + 1) * c];
        for (k, w) in wp[..pairs].iter_mut().enumerate() {
            let w0 = row[2 * k] as i16 as u16 as u32;
            let w1 = row.get(2 * k + 1).map_or(0, |&v| v as i16 as u16 as u32);
            *w = (w0 | (w1 << 16)) as i32;
        }
    };
    const ALL: usize = 4096;
    let mut all = [0i32; ALL];
    let hoisted = n * pairs <= ALL;
    if hoisted {
        for (b, wp) in all.chunks_exact_mut(pairs.max(1)).take(n).enumerate() {
            pair_words(b, wp);
        }
    }
    let mut wp = [0i32; MAX_BIN_FEATURES / 2];
    let mut x = [_mm256_setzero_si256(); MAX_BIN_FEATURES / 2];
    let mut logits = [_mm256_setzero_ps(); MAX_BINS];
    let zpv = _mm256_set1_epi32(zp);
    let mut i = 0;
    while i + 8 <= p {
        for (k, xk) in x[..pairs].iter_mut().enumerate() {
            let load = |ch: usize| {
                if ch < c {
                    let q = _mm_loadl_epi64(features.as_ptr().add(ch * p + i) as *const __m128i);
                    _mm256_sub_epi32(_mm256_cvtepi8_epi32(q), zpv)
                } else {
                    _mm256_setzero_si256()
                }
            };
            let (lo, hi) = (load(2 * k), load(2 * k + 1));
            // Each lane: low 16 bits channel 2k, high 16 bits channel 2k+1.
            *xk = _mm256_or_si256(
                _mm256_and_si256(lo, _mm256_set1_epi32(0xFFFF)),
                _mm256_slli_epi32::<16>(hi),
            );
        }
        for (b, (lg, ch)) in logits[..n].iter_mut().zip(channels).enumerate() {
            let words = if hoisted {
                &all[b * pairs..(b + 1) * pairs]
            } else {
                pair_words(b, &mut wp);
                &wp[..pairs]
            };
            let mut acc = _mm256_set1_epi32(ch.bias);
            for (xk, &w) in x[..pairs].iter().zip(words) {
                acc = _mm256_add_epi32(acc, _mm256_madd_epi16(*xk, _mm256_set1_epi32(w)));
            }
            *lg = _mm256_mul_ps(_mm256_cvtepi32_ps(acc), _mm256_set1_ps(ch.scale));
        }
        let mut m = _mm256_set1_ps(f32::NEG_INFINITY);
        for lg in &logits[..n] {
            m = _mm256_max_ps(m, *lg);
        }
        let (mut s, mut d) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        for (lg, &cb) in logits[..n].iter().zip(centres) {
            let e = softmax_exp_ps(_mm256_sub_ps(*lg, m));
            s = _mm256_add_ps(s, e);
            d = _mm256_add_ps(d, _mm256_mul_ps(e, _mm256_set1_ps(cb)));
        }
        let pos = _mm256_cmp_ps::<_CMP_GT_OQ>(s, _mm256_setzero_ps());
        let r = _mm256_and_ps(_mm256_div_ps(d, s), pos);
        _mm256_storeu_ps(out.as_mut_ptr().add(i), r);
        i += 8;
    }
    i
}
