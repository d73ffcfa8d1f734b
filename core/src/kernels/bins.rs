//! Adaptive-bins head (docs/graph.md `bins_head`): per-pixel logits over `N` bins from a 1×1 conv
//! of the features (int8 × int8 → int32, never stored as a map), then a softmax-weighted sum of
//! bin centres → depth in metres.
//!
//! **Why f32 after the int32 logits.** A 128-way softmax needs logit differences resolved to a
//! few hundredths over a range of tens; an int8 logit (256 levels over that range) moves the
//! expectation by whole bins, and a fixed-point exp would need a 32-bit LUT pipeline like
//! TFLite's `SOFTMAX` with Q5.26 inputs. Cortex-M4F/M7 have a single-precision FPU, so the
//! logits are dequantised (`acc · s_F · s_w[i]`) and the softmax and expectation run in f32 in a
//! fixed order: `m = max l`, then for `i = 0..N` in order `e = E(l_i − m); S += e; D += e·c_i`,
//! result `D / S`, where `E` is [`scalar::softmax_exp`](super::scalar::softmax_exp) (`e^x` from a
//! 32-entry table of `2^(j/32)` and a cubic, within `3·10⁻⁷ + |x|·1.2·10⁻⁷` relative; 0 below
//! −80). No FMA is used (Rust never contracts `a*b+c`), so host and MCU give the same bits. The
//! output map is f32 metres.

use super::isa::Isa;
use super::{need, KernelError, Shape};

/// Most bins supported (stack arrays of this size hold logits and centres; 128 with the
/// `small-tables` feature).
#[cfg(not(feature = "small-tables"))]
pub const MAX_BINS: usize = 256;
/// Most feature channels supported by the int8 head (64 with the `small-tables` feature).
#[cfg(not(feature = "small-tables"))]
pub const MAX_BIN_FEATURES: usize = 512;
/// Most bins supported: the `small-tables` build (the shipped networks have 16 or 128; its
/// stack arrays hold this many).
#[cfg(feature = "small-tables")]
pub const MAX_BINS: usize = 128;
/// Most feature channels supported by the int8 head: the `small-tables` build (the shipped
/// networks have 12 or 16).
#[cfg(feature = "small-tables")]
pub const MAX_BIN_FEATURES: usize = 64;

/// Attributes of `bins_head`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinsAttrs {
    /// Number of bins `N` (≤ [`MAX_BINS`]).
    pub n_bins: usize,
    /// Lower end of the depth range, metres.
    pub min_depth: f32,
    /// Upper end of the depth range, metres.
    pub max_depth: f32,
}

/// Per-bin constants of the int8 head: int32 bias (units `s_F·s_w[i]`) and the logit scale.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C)]
pub struct BinChannel {
    /// Bias in accumulator units.
    pub bias: i32,
    /// `s_F · s_w[i]`: accumulator → logit.
    pub scale: f32,
}

/// Bin centres from the bin logits: `w_i = relu(l_i) + 0.1`, normalised; widths
/// `(max − min)·w_i`; `centre_i = min + Σ_{j<i} width_j + width_i/2`.
pub fn bin_centres(
    bin_logits: &[f32],
    attrs: &BinsAttrs,
    centres: &mut [f32],
) -> Result<(), KernelError> {
    let n = attrs.n_bins;
    if n == 0 || n > MAX_BINS || bin_logits.len() < n || centres.len() < n {
        return Err(KernelError::Shape);
    }
    let mut total = 0.0f32;
    for &l in &bin_logits[..n] {
        total += super::scalar::relu(l) + 0.1;
    }
    let range = attrs.max_depth - attrs.min_depth;
    let mut edge = attrs.min_depth;
    for (c, &l) in centres[..n].iter_mut().zip(bin_logits) {
        let width = range * ((super::scalar::relu(l) + 0.1) / total);
        *c = edge + width / 2.0;
        edge += width;
    }
    Ok(())
}

/// Softmax expectation `Σ softmax(l)_i · c_i` in the fixed order described in the module doc.
pub fn expected_depth(logits: &[f32], centres: &[f32]) -> f32 {
    // `if b > a` rather than `f32::max`, which is a libm call on Cortex-M (same result: NaN
    // logits are skipped either way, and ±0 give the same `exp(l − m)`).
    let m = logits
        .iter()
        .fold(f32::NEG_INFINITY, |a, &b| if b > a { b } else { a });
    expectation(logits, m, centres)
}

/// The softmax sums of [`expectation`]: `(Σ e_i, Σ e_i·c_i)` with `e_i = softmax_exp(l_i − m)`,
/// accumulated in bin order (with `arm-dsp` on Cortex-M, the spec its FPU loop is tested
/// against).
#[cfg(any(test, not(all(target_arch = "arm", feature = "arm-dsp"))))]
#[inline(always)]
fn softmax_sums(logits: &[f32], m: f32, centres: &[f32]) -> (f32, f32) {
    let (mut s, mut d) = (0.0f32, 0.0f32);
    for (&l, &c) in logits.iter().zip(centres) {
        // `l − m ≤ 0` (or NaN).
        let e = super::scalar::softmax_exp(l - m);
        s += e;
        d += e * c;
    }
    (s, d)
}

/// [`expected_depth`] given the logits' maximum `m` (as its fold finds it); the sums by the
/// Cortex-M FPU loop with `arm-dsp` (the same operations, the same bits).
#[inline(always)]
fn expectation(logits: &[f32], m: f32, centres: &[f32]) -> f32 {
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    let (s, d) = super::arm::bins::sums(logits, m, centres);
    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
    let (s, d) = softmax_sums(logits, m, centres);
    if s > 0.0 {
        d / s
    } else {
        0.0
    }
}

/// int8 head: `features` `[C,h,w]` with zero point `zp`, weights `[N, C]` int8, one
/// [`BinChannel`] per bin, `centres` from [`bin_centres`]; writes `h·w` metres. `isa`: the
/// kernel set (all give the same bits).
#[allow(clippy::too_many_arguments)]
pub fn bins_head_i8(
    isa: Isa,
    features: &[i8],
    shape: Shape,
    zp: i32,
    weights: &[i8],
    channels: &[BinChannel],
    centres: &[f32],
    out: &mut [f32],
) -> Result<(), KernelError> {
    let n = channels.len();
    let c = shape.c;
    need(features, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if n == 0
        || n > MAX_BINS
        || c == 0
        || c > MAX_BIN_FEATURES
        || Some(weights.len()) != n.checked_mul(c)
    {
        return Err(KernelError::Attr);
    }
    if centres.len() < n || out.len() < p {
        return Err(KernelError::Shape);
    }
    let lanes = match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512Vnni if Isa::Avx2.available() => {
            // SAFETY: AVX2 is available; the lengths were checked above.
            unsafe {
                super::x86_64::bins::head(features, p, c, zp, weights, channels, centres, out)
            }
        }
        #[cfg(target_arch = "aarch64")]
        Isa::Neon | Isa::NeonDot => {
            super::aarch64::bins::head(features, p, c, zp, weights, channels, centres, out)
        }
        _ => 0,
    };
    let mut col = [0i32; MAX_BIN_FEATURES];
    let mut logits = [0f32; MAX_BINS];
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    if isa == Isa::ArmDsp {
        use super::arm::dsp;
        let mut words = [0u32; MAX_BIN_FEATURES / 2];
        let mut sums = [0i32; MAX_BINS];
        // Heads of 12 features and up to 16 bins: bias, widened weights and scale per bin,
        // made once per call, then each pixel's logits and their maximum in one asm loop.
        let mut wide = [0u32; 16 * dsp::WIDE12_ROW];
        let wide12 = c == 12
            && dsp::WIDE12_ROW * n <= wide.len()
            && dsp::widen_rows12(weights, channels, n, &mut wide);
        let mut done = lanes;
        for (i, o) in out[..p].iter_mut().enumerate().skip(lanes) {
            let packed = if wide12 {
                let src = &features[i..];
                (words.first_chunk_mut::<6>())
                    .is_some_and(|six| dsp::pack12_strided(src, p, zp, six))
            } else {
                c.is_multiple_of(4) && dsp::pack_strided(&features[i..], p, zp, &mut words[..c / 2])
            };
            if !packed {
                let x = (0..c).map(|k| features[k * p + i] as i32 - zp);
                dsp::pack_pixel(x, &mut words[..c / 2]);
            }
            if wide12 {
                let wide = &wide[..dsp::WIDE12_ROW * n];
                let Some(m) = dsp::logits12(wide, &words[..6], &mut logits[..n]) else {
                    break;
                };
                *o = expectation(&logits[..n], m, &centres[..n]);
                done = i + 1;
                continue;
            }
            for (s, ch) in sums[..n].iter_mut().zip(channels) {
                *s = ch.bias;
            }
            if !dsp::dot_rows(weights, c, &words[..c / 2], &mut sums[..n]) {
                break;
            }
            // The logits and their maximum in one pass (the fold of `expected_depth`).
            let mut m = f32::NEG_INFINITY;
            for ((l, &s), ch) in logits[..n].iter_mut().zip(&sums[..n]).zip(channels) {
                *l = s as f32 * ch.scale;
                if *l > m {
                    m = *l;
                }
            }
            *o = expectation(&logits[..n], m, &centres[..n]);
            done = i + 1;
        }
        if done == p {
            return Ok(());
        }
    }
    for (i, o) in out[..p].iter_mut().enumerate().skip(lanes) {
        for (k, v) in col[..c].iter_mut().enumerate() {
            *v = features[k * p + i] as i32 - zp;
        }
        for ((l, ch), wrow) in logits[..n]
            .iter_mut()
            .zip(channels)
            .zip(weights.chunks_exact(c))
        {
            let mut acc = ch.bias;
            for (&w, &x) in wrow.iter().zip(&col[..c]) {
                acc = acc.wrapping_add(w as i32 * x);
            }
            *l = acc as f32 * ch.scale;
        }
        *o = expected_depth(&logits[..n], &centres[..n]);
    }
    Ok(())
}

/// f32 head (the float reference): weights `[N, C]`, bias `[N]`.
pub fn bins_head_f32(
    features: &[f32],
    shape: Shape,
    bin_logits: &[f32],
    weights: &[f32],
    bias: &[f32],
    attrs: &BinsAttrs,
    out: &mut [f32],
) -> Result<(), KernelError> {
    let n = attrs.n_bins;
    let c = shape.c;
    need(features, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if n == 0
        || n > MAX_BINS
        || Some(weights.len()) != n.checked_mul(c)
        || bias.len() < n
        || out.len() < p
    {
        return Err(KernelError::Shape);
    }
    let mut centres = [0f32; MAX_BINS];
    bin_centres(bin_logits, attrs, &mut centres)?;
    let mut logits = [0f32; MAX_BINS];
    for (i, o) in out[..p].iter_mut().enumerate() {
        for (b, l) in logits[..n].iter_mut().enumerate() {
            let mut acc = bias[b];
            for k in 0..c {
                acc += weights[b * c + k] * features[k * p + i];
            }
            *l = acc;
        }
        *o = expected_depth(&logits[..n], &centres[..n]);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::requant::QParams;
    use std::vec::Vec;

    #[test]
    fn centres_by_hand() {
        // logits 0.9, −5 → w = 1.0, 0.1 → 10/11, 1/11 of [1, 12]: widths 10, 1.
        let a = BinsAttrs {
            n_bins: 2,
            min_depth: 1.0,
            max_depth: 12.0,
        };
        let mut c = [0f32; 2];
        bin_centres(&[0.9, -5.0], &a, &mut c).unwrap();
        assert!(
            (c[0] - 6.0).abs() < 1e-5 && (c[1] - 11.5).abs() < 1e-5,
            "{c:?}"
        );
        assert!(bin_centres(&[0.0], &BinsAttrs { n_bins: 0, ..a }, &mut c).is_err());
    }

    #[test]
    fn expectation_by_hand() {
        // equal logits → mean of centres; one dominant logit → that centre.
        assert!((expected_depth(&[0.0, 0.0], &[2.0, 4.0]) - 3.0).abs() < 1e-5);
        assert!((expected_depth(&[40.0, 0.0], &[2.0, 4.0]) - 2.0).abs() < 1e-5);
        // ln 3 difference → weights 3/4, 1/4.
        assert!((expected_depth(&[1.0986123, 0.0], &[2.0, 4.0]) - 2.5).abs() < 1e-3);
    }

    /// The Cortex-M FPU loop of the softmax sums gives the Rust loop's bits: logits spread over
    /// ±100 around the maximum (so some fall below the −80 floor), a NaN, an infinity.
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    #[test]
    fn arm_softmax_sums_equal_the_loop() {
        for seed in 0..200u32 {
            let n = 1 + (seed as usize % 40);
            let logits: Vec<f32> = (0..n as u32)
                .map(|i| {
                    let h = (i ^ seed.wrapping_mul(2_654_435_761)).wrapping_mul(2_246_822_519);
                    match (seed % 50, i) {
                        (7, 3) => f32::NAN,
                        (9, 1) => f32::NEG_INFINITY,
                        _ => (h >> 8) as f32 / (1u32 << 24) as f32 * 200.0 - 100.0,
                    }
                })
                .collect();
            let centres: Vec<f32> = (0..n).map(|i| 0.2 + 0.37 * i as f32).collect();
            let m = logits
                .iter()
                .fold(f32::NEG_INFINITY, |a, &b| if b > a { b } else { a });
            let (s0, d0) = softmax_sums(&logits, m, &centres);
            let (s1, d1) = super::super::arm::bins::sums(&logits, m, &centres);
            assert_eq!(
                (s0.to_bits(), d0.to_bits()),
                (s1.to_bits(), d1.to_bits()),
                "{logits:?}"
            );
        }
    }

    /// Every kernel set gives the portable bits with many bins and features (the AVX2 head's
    /// weight pairs then do not fit its stack table and are made per chunk of pixels).
    #[test]
    fn wide_heads_agree_across_sets() {
        // 256 bins (128 under `small-tables`, its limit).
        let (c, n, h, w) = (40usize, MAX_BINS, 2usize, 9usize);
        let shape = Shape::new(c, h, w);
        let feats: Vec<i8> = (0..c * h * w).map(|i| ((i * 73 + 5) % 251) as i8).collect();
        let wq: Vec<i8> = (0..n * c).map(|i| ((i * 31 + 7) % 253) as i8).collect();
        let chans: Vec<BinChannel> = (0..n)
            .map(|i| BinChannel {
                bias: i as i32 * 13 - 1600,
                scale: 1e-4 * (1.0 + (i % 7) as f32),
            })
            .collect();
        let centres: Vec<f32> = (0..n).map(|i| 0.1 + 0.04 * i as f32).collect();
        let mut want = std::vec![0f32; h * w];
        let (f, ch, ce) = (&feats, &chans, &centres);
        bins_head_i8(Isa::Portable, f, shape, 3, &wq, ch, ce, &mut want).unwrap();
        for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
            let mut got = std::vec![0f32; h * w];
            bins_head_i8(isa, f, shape, 3, &wq, ch, ce, &mut got).unwrap();
            let same = got
                .iter()
                .zip(&want)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{} differs from the portable head", isa.name());
        }
    }

    /// Heads of 12 features (the Cortex-M path with widened weights, up to 16 bins) give the
    /// portable bits on every set, extremes of codes and weights included.
    #[test]
    fn twelve_feature_heads_agree_across_sets() {
        for n in [1usize, 2, 15, 16, 17] {
            let (c, h, w) = (12usize, 3usize, 5usize);
            let shape = Shape::new(c, h, w);
            let feats: Vec<i8> = (0..c * h * w)
                .map(|i| match i % 11 {
                    0 => -128,
                    1 => 127,
                    _ => ((i * 73 + 5) % 251) as i8,
                })
                .collect();
            let wq: Vec<i8> = (0..n * c)
                .map(|i| {
                    if i % 5 == 0 {
                        -128
                    } else {
                        ((i * 31 + 7) % 253) as i8
                    }
                })
                .collect();
            let chans: Vec<BinChannel> = (0..n)
                .map(|i| BinChannel {
                    bias: i as i32 * 13 - 160,
                    scale: 1e-3 * (1.0 + (i % 7) as f32),
                })
                .collect();
            let centres: Vec<f32> = (0..n).map(|i| 0.1 + 0.04 * i as f32).collect();
            let (f, ch, ce) = (&feats, &chans, &centres);
            let mut want = std::vec![0f32; h * w];
            bins_head_i8(Isa::Portable, f, shape, -3, &wq, ch, ce, &mut want).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut got = std::vec![0f32; h * w];
                bins_head_i8(isa, f, shape, -3, &wq, ch, ce, &mut got).unwrap();
                let same = got
                    .iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    same,
                    "{} differs from the portable head, {n} bins",
                    isa.name()
                );
            }
        }
    }

    #[test]
    fn int8_head_matches_float_head() {
        let (c, n, h, w) = (6usize, 16usize, 3usize, 4usize);
        let shape = Shape::new(c, h, w);
        let fq = QParams {
            scale: 0.05,
            zero_point: -7,
        };
        let feats: Vec<i8> = (0..c * h * w)
            .map(|i| ((i * 37 + 11) % 200) as i8)
            .collect();
        let wq: Vec<i8> = (0..n * c).map(|i| ((i * 53 + 5) % 255) as i8).collect();
        let ws: Vec<f32> = (0..n).map(|i| 0.002 + 0.0003 * i as f32).collect();
        let bias: Vec<i32> = (0..n).map(|i| i as i32 * 40 - 300).collect();
        let attrs = BinsAttrs {
            n_bins: n,
            min_depth: 0.1,
            max_depth: 10.0,
        };
        let bl: Vec<f32> = (0..n).map(|i| (i as f32 * 0.7).sin()).collect();
        let mut centres = [0f32; MAX_BINS];
        bin_centres(&bl, &attrs, &mut centres).unwrap();
        let chans: Vec<BinChannel> = (0..n)
            .map(|i| BinChannel {
                bias: bias[i],
                scale: fq.scale * ws[i],
            })
            .collect();
        let mut y = std::vec![0f32; h * w];
        bins_head_i8(
            Isa::Portable,
            &feats,
            shape,
            fq.zero_point,
            &wq,
            &chans,
            &centres[..n],
            &mut y,
        )
        .unwrap();
        // Every kernel set gives the portable path's bits.
        for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
            let mut z = std::vec![0f32; h * w];
            let (f, ch, ce) = (&feats, &chans, &centres[..n]);
            bins_head_i8(isa, f, shape, fq.zero_point, &wq, ch, ce, &mut z).unwrap();
            let same = z.iter().zip(&y).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{} differs from the portable head", isa.name());
        }
        let ff: Vec<f32> = feats.iter().map(|&q| fq.dequantize(q)).collect();
        let wf: Vec<f32> = wq
            .iter()
            .enumerate()
            .map(|(i, &q)| q as f32 * ws[i / c])
            .collect();
        let bf: Vec<f32> = (0..n).map(|i| bias[i] as f32 * fq.scale * ws[i]).collect();
        let mut r = std::vec![0f32; h * w];
        bins_head_f32(&ff, shape, &bl, &wf, &bf, &attrs, &mut r).unwrap();
        for (a, b) in y.iter().zip(&r) {
            assert!((a - b).abs() < 1e-4 * b.abs().max(1.0), "{a} vs {b}");
            assert!((0.1..=10.0).contains(a));
        }
    }
}
