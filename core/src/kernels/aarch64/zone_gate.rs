//! NEON kernels of the zone gate (`crate::zone_gate`), bit for bit its portable code.
//!
//! [`conv3x3`]: every output starts at its bias and adds `weight · input` for its inputs in (channel, row,
//! column) order, taps outside the plane skipped (zero padding), with separate multiplies and
//! adds. Here 4 output channels × 8 (or 4) columns are kept in registers over all the taps; near the
//! sides a lane keeps its sum (a select) where its tap leaves the plane.
//!
//! [`blend`]: 4 pixels of a row at once, each lane the portable blend's operations in order
//! (bilinear logits, their maximum, `exp`, the weighted sums, the finite check).

use super::vmath::exp_f32x4;
use core::arch::aarch64::*;

/// The weight of output `o`, input `i`, tap `t` of a layer stored as `outputs · inputs · 9`
/// little-endian `f32` (the biases follow).
#[inline(always)]
fn weight(bytes: &[u8], inputs: usize, o: usize, i: usize, t: usize) -> f32 {
    let a = 4 * ((o * inputs + i) * 9 + t);
    f32::from_le_bytes([bytes[a], bytes[a + 1], bytes[a + 2], bytes[a + 3]])
}

/// `acc[k] + v · w[k]` for the 4 output channels `k` (a multiply, then an add).
#[target_feature(enable = "neon")]
#[inline]
fn madd4(acc: [float32x4_t; 4], v: float32x4_t, w: float32x4_t) -> [float32x4_t; 4] {
    [
        vaddq_f32(acc[0], vmulq_laneq_f32::<0>(v, w)),
        vaddq_f32(acc[1], vmulq_laneq_f32::<1>(v, w)),
        vaddq_f32(acc[2], vmulq_laneq_f32::<2>(v, w)),
        vaddq_f32(acc[3], vmulq_laneq_f32::<3>(v, w)),
    ]
}

/// One 3×3 convolution at `qw × qh` (planes of `qw · qh`, channel after channel), dilation
/// `dilation`, zero padding equal to it. `layer` holds the weights then the `outputs` biases;
/// `src` at least `inputs` planes, `dst` at least `outputs` planes.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
pub(crate) unsafe fn conv3x3(
    layer: &[u8],
    (inputs, outputs, dilation): (usize, usize, usize),
    (qw, qh): (usize, usize),
    src: &[f32],
    dst: &mut [f32],
) {
    let plane = qw * qh;
    let d = dilation;
    let bias_at = 4 * outputs * inputs * 9;
    let bias = |o: usize| {
        let a = bias_at + 4 * o;
        f32::from_le_bytes([layer[a], layer[a + 1], layer[a + 2], layer[a + 3]])
    };
    let src = &src[..inputs * plane];
    let dst = &mut dst[..outputs * plane];
    for ob in (0..outputs).step_by(4) {
        let n = (outputs - ob).min(4);
        // The block's weights per (input, tap) as one vector of its ≤ 4 outputs (0 past the
        // last output: those lanes are never stored).
        let mut wv = [[0.0f32; 4]; crate::zone_gate::MAX_CHANNELS * 9];
        for (it, w) in wv.iter_mut().enumerate().take(inputs * 9) {
            for (k, v) in w.iter_mut().enumerate().take(n) {
                *v = weight(layer, inputs, ob + k, it / 9, it % 9);
            }
        }
        for y in 0..qh {
            // The kernel rows inside the plane for this output row.
            let mut rows: [Option<usize>; 3] = [None; 3];
            for (ky, r) in rows.iter_mut().enumerate() {
                *r = (y + ky * d).checked_sub(d).filter(|&sy| sy < qh);
            }
            // Inside the plane 8 columns at a time (two vectors share each weight load), else 4.
            let mut x = 0;
            while x < qw {
                let mut acc = [vdupq_n_f32(0.0); 4];
                for (k, a) in acc.iter_mut().enumerate().take(n) {
                    *a = vdupq_n_f32(bias(ob + k));
                }
                if x >= d && x + 8 + d <= qw {
                    let mut acc2 = acc;
                    // SAFETY: `x − d ≥ 0` and `x + 7 + d < qw`: every load reads 4 floats of
                    // row `sy < qh` of plane `i < inputs`, inside `src`.
                    unsafe {
                        for i in 0..inputs {
                            let base = src.as_ptr().add(i * plane);
                            for (ky, sy) in rows.iter().enumerate() {
                                let Some(sy) = *sy else { continue };
                                let row = base.add(sy * qw + x - d);
                                for kx in 0..3 {
                                    let w = vld1q_f32(wv[i * 9 + ky * 3 + kx].as_ptr());
                                    acc = madd4(acc, vld1q_f32(row.add(kx * d)), w);
                                    acc2 = madd4(acc2, vld1q_f32(row.add(kx * d + 4)), w);
                                }
                            }
                        }
                    }
                    for (k, (a, a2)) in acc.iter().zip(&acc2).enumerate().take(n) {
                        let at = (ob + k) * plane + y * qw + x;
                        let out = &mut dst[at..at + 8];
                        // SAFETY: `out` holds 8 floats.
                        unsafe {
                            vst1q_f32(out.as_mut_ptr(), *a);
                            vst1q_f32(out.as_mut_ptr().add(4), *a2);
                        }
                    }
                    x += 8;
                    continue;
                }
                if x >= d && x + 4 + d <= qw {
                    // SAFETY: `x − d ≥ 0` and `x + 3 + d < qw`: every load reads 4 floats of
                    // row `sy < qh` of plane `i < inputs`, inside `src`.
                    unsafe {
                        for i in 0..inputs {
                            let base = src.as_ptr().add(i * plane);
                            for (ky, sy) in rows.iter().enumerate() {
                                let Some(sy) = *sy else { continue };
                                let row = base.add(sy * qw + x - d);
                                for kx in 0..3 {
                                    let v = vld1q_f32(row.add(kx * d));
                                    let w = vld1q_f32(wv[i * 9 + ky * 3 + kx].as_ptr());
                                    acc = madd4(acc, v, w);
                                }
                            }
                        }
                    }
                } else {
                    // Near the sides (or past the row's end) a lane adds a tap only where its
                    // input column is inside the row, else keeps its sum as it was.
                    let mut col = [[0usize; 4]; 3];
                    let mut inside = [[0u32; 4]; 3];
                    for kx in 0..3 {
                        for l in 0..4 {
                            let sx = (x + l + kx * d).checked_sub(d);
                            if let Some(sx) = sx.filter(|&sx| sx < qw && x + l < qw) {
                                (col[kx][l], inside[kx][l]) = (sx, u32::MAX);
                            }
                        }
                    }
                    // SAFETY: the 4-lane arrays are read and written whole.
                    let masks = inside.map(|m| unsafe { vld1q_u32(m.as_ptr()) });
                    for i in 0..inputs {
                        for (ky, sy) in rows.iter().enumerate() {
                            let Some(sy) = *sy else { continue };
                            let row = &src[i * plane + sy * qw..i * plane + (sy + 1) * qw];
                            for kx in 0..3 {
                                let mut lanes = [0.0f32; 4];
                                for (l, v) in lanes.iter_mut().enumerate() {
                                    if inside[kx][l] != 0 {
                                        *v = row[col[kx][l]];
                                    }
                                }
                                // SAFETY: as above.
                                let (v, w) = unsafe {
                                    (
                                        vld1q_f32(lanes.as_ptr()),
                                        vld1q_f32(wv[i * 9 + ky * 3 + kx].as_ptr()),
                                    )
                                };
                                let sum = madd4(acc, v, w);
                                for (a, s) in acc.iter_mut().zip(sum) {
                                    *a = vbslq_f32(masks[kx], s, *a);
                                }
                            }
                        }
                    }
                }
                let valid = (qw - x).min(4);
                for (k, a) in acc.iter().enumerate().take(n) {
                    let at = (ob + k) * plane + y * qw + x;
                    let mut lanes = [0.0f32; 4];
                    // SAFETY: `lanes` holds 4 floats.
                    unsafe { vst1q_f32(lanes.as_mut_ptr(), *a) };
                    dst[at..at + valid].copy_from_slice(&lanes[..valid]);
                }
                x += 4;
            }
        }
    }
}

/// The gate's blend of `candidates` with the softmax of the bilinearly upsampled `logits`
/// (`crate::zone_gate`'s portable `blend`, the same bits); `width` a multiple of 4.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
pub(crate) unsafe fn blend(
    candidates: &[&[f32]; 3],
    logits: &[f32],
    (width, height): (usize, usize),
    (qw, qh): (usize, usize),
    out: &mut [f32],
) {
    use crate::zone_gate::upsample_source as source;
    let plane = qw * qh;
    let load = |v: [f32; 4]| {
        // SAFETY: `v` holds 4 floats.
        unsafe { vld1q_f32(v.as_ptr()) }
    };
    for y in 0..height {
        let (y0, y1, fy) = source(y, qh);
        let (fy, gy) = (vdupq_n_f32(fy), vdupq_n_f32(1.0 - fy));
        for x in (0..width).step_by(4) {
            let mut s = [(0usize, 0usize, 0.0f32); 4];
            let (mut fxa, mut gxa) = ([0.0f32; 4], [0.0f32; 4]);
            for (l, c) in s.iter_mut().enumerate() {
                *c = source(x + l, qw);
                (fxa[l], gxa[l]) = (c.2, 1.0 - c.2);
            }
            let (fx, gx) = (load(fxa), load(gxa));
            let mut z = [vdupq_n_f32(0.0); 3];
            for (k, zk) in z.iter_mut().enumerate() {
                let l = &logits[k * plane..(k + 1) * plane];
                // The 4 lanes' logits at (row y0 | y1, column x0 | x1).
                let mut g = [[0.0f32; 4]; 4];
                for (i, c) in s.iter().enumerate() {
                    g[0][i] = l[y0 * qw + c.0];
                    g[1][i] = l[y0 * qw + c.1];
                    g[2][i] = l[y1 * qw + c.0];
                    g[3][i] = l[y1 * qw + c.1];
                }
                let (a, b, c, e) = (load(g[0]), load(g[1]), load(g[2]), load(g[3]));
                let top = vaddq_f32(vmulq_f32(a, gx), vmulq_f32(b, fx));
                let bottom = vaddq_f32(vmulq_f32(c, gx), vmulq_f32(e, fx));
                *zk = vaddq_f32(vmulq_f32(top, gy), vmulq_f32(bottom, fy));
            }
            let m = vmaxnmq_f32(
                vmaxnmq_f32(vmaxnmq_f32(vdupq_n_f32(f32::NEG_INFINITY), z[0]), z[1]),
                z[2],
            );
            let p = y * width + x;
            let (mut num, mut den) = (vdupq_n_f32(0.0), vdupq_n_f32(0.0));
            let mut first = vdupq_n_f32(0.0);
            for (k, (zk, c)) in z.iter().zip(candidates).enumerate() {
                // SAFETY: NEON is available (this function's contract); `c` has the 4 values
                // of the row from `p` (the caller's sizes).
                let (e, c) = unsafe {
                    (
                        exp_f32x4(vsubq_f32(*zk, m)),
                        vld1q_f32(c[p..p + 4].as_ptr()),
                    )
                };
                if k == 0 {
                    first = c;
                }
                num = vaddq_f32(num, vmulq_f32(e, c));
                den = vaddq_f32(den, e);
            }
            let v = vdivq_f32(num, den);
            let finite = vcltq_f32(vabsq_f32(v), vdupq_n_f32(f32::INFINITY));
            // SAFETY: `out[p..p + 4]` is 4 floats.
            unsafe { vst1q_f32(out[p..p + 4].as_mut_ptr(), vbslq_f32(finite, v, first)) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// Equal to the portable blend bit for bit: random logits (huge, ±0, ±inf and NaN among
    /// them) and candidates on grids whose cells do not divide evenly.
    #[test]
    fn blend_equals_the_portable_blend_bit_for_bit() {
        let mut s = 0x9e37_79b9u32;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        for (w, h, qw, qh) in [
            (240, 320, 60, 80),
            (16, 12, 4, 3),
            (8, 4, 2, 1),
            (4, 4, 1, 1),
        ] {
            let mut logit = || -> f32 {
                let r = next();
                match r % 23 {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    2 => f32::NEG_INFINITY,
                    3 => 0.0,
                    4 => -0.0,
                    5 => 3e38,
                    _ => (r >> 8) as f32 / (1u32 << 24) as f32 * 40.0 - 20.0,
                }
            };
            let logits: Vec<f32> = (0..3 * qw * qh).map(|_| logit()).collect();
            let cands: Vec<Vec<f32>> = (0..3)
                .map(|_| {
                    (0..w * h)
                        .map(|_| 0.1 + (next() % 1000) as f32 / 100.0)
                        .collect()
                })
                .collect();
            let c = [&cands[0][..], &cands[1][..], &cands[2][..]];
            let mut want = std::vec![0.0f32; w * h];
            let mut got = want.clone();
            crate::zone_gate::blend_portable(&c, &logits, (w, h), (qw, qh), &mut want);
            // SAFETY: NEON is part of every aarch64 target these tests run on.
            unsafe { blend(&c, &logits, (w, h), (qw, qh), &mut got) };
            for (i, (g, e)) in got.iter().zip(&want).enumerate() {
                assert_eq!(g.to_bits(), e.to_bits(), "{w}×{h} pixel {i}: {g} vs {e}");
            }
        }
    }

    /// Equal to the portable convolution bit for bit: random layers (signed weights, some
    /// exactly 0, biases ±0 among them) on planes narrower than the kernel's reach, with
    /// widths that are not multiples of 4, every dilation the file allows and 1 to 6 outputs.
    #[test]
    fn equals_the_portable_convolution_bit_for_bit() {
        let mut s = 0x2545_f491u32;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        let mut value = move || -> f32 {
            let r = next();
            match r % 11 {
                0 => 0.0,
                1 => -0.0,
                _ => (r >> 8) as f32 / (1u32 << 23) as f32 * 4.0 - 2.0,
            }
        };
        for (qw, qh, inputs, outputs, dilation) in [
            (60, 80, 8, 4, 1),
            (13, 7, 3, 5, 2),
            (5, 9, 2, 6, 3),
            (3, 3, 1, 1, 8),
            (17, 11, 4, 3, 8),
            (9, 4, 2, 2, 4),
            (1, 6, 2, 3, 1),
            (24, 20, 16, 16, 2),
        ] {
            let values = outputs * inputs * 9 + outputs;
            let layer: Vec<u8> = (0..values).flat_map(|_| value().to_le_bytes()).collect();
            let src: Vec<f32> = (0..inputs * qw * qh).map(|_| value()).collect();
            let mut want = std::vec![f32::NAN; outputs * qw * qh];
            let mut got = want.clone();
            let shape = (inputs, outputs, dilation);
            crate::zone_gate::conv3x3(&layer, shape, (qw, qh), &src, &mut want);
            // SAFETY: NEON is part of every aarch64 target these tests run on.
            unsafe { conv3x3(&layer, shape, (qw, qh), &src, &mut got) };
            for (i, (g, e)) in got.iter().zip(&want).enumerate() {
                assert_eq!(
                    g.to_bits(),
                    e.to_bits(),
                    "{qw}×{qh} d {dilation}: value {i}"
                );
            }
        }
    }
}
