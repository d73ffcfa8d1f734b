//! The learned zone gate (issue 39; docs/results/models_zone_gate.md): per pixel, a blend of
//! three depth candidates, the network's output, the joint bilateral upsampling of the zones
//! ([`crate::interp`]) and the bilinear interpolation of the zone grid
//! ([`crate::interp::bilinear`]), with softmax weights that
//! a small CNN predicts at 1/4 resolution from the candidates and the RGB. Where the zones agree
//! with the image it follows them; where they do not it keeps the network.
//!
//! The CNN (`models/depthor_models/zone_gate.py`, `ZoneGate`): features = the candidates' log
//! depths (`ln max(d, 0.1 m)`), the log differences of the network to the two others and the
//! RGB in [0, 1], average-pooled 4×4; then 3×3 convolutions with zero padding equal to their
//! dilation, a leaky ReLU after every layer but the last; the last layer's logits (one per
//! candidate) are upsampled bilinearly (pixel centres aligned, edges clamped), and the softmax
//! over them weighs the candidates.
//!
//! `f32` throughout with a fixed operation order (no fused multiply-add, `ln` and `exp` from the
//! core's own routines), so the bits are the same on every target. No allocation: the weights
//! stay in the caller's bytes ([`ZoneGate::parse`]) and the activations live in the caller's
//! scratch ([`ZoneGate::scratch_floats`]).
//!
//! # File format (`zone_gate.bin`, little-endian)
//!
//! | bytes | field |
//! | --- | --- |
//! | 4 | magic `DZG1` |
//! | 2 | candidates `K` (3) |
//! | 2 | hidden channels `C` (1–64) |
//! | 2 | layers `L` (2–8) |
//! | 2 | pooling factor (4) |
//! | 4 | leaky ReLU slope, `f32` (finite, in [0, 1]) |
//!
//! then per layer `l` (inputs `2K + 2` for the first, `C` after; outputs `K` for the last, `C`
//! before): `u16` dilation (1–8), `u16` 0, `f32` weights `[out][in][3][3]`, `f32` biases `[out]`;
//! nothing after the last layer. Every value must be finite.

use crate::fmath::{exp_f32, ln_f32};

/// Magic of a gate file.
pub const MAGIC: [u8; 4] = *b"DZG1";
/// Depth candidates a gate blends: the network, joint bilateral zones, bilinear zones.
pub const CANDIDATES: usize = 3;
/// Feature channels the first layer reads: `K` log depths, `K − 1` log differences, RGB.
pub const FEATURES: usize = 2 * CANDIDATES + 2;
/// Side of the average pooling, pixels.
pub const POOL: usize = 4;
/// Depth below which candidates are clamped before the logarithm, metres.
pub const MIN_DEPTH_M: f32 = 0.1;
/// Most layers a gate file may hold.
pub const MAX_LAYERS: usize = 8;
/// Most hidden channels a gate file may hold.
pub const MAX_CHANNELS: usize = 64;

const HEADER_BYTES: usize = 16;
const LAYER_HEADER_BYTES: usize = 4;

/// Why a gate file or a run's buffers were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GateError {
    /// The file does not start with [`MAGIC`].
    Magic,
    /// The file ends inside the named field.
    Truncated(&'static str),
    /// A header field is out of its range (the field's name).
    Field(&'static str),
    /// A weight, bias or the slope is not finite.
    NotFinite,
    /// Bytes follow the last layer.
    TrailingBytes,
    /// The image is empty or its sides are not multiples of [`POOL`].
    ImageSize,
    /// A candidate or the output is not `width · height` values, or `rgb` not `3 · width ·
    /// height` bytes.
    BufferSize,
    /// The scratch holds fewer than [`ZoneGate::scratch_floats`] values.
    ScratchSize,
}

/// One 3×3 convolution of the file.
#[derive(Clone, Copy, Debug, Default)]
struct Layer {
    inputs: usize,
    outputs: usize,
    dilation: usize,
    /// Byte offset of the weights; the biases follow them.
    offset: usize,
}

/// A parsed gate: borrows the file's bytes.
#[derive(Clone, Debug)]
pub struct ZoneGate<'a> {
    bytes: &'a [u8],
    channels: usize,
    slope: f32,
    layers: [Layer; MAX_LAYERS],
    count: usize,
}

fn u16_at(bytes: &[u8], at: usize, field: &'static str) -> Result<u16, GateError> {
    bytes
        .get(at..at + 2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .ok_or(GateError::Truncated(field))
}

/// The little-endian `f32` at byte `at` (0 past the end: `parse` checked every offset).
pub(crate) fn f32_at(bytes: &[u8], at: usize) -> f32 {
    // Offsets were checked against the length by `parse`.
    bytes
        .get(at..at + 4)
        .map_or(0.0, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

impl<'a> ZoneGate<'a> {
    /// Checks a gate file (see the module's format) and borrows it.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, GateError> {
        match bytes.get(..4) {
            Some(m) if m == MAGIC => {}
            Some(_) => return Err(GateError::Magic),
            None => return Err(GateError::Truncated("magic")),
        }
        if u16_at(bytes, 4, "candidates")? as usize != CANDIDATES {
            return Err(GateError::Field("candidates"));
        }
        let channels = u16_at(bytes, 6, "channels")? as usize;
        if !(1..=MAX_CHANNELS).contains(&channels) {
            return Err(GateError::Field("channels"));
        }
        let count = u16_at(bytes, 8, "layers")? as usize;
        if !(2..=MAX_LAYERS).contains(&count) {
            return Err(GateError::Field("layers"));
        }
        if u16_at(bytes, 10, "pool")? as usize != POOL {
            return Err(GateError::Field("pool"));
        }
        if bytes.len() < HEADER_BYTES {
            return Err(GateError::Truncated("slope"));
        }
        let slope = f32_at(bytes, 12);
        if !slope.is_finite() || !(0.0..=1.0).contains(&slope) {
            return Err(GateError::Field("slope"));
        }
        let mut layers = [Layer::default(); MAX_LAYERS];
        let mut at = HEADER_BYTES;
        for (l, layer) in layers.iter_mut().enumerate().take(count) {
            let dilation = u16_at(bytes, at, "dilation")? as usize;
            if !(1..=8).contains(&dilation) {
                return Err(GateError::Field("dilation"));
            }
            if u16_at(bytes, at + 2, "reserved")? != 0 {
                return Err(GateError::Field("reserved"));
            }
            let inputs = if l == 0 { FEATURES } else { channels };
            let outputs = if l + 1 == count { CANDIDATES } else { channels };
            let offset = at + LAYER_HEADER_BYTES;
            let values = outputs * inputs * 9 + outputs;
            let end = offset + 4 * values;
            let Some(body) = bytes.get(offset..end) else {
                return Err(GateError::Truncated("weights"));
            };
            if body
                .chunks_exact(4)
                .any(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
            {
                return Err(GateError::NotFinite);
            }
            *layer = Layer {
                inputs,
                outputs,
                dilation,
                offset,
            };
            at = end;
        }
        if at != bytes.len() {
            return Err(GateError::TrailingBytes);
        }
        Ok(ZoneGate {
            bytes,
            channels,
            slope,
            layers,
            count,
        })
    }

    /// Hidden channels.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Multiply-accumulates of the CNN on a `width × height` image (pooling, upsampling and the
    /// blend not counted).
    pub fn macs(&self, width: usize, height: usize) -> usize {
        let cells = (width / POOL) * (height / POOL);
        self.layers[..self.count]
            .iter()
            .map(|l| cells * l.inputs * l.outputs * 9)
            .sum()
    }

    /// `f32` values of scratch [`ZoneGate::run`] needs for a `width × height` image: two
    /// activation planes of the widest layer at 1/4 resolution (saturating).
    pub fn scratch_floats(&self, width: usize, height: usize) -> usize {
        let widest = self.channels.max(FEATURES).max(CANDIDATES);
        (width / POOL)
            .saturating_mul(height / POOL)
            .saturating_mul(widest)
            .saturating_mul(2)
    }

    /// Blends `candidates` (`[network, joint bilateral, bilinear]`, metres, `width · height`
    /// each, row-major) into `out` with the gate's weights, guided by `rgb` (interleaved, `3 ·
    /// width · height` bytes). `width` and `height` must be multiples of [`POOL`]. With finite
    /// candidates the output is finite and lies between the smallest and the largest candidate
    /// of its pixel.
    pub fn run(
        &self,
        candidates: [&[f32]; CANDIDATES],
        rgb: &[u8],
        (width, height): (usize, usize),
        scratch: &mut [f32],
        out: &mut [f32],
    ) -> Result<(), GateError> {
        if width == 0 || height == 0 || width % POOL != 0 || height % POOL != 0 {
            return Err(GateError::ImageSize);
        }
        let pixels = width.checked_mul(height).ok_or(GateError::ImageSize)?;
        if candidates.iter().any(|c| c.len() != pixels)
            || out.len() != pixels
            || rgb.len() != pixels.saturating_mul(3)
        {
            return Err(GateError::BufferSize);
        }
        let need = self.scratch_floats(width, height);
        if scratch.len() < need {
            return Err(GateError::ScratchSize);
        }
        let (qw, qh) = (width / POOL, height / POOL);
        let (a, b) = scratch[..need].split_at_mut(need / 2);
        pool_features(&candidates, rgb, width, (qw, qh), a);
        let (mut src, mut dst) = (a, b);
        for (l, layer) in self.layers[..self.count].iter().enumerate() {
            self.conv(layer, (qw, qh), src, dst);
            if l + 1 < self.count {
                let n = layer.outputs * qw * qh;
                for v in &mut dst[..n] {
                    if *v < 0.0 {
                        *v *= self.slope;
                    }
                }
            }
            core::mem::swap(&mut src, &mut dst);
        }
        blend(&candidates, src, (width, height), (qw, qh), out);
        Ok(())
    }

    /// One 3×3 convolution at `qw × qh`, zero padding equal to the dilation; each output sums
    /// its bias, then the inputs in (channel, row, column) order (in NEON on aarch64:
    /// `kernels::aarch64::zone_gate`, the same bits).
    fn conv(&self, layer: &Layer, (qw, qh): (usize, usize), src: &[f32], dst: &mut [f32]) {
        let end = layer.offset + 4 * (layer.outputs * layer.inputs * 9 + layer.outputs);
        let shape = (layer.inputs, layer.outputs, layer.dilation);
        let body = &self.bytes[layer.offset..end];
        #[cfg(target_arch = "aarch64")]
        if crate::kernels::isa::Isa::Neon.available() {
            // SAFETY: NEON is available (checked just above).
            unsafe { crate::kernels::aarch64::zone_gate::conv3x3(body, shape, (qw, qh), src, dst) };
            return;
        }
        conv3x3(body, shape, (qw, qh), src, dst);
    }
}

/// The portable 3×3 convolution of a layer (`layer`: `outputs · inputs · 9` little-endian
/// weights, then `outputs` biases) at `qw × qh`, zero padding equal to the dilation: each
/// output starts at its bias and adds `weight · input` for its inputs in (channel, row, column)
/// order, skipping the taps outside the plane.
pub(crate) fn conv3x3(
    layer: &[u8],
    (inputs, outputs, dilation): (usize, usize, usize),
    (qw, qh): (usize, usize),
    src: &[f32],
    dst: &mut [f32],
) {
    let plane = qw * qh;
    let d = dilation as isize;
    let bias_at = 4 * outputs * inputs * 9;
    for (o, out) in dst[..outputs * plane].chunks_exact_mut(plane).enumerate() {
        out.fill(f32_at(layer, bias_at + 4 * o));
        for (i, input) in src[..inputs * plane].chunks_exact(plane).enumerate() {
            for tap in 0..9 {
                let w = f32_at(layer, 4 * ((o * inputs + i) * 9 + tap));
                let (dy, dx) = ((tap / 3) as isize - 1, (tap % 3) as isize - 1);
                let (dy, dx) = (dy * d, dx * d);
                // Output columns whose input column x + dx is inside the plane.
                let x0 = (-dx).clamp(0, qw as isize) as usize;
                let x1 = (qw as isize - dx).clamp(0, qw as isize) as usize;
                if x0 >= x1 {
                    continue;
                }
                for y in 0..qh {
                    let sy = y as isize + dy;
                    if sy < 0 || sy >= qh as isize {
                        continue;
                    }
                    let row = &mut out[y * qw + x0..y * qw + x1];
                    let start = (sy as usize * qw) as isize + x0 as isize + dx;
                    let inp = &input[start as usize..start as usize + (x1 - x0)];
                    for (r, v) in row.iter_mut().zip(inp) {
                        *r += w * *v;
                    }
                }
            }
        }
    }
}

/// The first layer's input: per 4×4 cell, the mean of each feature over its 16 pixels (row by
/// row), planes `[ln d₀, ln d₁, ln d₂, ln d₀ − ln d₁, ln d₀ − ln d₂, r, g, b]`.
fn pool_features(
    candidates: &[&[f32]; CANDIDATES],
    rgb: &[u8],
    width: usize,
    (qw, qh): (usize, usize),
    dst: &mut [f32],
) {
    let plane = qw * qh;
    for cy in 0..qh {
        for cx in 0..qw {
            let mut sum = [0.0f32; FEATURES];
            for y in cy * POOL..(cy + 1) * POOL {
                let p0 = y * width + cx * POOL;
                let l0 = log_depths(&candidates[0][p0..p0 + POOL]);
                let l1 = log_depths(&candidates[1][p0..p0 + POOL]);
                let l2 = log_depths(&candidates[2][p0..p0 + POOL]);
                for (j, ((&a, &b), &c)) in l0.iter().zip(&l1).zip(&l2).enumerate() {
                    let p = p0 + j;
                    let l = [a, b, c];
                    let f = [
                        l[0],
                        l[1],
                        l[2],
                        l[0] - l[1],
                        l[0] - l[2],
                        f32::from(rgb[3 * p]) / 255.0,
                        f32::from(rgb[3 * p + 1]) / 255.0,
                        f32::from(rgb[3 * p + 2]) / 255.0,
                    ];
                    for (s, v) in sum.iter_mut().zip(f) {
                        *s += v;
                    }
                }
            }
            for (c, s) in sum.iter().enumerate() {
                dst[c * plane + cy * qw + cx] = s / (POOL * POOL) as f32;
            }
        }
    }
}

/// `ln` of [`POOL`] depths, each first made finite and at least [`MIN_DEPTH_M`] (NaN and ±inf
/// become [`MIN_DEPTH_M`]): in NEON on aarch64, else one by one (the same bits).
#[inline(always)]
fn log_depths(d: &[f32]) -> [f32; POOL] {
    let mut v = [0.0f32; POOL];
    for (o, &x) in v.iter_mut().zip(d) {
        *o = if x.is_finite() {
            x.max(MIN_DEPTH_M)
        } else {
            MIN_DEPTH_M
        };
    }
    #[cfg(target_arch = "aarch64")]
    if crate::kernels::isa::Isa::Neon.available() {
        use core::arch::aarch64::{vld1q_f32, vst1q_f32};
        const _: () = assert!(POOL == 4, "one NEON register per row of a cell");
        // SAFETY: NEON is available (checked just above); `v` holds 4 floats.
        unsafe {
            let l = crate::kernels::aarch64::vmath::ln_f32x4(vld1q_f32(v.as_ptr()));
            vst1q_f32(v.as_mut_ptr(), l);
        }
        return v;
    }
    v.map(ln_f32)
}

/// Source cell and weight of output coordinate `i` when upsampling `n` cells by [`POOL`]
/// (pixel centres aligned, clamped at 0 and at the last cell).
pub(crate) fn upsample_source(i: usize, n: usize) -> (usize, usize, f32) {
    let s = ((i as f32 + 0.5) / POOL as f32 - 0.5).max(0.0);
    let i0 = (s as usize).min(n - 1);
    (i0, (i0 + 1).min(n - 1), s - i0 as f32)
}

/// Upsamples the logits bilinearly and blends the candidates with their softmax (a pixel whose
/// blend is not finite takes the network's depth).
fn blend(
    candidates: &[&[f32]; CANDIDATES],
    logits: &[f32],
    (width, height): (usize, usize),
    (qw, qh): (usize, usize),
    out: &mut [f32],
) {
    #[cfg(target_arch = "aarch64")]
    if crate::kernels::isa::Isa::Neon.available() && width % 4 == 0 {
        // SAFETY: NEON is available (checked just above).
        unsafe {
            crate::kernels::aarch64::zone_gate::blend(
                candidates,
                logits,
                (width, height),
                (qw, qh),
                out,
            )
        };
        return;
    }
    blend_portable(candidates, logits, (width, height), (qw, qh), out);
}

/// [`blend`] in portable code (each pixel on its own).
pub(crate) fn blend_portable(
    candidates: &[&[f32]; CANDIDATES],
    logits: &[f32],
    (width, height): (usize, usize),
    (qw, qh): (usize, usize),
    out: &mut [f32],
) {
    let plane = qw * qh;
    for y in 0..height {
        let (y0, y1, fy) = upsample_source(y, qh);
        for x in 0..width {
            let (x0, x1, fx) = upsample_source(x, qw);
            let mut z = [0.0f32; CANDIDATES];
            for (k, zk) in z.iter_mut().enumerate() {
                let l = &logits[k * plane..(k + 1) * plane];
                let top = l[y0 * qw + x0] * (1.0 - fx) + l[y0 * qw + x1] * fx;
                let bottom = l[y1 * qw + x0] * (1.0 - fx) + l[y1 * qw + x1] * fx;
                *zk = top * (1.0 - fy) + bottom * fy;
            }
            let m = z.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
            let (mut num, mut den) = (0.0f32, 0.0f32);
            let p = y * width + x;
            for (k, zk) in z.iter().enumerate() {
                let e = exp_f32(zk - m);
                num += e * candidates[k][p];
                den += e;
            }
            // Finite weights can still overflow the activations to ±inf (then NaN logits):
            // such a pixel keeps the network's depth rather than a NaN.
            let v = num / den;
            out[p] = if v.is_finite() { v } else { candidates[0][p] };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// A gate file with the given layer dilations and weights from `value(layer, index)`.
    fn file(channels: usize, dilations: &[u16], value: impl Fn(usize, usize) -> f32) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&MAGIC);
        for v in [
            CANDIDATES as u16,
            channels as u16,
            dilations.len() as u16,
            4,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&0.1f32.to_le_bytes());
        for (l, &d) in dilations.iter().enumerate() {
            b.extend_from_slice(&d.to_le_bytes());
            b.extend_from_slice(&0u16.to_le_bytes());
            let inputs = if l == 0 { FEATURES } else { channels };
            let outputs = if l + 1 == dilations.len() {
                CANDIDATES
            } else {
                channels
            };
            for i in 0..outputs * inputs * 9 + outputs {
                b.extend_from_slice(&value(l, i).to_le_bytes());
            }
        }
        b
    }

    fn pseudo(l: usize, i: usize) -> f32 {
        let h = (l as u32 * 7919 + i as u32).wrapping_mul(2_654_435_761);
        (h >> 8) as f32 / (1u32 << 24) as f32 * 0.4 - 0.2
    }

    /// The gate's definition in f64 with plain loops (padding by bounds checks, upsampling by
    /// the formula), for comparison.
    fn reference(gate: &[u8], cands: [&[f32]; 3], rgb: &[u8], w: usize, h: usize) -> Vec<f64> {
        let g = ZoneGate::parse(gate).unwrap();
        let (qw, qh) = (w / 4, h / 4);
        let mut x = vec![0.0f64; FEATURES * qw * qh];
        for cy in 0..qh {
            for cx in 0..qw {
                for y in cy * 4..cy * 4 + 4 {
                    for xx in cx * 4..cx * 4 + 4 {
                        let p = y * w + xx;
                        let l: Vec<f64> = cands
                            .iter()
                            .map(|c| f64::from(c[p].max(0.1)).ln())
                            .collect();
                        let f = [
                            l[0],
                            l[1],
                            l[2],
                            l[0] - l[1],
                            l[0] - l[2],
                            f64::from(rgb[3 * p]) / 255.0,
                            f64::from(rgb[3 * p + 1]) / 255.0,
                            f64::from(rgb[3 * p + 2]) / 255.0,
                        ];
                        for c in 0..FEATURES {
                            x[c * qw * qh + cy * qw + cx] += f[c] / 16.0;
                        }
                    }
                }
            }
        }
        for (l, layer) in g.layers[..g.count].iter().enumerate() {
            let wt = |o: usize, i: usize, t: usize| {
                f64::from(f32_at(
                    gate,
                    layer.offset + 4 * ((o * layer.inputs + i) * 9 + t),
                ))
            };
            let bias_at = layer.offset + 4 * layer.outputs * layer.inputs * 9;
            let mut y = vec![0.0f64; layer.outputs * qw * qh];
            for o in 0..layer.outputs {
                for py in 0..qh as isize {
                    for px in 0..qw as isize {
                        let mut acc = f64::from(f32_at(gate, bias_at + 4 * o));
                        for i in 0..layer.inputs {
                            for t in 0..9 {
                                let d = layer.dilation as isize;
                                let sy = py + (t as isize / 3 - 1) * d;
                                let sx = px + (t as isize % 3 - 1) * d;
                                if sy >= 0 && sx >= 0 && sy < qh as isize && sx < qw as isize {
                                    acc += wt(o, i, t)
                                        * x[i * qw * qh + sy as usize * qw + sx as usize];
                                }
                            }
                        }
                        if l + 1 < g.count && acc < 0.0 {
                            acc *= f64::from(g.slope);
                        }
                        y[o * qw * qh + py as usize * qw + px as usize] = acc;
                    }
                }
            }
            x = y;
        }
        let mut out = vec![0.0; w * h];
        let src = |i: usize, n: usize| {
            let s = ((i as f64 + 0.5) / 4.0 - 0.5).max(0.0);
            let i0 = (s.floor() as usize).min(n - 1);
            (i0, (i0 + 1).min(n - 1), s - i0 as f64)
        };
        for py in 0..h {
            let (y0, y1, fy) = src(py, qh);
            for px in 0..w {
                let (x0, x1, fx) = src(px, qw);
                let z: Vec<f64> = (0..3)
                    .map(|k| {
                        let l = |yy: usize, xx: usize| x[k * qw * qh + yy * qw + xx];
                        (l(y0, x0) * (1.0 - fx) + l(y0, x1) * fx) * (1.0 - fy)
                            + (l(y1, x0) * (1.0 - fx) + l(y1, x1) * fx) * fy
                    })
                    .collect();
                let m = z.iter().cloned().fold(f64::MIN, f64::max);
                let e: Vec<f64> = z.iter().map(|v| (v - m).exp()).collect();
                let s: f64 = e.iter().sum();
                out[py * w + px] = (0..3)
                    .map(|k| e[k] * f64::from(cands[k][py * w + px]))
                    .sum::<f64>()
                    / s;
            }
        }
        out
    }

    fn inputs(w: usize, h: usize) -> (Vec<Vec<f32>>, Vec<u8>) {
        let cands = (0..3)
            .map(|k| {
                (0..w * h)
                    .map(|p| 0.5 + ((p * (k + 3) + k * 17) % 97) as f32 * 0.05)
                    .collect()
            })
            .collect();
        let rgb = (0..3 * w * h).map(|i| (i * 37 % 251) as u8).collect();
        (cands, rgb)
    }

    #[test]
    fn run_matches_the_definition_in_f64() {
        let (w, h) = (24, 20);
        let gate = file(6, &[1, 2, 4, 1], pseudo);
        let g = ZoneGate::parse(&gate).unwrap();
        let (c, rgb) = inputs(w, h);
        let cands = [&c[0][..], &c[1][..], &c[2][..]];
        let mut scratch = vec![0.0; g.scratch_floats(w, h)];
        let mut out = vec![0.0; w * h];
        g.run(cands, &rgb, (w, h), &mut scratch, &mut out).unwrap();
        let want = reference(&gate, cands, &rgb, w, h);
        let worst = out
            .iter()
            .zip(&want)
            .map(|(a, b)| (f64::from(*a) - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5, "worst |core − f64| = {worst}");
        // The blend is not one candidate everywhere: the weights vary.
        assert!(out.iter().zip(&c[0]).any(|(a, b)| (a - b).abs() > 1e-3));
        assert_eq!(g.macs(w, h), 30 * (8 * 6 + 6 * 6 * 2 + 6 * 3) * 9);
    }

    #[test]
    fn a_gate_sure_of_one_candidate_returns_it() {
        // All weights 0, biases favour candidate 1 by 40 logits.
        let gate = file(4, &[1, 1], |l, i| {
            let bias_at = if l == 0 { 4 * FEATURES * 9 } else { 3 * 4 * 9 };
            if l == 1 && i == bias_at + 1 {
                40.0
            } else {
                0.0
            }
        });
        let g = ZoneGate::parse(&gate).unwrap();
        let (c, rgb) = inputs(8, 4);
        let mut scratch = vec![0.0; g.scratch_floats(8, 4)];
        let mut out = vec![0.0; 32];
        g.run([&c[0], &c[1], &c[2]], &rgb, (8, 4), &mut scratch, &mut out)
            .unwrap();
        assert_eq!(out, c[1]);
    }

    #[test]
    fn malformed_files_and_buffers_are_refused() {
        let good = file(4, &[1, 2, 1], pseudo);
        assert!(ZoneGate::parse(&good).is_ok());
        for cut in [0, 3, 10, 14, 17, good.len() - 1] {
            assert!(
                matches!(ZoneGate::parse(&good[..cut]), Err(GateError::Truncated(_))),
                "cut at {cut}"
            );
        }
        let mut long = good.clone();
        long.push(0);
        assert_eq!(
            ZoneGate::parse(&long).unwrap_err(),
            GateError::TrailingBytes
        );
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(ZoneGate::parse(&bad).unwrap_err(), GateError::Magic);
        for (at, field) in [
            (4, "candidates"),
            (6, "channels"),
            (8, "layers"),
            (10, "pool"),
            (16, "dilation"),
        ] {
            let mut bad = good.clone();
            bad[at] = 0;
            bad[at + 1] = 0;
            assert_eq!(ZoneGate::parse(&bad).unwrap_err(), GateError::Field(field));
        }
        let mut nan = good.clone();
        nan[40..44].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(ZoneGate::parse(&nan).unwrap_err(), GateError::NotFinite);

        let g = ZoneGate::parse(&good).unwrap();
        let (c, rgb) = inputs(8, 8);
        let cands = [&c[0][..], &c[1][..], &c[2][..]];
        let mut scratch = vec![0.0; g.scratch_floats(8, 8)];
        let mut out = vec![0.0; 64];
        assert_eq!(
            g.run(cands, &rgb, (8, 6), &mut scratch, &mut out),
            Err(GateError::ImageSize)
        );
        assert_eq!(
            g.run(cands, &rgb[1..], (8, 8), &mut scratch, &mut out),
            Err(GateError::BufferSize)
        );
        assert_eq!(
            g.run(cands, &rgb, (8, 8), &mut scratch[1..], &mut out),
            Err(GateError::ScratchSize)
        );
        // Non-finite depths are clamped, not propagated through the CNN.
        let mut inf = c[1].clone();
        inf[5] = f32::INFINITY;
        inf[6] = f32::NAN;
        g.run([&c[0], &inf, &c[2]], &rgb, (8, 8), &mut scratch, &mut out)
            .unwrap();
        assert!(out
            .iter()
            .enumerate()
            .all(|(p, v)| v.is_finite() || p == 5 || p == 6));
    }
}
