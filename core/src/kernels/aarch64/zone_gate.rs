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
use crate::zone_gate::f32_at;
use core::arch::aarch64::*;

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
    let src = &src[..inputs * plane];
    let dst = &mut dst[..outputs * plane];
    for ob in (0..outputs).step_by(4) {
        let n = (outputs - ob).min(4);
        // The block's weights per (input, tap) as one vector of its ≤ 4 outputs (0 past the
        // last output: those lanes are never stored).
        let mut wv = [[0.0f32; 4]; crate::zone_gate::MAX_CHANNELS * 9];
        for (it, w) in wv.iter_mut().enumerate().take(inputs * 9) {
            for (k, v) in w.iter_mut().enumerate().take(n) {
                *v = f32_at(layer, 4 * ((ob + k) * inputs * 9 + it));
            }
        }
        let mut bias = [vdupq_n_f32(0.0); 4];
        for (k, b) in bias.iter_mut().enumerate().take(n) {
            *b = vdupq_n_f32(f32_at(layer, bias_at + 4 * (ob + k)));
        }
        for y in 0..qh {
            // The kernel rows inside the plane for this output row.
            let mut rows: [Option<usize>; 3] = [None; 3];
            for (ky, r) in rows.iter_mut().enumerate() {
                *r = (y + ky * d).checked_sub(d).filter(|&sy| sy < qh);
            }
            let at = Taps {
                src,
                wv: &wv[..inputs * 9],
                rows,
                plane,
                qw,
                d,
            };
            // Inside the plane 8 columns at a time (two vectors share each weight load), else 4.
            let mut x = 0;
            while x < qw {
                let mut acc = [bias; 2];
                let cols = if x >= d && x + 8 + d <= qw {
                    // SAFETY: NEON is available (this function's contract); the 8 columns'
                    // taps lie inside the plane.
                    acc = unsafe { at.inside::<2>(acc, x) };
                    8
                } else if x >= d && x + 4 + d <= qw {
                    // SAFETY: as above, for 4 columns.
                    acc[0] = unsafe { at.inside::<1>([bias], x) }[0];
                    4
                } else {
                    // SAFETY: NEON is available (this function's contract).
                    acc[0] = unsafe { at.sides(bias, x) };
                    4
                };
                let valid = (qw - x).min(cols);
                for (k, (a0, a1)) in acc[0].iter().zip(&acc[1]).enumerate().take(n) {
                    let mut lanes = [0.0f32; 8];
                    // SAFETY: `lanes` holds 8 floats.
                    unsafe {
                        vst1q_f32(lanes.as_mut_ptr(), *a0);
                        vst1q_f32(lanes.as_mut_ptr().add(4), *a1);
                    }
                    let o = (ob + k) * plane + y * qw + x;
                    dst[o..o + valid].copy_from_slice(&lanes[..valid]);
                }
                x += cols;
            }
        }
    }
}

/// What the taps of one output row read: the input planes, the output block's weight vectors
/// per (input, tap), the kernel rows inside the plane, and the geometry.
struct Taps<'a> {
    src: &'a [f32],
    wv: &'a [[f32; 4]],
    rows: [Option<usize>; 3],
    plane: usize,
    qw: usize,
    d: usize,
}

impl Taps<'_> {
    /// Adds every tap of the `4·V` columns from `x` to `acc` (vector `v` holds columns
    /// `x + 4v ..`), all of whose taps lie inside the row: `x ≥ d`, `x + 4·V + d ≤ qw`.
    ///
    /// # Safety
    /// The CPU must have NEON; the columns as stated.
    #[target_feature(enable = "neon")]
    #[inline]
    unsafe fn inside<const V: usize>(
        &self,
        mut acc: [[float32x4_t; 4]; V],
        x: usize,
    ) -> [[float32x4_t; 4]; V] {
        for (i, w9) in self.wv.chunks_exact(9).enumerate() {
            let base = self.src[i * self.plane..].as_ptr();
            for (ky, sy) in self.rows.iter().enumerate() {
                let Some(sy) = *sy else { continue };
                // SAFETY: row `sy < qh` of plane `i`, from column `x − d ≥ 0`.
                let row = unsafe { base.add(sy * self.qw + x - self.d) };
                for kx in 0..3 {
                    // SAFETY: the 4 weights of the vector; each load reads 4 floats of the row
                    // ending at column `x + 4·V − 1 + d < qw` at most.
                    unsafe {
                        let w = vld1q_f32(w9[ky * 3 + kx].as_ptr());
                        for (v, a) in acc.iter_mut().enumerate() {
                            *a = madd4(*a, vld1q_f32(row.add(kx * self.d + 4 * v)), w);
                        }
                    }
                }
            }
        }
        acc
    }

    /// Adds the taps of the 4 columns from `x` near the sides (or past the row's end) to
    /// `acc`: a lane adds a tap only where its input column is inside the row, else keeps its
    /// sum as it was.
    ///
    /// # Safety
    /// The CPU must have NEON.
    #[target_feature(enable = "neon")]
    #[inline]
    unsafe fn sides(&self, mut acc: [float32x4_t; 4], x: usize) -> [float32x4_t; 4] {
        let (qw, d) = (self.qw, self.d);
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
        let mut masks = [vdupq_n_u32(0); 3];
        for (m, lanes) in masks.iter_mut().zip(&inside) {
            // SAFETY: `lanes` holds 4 words.
            *m = unsafe { vld1q_u32(lanes.as_ptr()) };
        }
        for (i, w9) in self.wv.chunks_exact(9).enumerate() {
            for (ky, sy) in self.rows.iter().enumerate() {
                let Some(sy) = *sy else { continue };
                let row = &self.src[i * self.plane + sy * qw..i * self.plane + (sy + 1) * qw];
                for kx in 0..3 {
                    let mut lanes = [0.0f32; 4];
                    for (l, v) in lanes.iter_mut().enumerate() {
                        if inside[kx][l] != 0 {
                            *v = row[col[kx][l]];
                        }
                    }
                    // SAFETY: `lanes` and the weight vector hold 4 floats each.
                    let (v, w) = unsafe {
                        (
                            vld1q_f32(lanes.as_ptr()),
                            vld1q_f32(w9[ky * 3 + kx].as_ptr()),
                        )
                    };
                    let sum = madd4(acc, v, w);
                    for (a, s) in acc.iter_mut().zip(sum) {
                        *a = vbslq_f32(masks[kx], s, *a);
                    }
                }
            }
        }
        acc
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
