//! Global pools (`[C,H,W] → [C,1,1]`) and channel reductions (`[C,H,W] → [1,H,W]`) in int8.
//! Means sum `q − zp_in` exactly in `i32` and requantise once with `s_in/(s_out·n)`; maxima take
//! the largest code and requantise it. One pass over memory each; with `arm-dsp` the sums and
//! maxima take four bytes per word ([`super::arm::bytes`]), the same integers.

use super::elementwise::Rescale;
use super::isa::Isa;
use super::requant::{clamp_i8, QParams, Requant};
use super::{need, KernelError, Shape};

/// The sum of `x` (four bytes per word with `arm-dsp`).
fn sum_i8(x: &[i8]) -> i32 {
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    return super::arm::bytes::sum_i8(x);
    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
    x.iter().map(|&v| i32::from(v)).sum()
}

/// The largest of `x` (`i8::MIN` when empty; four bytes per word with `arm-dsp`).
fn max_i8(x: &[i8]) -> i8 {
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    return super::arm::bytes::max_i8(x);
    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
    x.iter().copied().max().unwrap_or(i8::MIN)
}

/// Largest reduction length accepted (keeps the `i32` sum of `±255` terms exact).
pub const MAX_REDUCE: usize = 1 << 23;

/// Constants of an int8 mean over `n` elements.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct MeanQuant {
    /// Input zero point.
    pub zp_in: i32,
    /// Output zero point.
    pub zp_out: i32,
    /// `s_in/(s_out·n)`.
    pub m: Requant,
}

impl MeanQuant {
    /// For a mean over `n` elements.
    pub fn new(in_q: QParams, out_q: QParams, n: usize) -> MeanQuant {
        MeanQuant {
            zp_in: in_q.zero_point,
            zp_out: out_q.zero_point,
            m: Requant::from_real(in_q.scale as f64 / (out_q.scale as f64 * n.max(1) as f64)),
        }
    }

    #[inline]
    fn finish(&self, sum: i32) -> i8 {
        clamp_i8(
            self.m.apply_rounded(sum).saturating_add(self.zp_out),
            -128,
            127,
        )
    }
}

fn check(input: &[i8], shape: Shape, out: &[i8], out_len: usize) -> Result<usize, KernelError> {
    need(input, shape)?;
    let p = shape.plane().ok_or(KernelError::Shape)?;
    if out.len() < out_len || p == 0 || shape.c == 0 || p > MAX_REDUCE || shape.c > MAX_REDUCE {
        return Err(KernelError::Shape);
    }
    Ok(p)
}

/// Global average pool; `q` built with `n = H·W`.
pub fn global_avg_pool(
    q: &MeanQuant,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.c)?;
    for (c, o) in out[..shape.c].iter_mut().enumerate() {
        let plane = &input[c * p..(c + 1) * p];
        // Σ(x − zp) = Σx − n·zp, exact in i32 (n ≤ MAX_REDUCE).
        *o = q.finish(sum_i8(plane) - p as i32 * q.zp_in);
    }
    Ok(())
}

/// Global max pool, requantised with `r` (identity when input and output share parameters).
pub fn global_max_pool(
    r: &Rescale,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.c)?;
    for (c, o) in out[..shape.c].iter_mut().enumerate() {
        *o = r.apply(max_i8(&input[c * p..(c + 1) * p]));
    }
    Ok(())
}

/// Mean over channels; `q` built with `n = C` (the portable set's loops).
pub fn channel_mean(
    q: &MeanQuant,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    channel_mean_with(Isa::Portable, q, input, shape, out)
}

/// [`channel_mean`] with kernel set `isa`: `neon` and `neon-dot` sum 16 pixels per pass
/// ([`super::aarch64::pool::sums`], up to 256 channels); the same integers, so the same bits.
pub fn channel_mean_with(
    isa: Isa,
    q: &MeanQuant,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.h.saturating_mul(shape.w))?;
    #[cfg(target_arch = "aarch64")]
    let first = if matches!(isa, Isa::Neon | Isa::NeonDot) {
        let shift = shape.c as i32 * q.zp_in;
        super::aarch64::pool::sums(input, shape.c, p, |i, s| {
            for (o, &s) in out[i..i + 16].iter_mut().zip(s) {
                *o = q.finish(i32::from(s) - shift);
            }
        })
    } else {
        0
    };
    let _ = isa;
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    let first = if shape.c <= 256 {
        // Four pixels per word: channel c's bytes added to 16-bit lanes (≤ 256 per lane).
        use super::arm::bytes::{add4, halves, word};
        let shift = shape.c as i32 * q.zp_in;
        let mut first = 0;
        while first + 4 <= p {
            let (mut e, mut o) = (0u32, 0u32);
            for c in 0..shape.c {
                (e, o) = add4(e, o, word(&input[c * p + first..]));
            }
            let ((s0, s2), (s1, s3)) = (halves(e), halves(o));
            for (k, s) in [s0, s1, s2, s3].into_iter().enumerate() {
                out[first + k] = q.finish(s - shift);
            }
            first += 4;
        }
        first
    } else {
        0
    };
    #[cfg(not(any(target_arch = "aarch64", all(target_arch = "arm", feature = "arm-dsp"))))]
    let first = 0;
    for (i, o) in out[..p].iter_mut().enumerate().skip(first) {
        let mut sum = 0i32;
        for c in 0..shape.c {
            sum += input[c * p + i] as i32 - q.zp_in;
        }
        *o = q.finish(sum);
    }
    Ok(())
}

/// Max over channels, requantised with `r`.
pub fn channel_max(
    r: &Rescale,
    input: &[i8],
    shape: Shape,
    out: &mut [i8],
) -> Result<(), KernelError> {
    let p = check(input, shape, out, shape.h.saturating_mul(shape.w))?;
    out[..p].copy_from_slice(&input[..p]);
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    let first = {
        // Four pixels per word, every channel's word folded in before the one store.
        use super::arm::bytes::{max4, word};
        let mut first = 0;
        while first + 4 <= p {
            let mut m = word(&input[first..]);
            for c in 1..shape.c {
                m = max4(m, word(&input[c * p + first..]));
            }
            for (o, b) in out[first..first + 4].iter_mut().zip(m.to_le_bytes()) {
                *o = b as i8;
            }
            first += 4;
        }
        first
    };
    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
    let first = 0;
    for c in 1..shape.c {
        let plane = &input[c * p..(c + 1) * p];
        for (o, &x) in out[first..p].iter_mut().zip(&plane[first..]) {
            *o = (*o).max(x);
        }
    }
    if !r.is_identity() {
        for o in out[..p].iter_mut() {
            *o = r.apply(*o);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::float;
    use proptest::prelude::*;
    use std::vec::Vec;

    #[test]
    fn pools_by_hand() {
        let qi = QParams {
            scale: 0.5,
            zero_point: 2,
        };
        let qo = QParams {
            scale: 0.25,
            zero_point: -1,
        };
        let s = Shape::new(2, 1, 3);
        let x = [2, 4, 7, -2, 0, 2]; // real: 0 1 2.5 | −2 −1 0
        let mut y = [0i8; 3];
        global_avg_pool(&MeanQuant::new(qi, qo, 3), &x, s, &mut y).unwrap();
        // means 3.5/3 = 1.1667 → 4.667 → 5 − 1 = 4 ; −1 → −4 − 1 = −5
        assert_eq!(&y[..2], &[4, -5]);
        global_max_pool(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
        assert_eq!(&y[..2], &[9, -1]); // 2.5 → 10 − 1; 0 → −1
        channel_mean(&MeanQuant::new(qi, qo, 2), &x, s, &mut y).unwrap();
        assert_eq!(y, [-5, -1, 4]); // −1 → −5, 0 → −1, 1.25 → 5 − 1
        channel_max(&Rescale::new(qi, qi), &x, s, &mut y).unwrap();
        assert_eq!(y, [2, 4, 7]);
        assert_eq!(
            channel_max(&Rescale::new(qi, qi), &x[..5], s, &mut y),
            Err(KernelError::Shape)
        );
    }

    proptest! {
        /// Every pool equals a plain scalar oracle of its integers (the sums and maxima of the
        /// codes), bit for bit: with `arm-dsp` these are the four-bytes-per-word paths, over
        /// widths that are not multiples of four and channel counts past the 16-bit lanes'.
        #[test]
        fn pools_equal_scalar_integers(c in 1usize..300, h in 1usize..4, w in 1usize..23,
                                       zi in -128i32..128, seed in any::<u32>()) {
            let s = Shape::new(c, h, w);
            let p = h * w;
            let x: Vec<i8> = (0..s.len().unwrap())
                .map(|i| match (seed % 3, i % 7) {
                    (0, _) => -128,
                    (1, 3) => 127,
                    _ => ((i as u32).wrapping_mul(2654435761) ^ seed) as i8,
                })
                .collect();
            let (qi, qo) = (QParams { scale: 0.1, zero_point: zi }, QParams { scale: 0.07, zero_point: 3 });
            let plane = |k: usize| &x[k * p..(k + 1) * p];
            let mut y = std::vec![0i8; c.max(p)];
            let q = MeanQuant::new(qi, qo, p);
            global_avg_pool(&q, &x, s, &mut y).unwrap();
            for (k, &got) in y[..c].iter().enumerate() {
                let sum: i32 = plane(k).iter().map(|&v| v as i32 - zi).sum();
                prop_assert_eq!(got, q.finish(sum), "avg {}", k);
            }
            let r = Rescale::new(qi, qo);
            global_max_pool(&r, &x, s, &mut y).unwrap();
            for (k, &got) in y[..c].iter().enumerate() {
                prop_assert_eq!(got, r.apply(*plane(k).iter().max().unwrap()), "max {}", k);
            }
            let q = MeanQuant::new(qi, qo, c);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                channel_mean_with(isa, &q, &x, s, &mut y).unwrap();
                for (i, &got) in y[..p].iter().enumerate() {
                    let sum: i32 = (0..c).map(|k| plane(k)[i] as i32 - zi).sum();
                    prop_assert_eq!(got, q.finish(sum), "channel mean {} ({})", i, isa.name());
                }
            }
            channel_max(&r, &x, s, &mut y).unwrap();
            for (i, &got) in y[..p].iter().enumerate() {
                let m = (0..c).map(|k| plane(k)[i]).max().unwrap();
                prop_assert_eq!(got, r.apply(m), "channel max {}", i);
            }
        }

        #[test]
        fn means_within_one_lsb(c in 1usize..5, h in 1usize..6, w in 1usize..6, zi in -20i32..20, zo in -20i32..20,
                                si in 0.01f32..0.5, so in 0.01f32..0.5, seed in any::<u32>()) {
            let s = Shape::new(c, h, w);
            let x: Vec<i8> = (0..s.len().unwrap()).map(|i| ((i as u32).wrapping_mul(2654435761) ^ seed) as i8).collect();
            let (qi, qo) = (QParams { scale: si, zero_point: zi }, QParams { scale: so, zero_point: zo });
            let xf: Vec<f32> = x.iter().map(|&q| qi.dequantize(q)).collect();
            let mut y = std::vec![0i8; c.max(h * w)];
            let mut r = std::vec![0f32; c.max(h * w)];
            global_avg_pool(&MeanQuant::new(qi, qo, h * w), &x, s, &mut y).unwrap();
            float::global_avg_pool(&xf, s, &mut r).unwrap();
            for i in 0..c { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            channel_mean(&MeanQuant::new(qi, qo, c), &x, s, &mut y).unwrap();
            float::channel_mean(&xf, s, &mut r).unwrap();
            for i in 0..h * w { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            channel_max(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
            float::channel_max(&xf, s, &mut r).unwrap();
            for i in 0..h * w { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
            global_max_pool(&Rescale::new(qi, qo), &x, s, &mut y).unwrap();
            float::global_max_pool(&xf, s, &mut r).unwrap();
            for i in 0..c { prop_assert!((y[i] as i32 - qo.quantize(r[i]) as i32).abs() <= 1); }
        }
    }
}
