//! Affinity propagation (docs/graph.md `refine`), in f32.
//!
//! **Why f32.** Depth in metres is propagated `T` times with weights that sum to one; int8
//! (4 cm steps over 10 m) would add a quantisation step per iteration, and Q-format would need
//! per-model range analysis. Cortex-M4F/M7 have a single-precision FPU, and IEEE f32 is
//! deterministic when the order of operations is fixed and nothing is fused (Rust never
//! contracts `a*b + c` into an FMA). The affinity, kmix and tmix maps stay int8 in the arena and
//! are dequantised on the fly.
//!
//! **Fixed order.** Per kernel `k` ∈ {3, 5, 7} (in that order), per iteration, per pixel in
//! raster order: `r_j = relu(aff_k[j]) · g_j` for neighbours `j` in raster order (0 outside the
//! image), `S = Σ r_j` summed in that order, `q = 1/(1 + S)`, `w_j = r_j · q`,
//! `w_c = 1 − Σ w_j` (in order), `D' = w_c·D + Σ w_j·D_j` (in order). The Gaussians
//! `g_j = exp(−(dx²+dy²)/(2σ_k²))` are computed once per run with [`super::float::exp`]. After `t ∈ {0, T/2,
//! T}` the output gains `(τ_t · σ_k) · D_{k,t}` with `σ`, `τ` per-pixel 3-way softmaxes of
//! kmix / tmix. Scratch: two f32 `H×W` maps (ping-pong), i.e. `8·H·W` bytes; the output map is
//! the accumulator.

use super::float::{exp, relu};
use super::isa::Isa;
use super::requant::QParams;
use super::KernelError;

/// Most iterations accepted.
pub const MAX_ITERATIONS: usize = 64;
/// Kernel sizes of the three branches.
pub const KERNELS: [usize; 3] = [3, 5, 7];

/// Attributes of `refine`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineAttrs {
    /// `T` (even, ≤ [`MAX_ITERATIONS`]).
    pub iterations: usize,
    /// `[σ3, σ5, σ7]` of the spatial Gaussians (> 0).
    pub sigma: [f32; 3],
}

/// A multi-channel `H×W` map read as f32 (int8 maps dequantise on the fly).
pub trait Map {
    /// Channels available.
    fn channels(&self) -> usize;
    /// Value of channel `c` at flat pixel index `i` (`c < channels()`, `i < plane`).
    fn value(&self, c: usize, i: usize) -> f32;
    /// The map as int8 codes, where it is one (for the vector paths).
    fn as_i8(&self) -> Option<&I8Map<'_>> {
        None
    }
    /// Values of channel `c` at pixels `i..i + L` (the same values as [`Map::value`]).
    #[inline(always)]
    fn values<const L: usize>(&self, c: usize, i: usize) -> [f32; L] {
        core::array::from_fn(|l| self.value(c, i + l))
    }
}

/// An f32 CHW map.
#[derive(Clone, Copy, Debug)]
pub struct F32Map<'a> {
    data: &'a [f32],
    channels: usize,
    plane: usize,
}

impl<'a> F32Map<'a> {
    /// Wraps `data` holding at least `channels × plane` values.
    pub fn new(data: &'a [f32], channels: usize, plane: usize) -> Result<Self, KernelError> {
        if channels.checked_mul(plane).is_none_or(|n| data.len() < n) {
            return Err(KernelError::Shape);
        }
        Ok(F32Map {
            data,
            channels,
            plane,
        })
    }
}

impl Map for F32Map<'_> {
    fn channels(&self) -> usize {
        self.channels
    }
    #[inline]
    fn value(&self, c: usize, i: usize) -> f32 {
        self.data[c * self.plane + i]
    }
    #[inline(always)]
    fn values<const L: usize>(&self, c: usize, i: usize) -> [f32; L] {
        let at = c * self.plane + i;
        let s: &[f32; L] = self.data[at..at + L].try_into().unwrap_or(&[0.0; L]);
        *s
    }
}

/// An int8 CHW map with its quantisation.
#[derive(Clone, Copy, Debug)]
pub struct I8Map<'a> {
    data: &'a [i8],
    q: QParams,
    channels: usize,
    plane: usize,
}

impl<'a> I8Map<'a> {
    /// Wraps `data` holding at least `channels × plane` codes.
    pub fn new(
        data: &'a [i8],
        q: QParams,
        channels: usize,
        plane: usize,
    ) -> Result<Self, KernelError> {
        if channels.checked_mul(plane).is_none_or(|n| data.len() < n) {
            return Err(KernelError::Shape);
        }
        Ok(I8Map {
            data,
            q,
            channels,
            plane,
        })
    }
}

impl I8Map<'_> {
    /// The codes.
    pub fn data(&self) -> &[i8] {
        self.data
    }
    /// Their quantisation.
    pub fn q(&self) -> QParams {
        self.q
    }
    /// Pixels per channel.
    pub fn plane(&self) -> usize {
        self.plane
    }
}

impl Map for I8Map<'_> {
    fn channels(&self) -> usize {
        self.channels
    }
    fn as_i8(&self) -> Option<&I8Map<'_>> {
        Some(self)
    }
    #[inline]
    fn value(&self, c: usize, i: usize) -> f32 {
        self.q.dequantize(self.data[c * self.plane + i])
    }
    #[inline(always)]
    fn values<const L: usize>(&self, c: usize, i: usize) -> [f32; L] {
        let at = c * self.plane + i;
        let s: &[i8; L] = self.data[at..at + L].try_into().unwrap_or(&[0; L]);
        s.map(|q| self.q.dequantize(q))
    }
}

/// Per-pixel softmax over 3 channels of `m` at pixel `i`.
#[inline]
fn softmax3<M: Map>(m: &M, i: usize) -> [f32; 3] {
    let v = [m.value(0, i), m.value(1, i), m.value(2, i)];
    let mx = v[0].max(v[1]).max(v[2]);
    let e = [exp(v[0] - mx), exp(v[1] - mx), exp(v[2] - mx)];
    let s = e[0] + e[1] + e[2];
    [e[0] / s, e[1] / s, e[2] / s]
}

/// Neighbour offsets of an `s×s` window in raster order, centre skipped.
fn offsets(s: usize, out: &mut [(isize, isize); 48]) -> usize {
    let r = (s / 2) as isize;
    let mut n = 0;
    for dy in -r..=r {
        for dx in -r..=r {
            if (dy, dx) != (0, 0) {
                out[n] = (dy, dx);
                n += 1;
            }
        }
    }
    n
}

/// Runs the propagation (module doc) with the fastest kernel set of this CPU. `d0`, `out`:
/// `h·w` f32; `aff[k]`: `s_k² − 1` channels; `kmix`, `tmix`: 3 channels; `scratch`: ≥
/// `2·h·w` f32.
#[allow(clippy::too_many_arguments)]
pub fn refine<A: Map, B: Map>(
    d0: &[f32],
    h: usize,
    w: usize,
    aff: [&A; 3],
    kmix: &B,
    tmix: &B,
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), KernelError> {
    refine_with(Isa::best(), d0, h, w, aff, kmix, tmix, attrs, out, scratch)
}

/// As [`refine`] with kernel set `isa`: the x86 sets run `L` pixels per vector lane group
/// (every pixel's own operations in the module doc's order, so the bits do not change).
#[allow(clippy::too_many_arguments)]
pub fn refine_with<A: Map, B: Map>(
    isa: Isa,
    d0: &[f32],
    h: usize,
    w: usize,
    aff: [&A; 3],
    kmix: &B,
    tmix: &B,
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), KernelError> {
    let p = h.checked_mul(w).ok_or(KernelError::Shape)?;
    let t_max = attrs.iterations;
    if t_max > MAX_ITERATIONS
        || !t_max.is_multiple_of(2)
        || attrs.sigma.iter().any(|s| s.is_nan() || *s <= 0.0)
    {
        return Err(KernelError::Attr);
    }
    if d0.len() < p
        || out.len() < p
        || scratch.len() < 2 * p
        || kmix.channels() < 3
        || tmix.channels() < 3
    {
        return Err(KernelError::Shape);
    }
    for (a, s) in aff.iter().zip(KERNELS) {
        if a.channels() < s * s - 1 {
            return Err(KernelError::Shape);
        }
    }
    let times = [0, t_max / 2, t_max];
    let out = &mut out[..p];
    out.fill(0.0);
    let (mut cur, mut nxt) = scratch[..2 * p].split_at_mut(p);
    let mut off = [(0isize, 0isize); 48];
    for (k, (&a, &s)) in aff.iter().zip(&KERNELS).enumerate() {
        let nn = offsets(s, &mut off);
        let mut g = [0f32; 48];
        let two_s2 = 2.0 * attrs.sigma[k] * attrs.sigma[k];
        for (gj, &(dy, dx)) in g.iter_mut().zip(&off[..nn]) {
            *gj = exp(-((dx * dx + dy * dy) as f32) / two_s2);
        }
        cur.copy_from_slice(&d0[..p]);
        for t in 0..=t_max {
            if t > 0 {
                step(isa, a, &off[..nn], &g[..nn], h, w, cur, nxt);
                core::mem::swap(&mut cur, &mut nxt);
            }
            for (ti, &tt) in times.iter().enumerate() {
                if tt == t {
                    accumulate(isa, out, cur, tmix, kmix, ti, k);
                }
            }
        }
    }
    Ok(())
}

/// Pixels per lane group of the portable path: 4 where the baseline has 4-wide vectors (SSE2,
/// NEON), 1 on scalar FPUs (Cortex-M), where lane arrays only cost loads and stores.
const PORTABLE_LANES: usize = if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
    4
} else {
    1
};

/// `out[i] += (softmax3(tmix)[ti] · softmax3(kmix)[k]) · cur[i]` for every pixel.
fn accumulate<B: Map>(
    isa: Isa,
    out: &mut [f32],
    cur: &[f32],
    tmix: &B,
    kmix: &B,
    ti: usize,
    k: usize,
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512Vnni if Isa::Avx2.available() => {
            let p = out.len().min(cur.len());
            if let (Some(t), Some(m)) = (tmix.as_i8(), kmix.as_i8()) {
                if t.channels >= 3 && m.channels >= 3 && t.plane >= p && m.plane >= p {
                    // SAFETY: AVX2 is available; both maps hold 3 channels of ≥ p pixels.
                    let done = unsafe { super::x86_64::refine::accumulate(out, cur, t, m, ti, k) };
                    accumulate_lanes::<B, 1>(
                        &mut out[done..p],
                        &cur[done..p],
                        tmix,
                        kmix,
                        ti,
                        k,
                        done,
                    );
                    return;
                }
            }
            // SAFETY: AVX2 is available (checked).
            unsafe { accumulate_avx2(out, cur, tmix, kmix, ti, k) }
        }
        _ => accumulate_lanes::<B, PORTABLE_LANES>(out, cur, tmix, kmix, ti, k, 0),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2<B: Map>(
    out: &mut [f32],
    cur: &[f32],
    tmix: &B,
    kmix: &B,
    ti: usize,
    k: usize,
) {
    accumulate_lanes::<B, 8>(out, cur, tmix, kmix, ti, k, 0)
}

/// [`accumulate`] for `out`, `cur` covering map pixels `first..`, `L` pixels at a time.
#[inline(always)]
fn accumulate_lanes<B: Map, const L: usize>(
    out: &mut [f32],
    cur: &[f32],
    tmix: &B,
    kmix: &B,
    ti: usize,
    k: usize,
    first: usize,
) {
    let p = out.len().min(cur.len());
    let mut i = 0;
    while i + L <= p {
        let t = softmax3_lanes::<B, L>(tmix, first + i);
        let m = softmax3_lanes::<B, L>(kmix, first + i);
        for l in 0..L {
            out[i + l] += (t[ti][l] * m[k][l]) * cur[i + l];
        }
        i += L;
    }
    for i in i..p {
        let coef = softmax3(tmix, first + i)[ti] * softmax3(kmix, first + i)[k];
        out[i] += coef * cur[i];
    }
}

/// [`softmax3`] of pixels `i..i + L`, channel-major.
#[inline(always)]
fn softmax3_lanes<M: Map, const L: usize>(m: &M, i: usize) -> [[f32; L]; 3] {
    let v = [
        m.values::<L>(0, i),
        m.values::<L>(1, i),
        m.values::<L>(2, i),
    ];
    let mut r = [[0f32; L]; 3];
    for l in 0..L {
        let mx = v[0][l].max(v[1][l]).max(v[2][l]);
        let e = [exp(v[0][l] - mx), exp(v[1][l] - mx), exp(v[2][l] - mx)];
        let s = e[0] + e[1] + e[2];
        r[0][l] = e[0] / s;
        r[1][l] = e[1] / s;
        r[2][l] = e[2] / s;
    }
    r
}

/// One propagation step of one kernel: `nxt` from `cur`. Runs of `L` pixels whose windows lie
/// inside the image take a lane path without bounds tests, the others a per-pixel path; both
/// add the same terms in the same order per pixel, so the bits do not depend on which ran.
#[allow(clippy::too_many_arguments)]
fn step<A: Map>(
    isa: Isa,
    a: &A,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512Vnni if Isa::Avx2.available() => match a.as_i8() {
            Some(m) if m.channels >= off.len() && m.plane >= h * w && cur.len() >= h * w => {
                step_i8_avx2(isa, m, off, g, h, w, cur, nxt)
            }
            // SAFETY: AVX2 is available (checked).
            _ => unsafe { step_avx2(a, off, g, h, w, cur, nxt) },
        },
        _ => match a.as_i8() {
            Some(m) if PORTABLE_LANES == 1 && m.channels >= off.len() && m.plane >= h * w => {
                step_i8_scalar(m, off, g, h, w, cur, nxt)
            }
            _ => step_lanes::<A, PORTABLE_LANES>(a, off, g, h, w, cur, nxt),
        },
    }
}

/// [`step`] on an int8 map for scalar FPUs: `relu(dequantise(q))` read from a 256-entry table
/// (the same f32 values), interior pixels without bounds tests, borders through [`step_pixel`].
fn step_i8_scalar(
    a: &I8Map,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let n = off.len().min(48).min(g.len());
    let mut lut = [0f32; 256];
    for (code, v) in lut.iter_mut().enumerate() {
        *v = relu(a.q.dequantize(code as u8 as i8));
    }
    let rad = off
        .iter()
        .map(|&(dy, dx)| dy.unsigned_abs().max(dx.unsigned_abs()))
        .max()
        .unwrap_or(0);
    let mut delta = [0isize; 48];
    for (d, &(dy, dx)) in delta.iter_mut().zip(off) {
        *d = dy * w as isize + dx;
    }
    let mut r = [0f32; 48];
    let data = a.data;
    let plane = a.plane;
    for y in 0..h {
        let inner_row = y >= rad && y + rad < h;
        for x in 0..w {
            let i = y * w + x;
            if !(inner_row && x >= rad && x + rad < w) {
                nxt[i] = step_pixel(a, off, g, h, w, cur, y, x);
                continue;
            }
            let mut s = 0.0f32;
            for (j, (rj, &gj)) in r[..n].iter_mut().zip(g).enumerate() {
                // In bounds: the map holds ≥ n channels of ≥ h·w pixels (the caller's match).
                let code = data[j * plane + i] as u8;
                *rj = lut[code as usize] * gj;
                s += *rj;
            }
            let q = 1.0 / (1.0 + s);
            let mut wsum = 0.0f32;
            for rj in r[..n].iter_mut() {
                *rj *= q;
                wsum += *rj;
            }
            let mut d = (1.0 - wsum) * cur[i];
            for (&wj, &dj) in r[..n].iter().zip(&delta) {
                d += wj * cur[(i as isize + dj) as usize];
            }
            nxt[i] = d;
        }
    }
}

/// [`step`] on an int8 map with the AVX2 run kernel for each row's interior pixels.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
fn step_i8_avx2(
    isa: Isa,
    a: &I8Map,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let n = off.len().min(48).min(g.len());
    let rad = off
        .iter()
        .map(|&(dy, dx)| dy.unsigned_abs().max(dx.unsigned_abs()))
        .max()
        .unwrap_or(0);
    let mut delta = [0isize; 48];
    for (d, &(dy, dx)) in delta.iter_mut().zip(off) {
        *d = dy * w as isize + dx;
    }
    for y in 0..h {
        let (mut x0, mut x1) = (0, 0);
        if y >= rad && y + rad < h && w > 2 * rad {
            let wide = isa == Isa::Avx512Vnni && Isa::Avx512Vnni.available();
            let lanes = if wide { 16 } else { 8 };
            x0 = rad;
            x1 = rad + (w - 2 * rad) / lanes * lanes;
            // SAFETY: AVX2 (and AVX-512 F for `wide`) is available (the caller's match and the
            // test above); `a` has ≥ n channels over ≥ h·w pixels and every window of x0..x1 in
            // row y lies inside the image, so every `i + delta` is a pixel of `cur`.
            unsafe {
                let args = (a, &delta[..n], g, y * w, x0, x1);
                if wide {
                    super::x86_64::refine::step_run512(
                        args.0, args.1, args.2, args.3, args.4, args.5, cur, nxt,
                    )
                } else {
                    super::x86_64::refine::step_run(
                        args.0, args.1, args.2, args.3, args.4, args.5, cur, nxt,
                    )
                }
            };
        }
        if w < 8 {
            for x in (0..x0).chain(x1..w) {
                nxt[y * w + x] = step_pixel(a, off, g, h, w, cur, y, x);
            }
            continue;
        }
        // The rest of the row in masked chunks of 8 (a chunk may overlap the interior run or
        // the previous chunk; it writes the same values, which depend on `cur` only).
        for xc in (0..x0).step_by(8).chain((x1..w).step_by(8)) {
            let xc = xc.min(w - 8);
            // SAFETY: AVX2 is available (the caller's match); `a` has ≥ n channels over ≥ h·w
            // pixels and xc + 8 ≤ w.
            unsafe { super::x86_64::refine::step_masked(a, &off[..n], g, h, w, y, xc, cur, nxt) };
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn step_avx2<A: Map>(
    a: &A,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    step_lanes::<A, 8>(a, off, g, h, w, cur, nxt)
}

#[inline(always)]
fn step_lanes<A: Map, const L: usize>(
    a: &A,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let n = off.len().min(48);
    let rad = off
        .iter()
        .map(|&(dy, dx)| dy.unsigned_abs().max(dx.unsigned_abs()))
        .max()
        .unwrap_or(0);
    let mut delta = [0isize; 48];
    for (d, &(dy, dx)) in delta.iter_mut().zip(off) {
        *d = dy * w as isize + dx;
    }
    let mut r = [[0f32; L]; 48];
    for y in 0..h {
        let inner_row = y >= rad && y + rad < h;
        let mut x = 0;
        while x < w {
            let i = y * w + x;
            if inner_row && x >= rad && x + L - 1 + rad < w {
                let mut s = [0f32; L];
                for j in 0..n {
                    let v = a.values::<L>(j, i);
                    for l in 0..L {
                        r[j][l] = relu(v[l]) * g[j];
                        s[l] += r[j][l];
                    }
                }
                let mut q = [0f32; L];
                for l in 0..L {
                    q[l] = 1.0 / (1.0 + s[l]);
                }
                let mut wsum = [0f32; L];
                for rj in r[..n].iter_mut() {
                    for l in 0..L {
                        rj[l] *= q[l];
                        wsum[l] += rj[l];
                    }
                }
                let c: &[f32; L] = cur[i..i + L].try_into().unwrap_or(&[0.0; L]);
                let mut d = [0f32; L];
                for l in 0..L {
                    d[l] = (1.0 - wsum[l]) * c[l];
                }
                for (rj, &dj) in r[..n].iter().zip(&delta) {
                    let k = (i as isize + dj) as usize;
                    let cn: &[f32; L] = cur[k..k + L].try_into().unwrap_or(&[0.0; L]);
                    for l in 0..L {
                        d[l] += rj[l] * cn[l];
                    }
                }
                nxt[i..i + L].copy_from_slice(&d);
                x += L;
            } else {
                nxt[i] = step_pixel(a, off, g, h, w, cur, y, x);
                x += 1;
            }
        }
    }
}

/// One pixel of [`step`] with per-neighbour bounds tests (neighbours outside get weight 0).
#[allow(clippy::too_many_arguments)]
#[inline]
fn step_pixel<A: Map>(
    a: &A,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    cur: &[f32],
    y: usize,
    x: usize,
) -> f32 {
    let i = y * w + x;
    let mut r = [0f32; 48];
    let mut idx = [0usize; 48];
    let mut s = 0.0f32;
    for (j, &(dy, dx)) in off.iter().enumerate().take(48) {
        let (ny, nx) = (y as isize + dy, x as isize + dx);
        if ny < 0 || nx < 0 || ny >= h as isize || nx >= w as isize {
            r[j] = 0.0;
            idx[j] = i;
        } else {
            r[j] = relu(a.value(j, i)) * g[j];
            idx[j] = ny as usize * w + nx as usize;
        }
        s += r[j];
    }
    let n = off.len().min(48);
    let q = 1.0 / (1.0 + s);
    let mut wsum = 0.0f32;
    for rj in r[..n].iter_mut() {
        *rj *= q;
        wsum += *rj;
    }
    let mut d = (1.0 - wsum) * cur[i];
    for (&wj, &k) in r[..n].iter().zip(&idx[..n]) {
        d += wj * cur[k];
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::float;
    use std::vec::Vec;

    fn run(
        d0: &[f32],
        h: usize,
        w: usize,
        aff3: &[f32],
        km: [f32; 3],
        tm: [f32; 3],
        t: usize,
    ) -> Vec<f32> {
        let p = h * w;
        let z5 = std::vec![0f32; 24 * p];
        let z7 = std::vec![0f32; 48 * p];
        let kmix: Vec<f32> = km.iter().flat_map(|&v| std::iter::repeat_n(v, p)).collect();
        let tmix: Vec<f32> = tm.iter().flat_map(|&v| std::iter::repeat_n(v, p)).collect();
        let attrs = RefineAttrs {
            iterations: t,
            sigma: [1e6, 1.0, 1.0],
        };
        let mut out = std::vec![0f32; p];
        let mut scratch = std::vec![0f32; 2 * p];
        float::refine(
            d0,
            h,
            w,
            [aff3, &z5, &z7],
            &kmix,
            &tmix,
            &attrs,
            &mut out,
            &mut scratch,
        )
        .unwrap();
        out
    }

    #[test]
    fn one_neighbour_by_hand() {
        // 1×2 image, pixel 0 pulls from its right neighbour (raster index 4 of the 3×3 window)
        // with r = 1: w = 1/2, w_c = 1/2. d0 = [2, 4] → t1 [3, 4] → t2 [3.5, 4].
        let mut aff3 = std::vec![0f32; 8 * 2];
        aff3[4 * 2] = 1.0;
        let at_t = run(
            &[2.0, 4.0],
            1,
            2,
            &aff3,
            [60.0, 0.0, 0.0],
            [0.0, 0.0, 60.0],
            2,
        );
        assert!(
            (at_t[0] - 3.5).abs() < 1e-4 && (at_t[1] - 4.0).abs() < 1e-4,
            "{at_t:?}"
        );
        let at_half = run(
            &[2.0, 4.0],
            1,
            2,
            &aff3,
            [60.0, 0.0, 0.0],
            [0.0, 60.0, 0.0],
            2,
        );
        assert!((at_half[0] - 3.0).abs() < 1e-4, "{at_half:?}");
        // Equal mixes: (1/3)(d0 + D1 + D2) of kernel 3 weighted 1/3, plus 2/3 · d0 from 5 and 7.
        let mixed = run(&[2.0, 4.0], 1, 2, &aff3, [0.0; 3], [0.0; 3], 2);
        let want = (2.0 + 3.0 + 3.5) / 9.0 + 2.0 * 2.0 / 3.0;
        assert!((mixed[0] - want).abs() < 1e-4, "{mixed:?} vs {want}");
    }

    /// The driver of [`refine_with`] with every pixel through [`step_pixel`] and the scalar
    /// [`softmax3`]: the per-pixel order the module doc specifies.
    fn refine_per_pixel<A: Map, B: Map>(
        d0: &[f32],
        h: usize,
        w: usize,
        aff: [&A; 3],
        kmix: &B,
        tmix: &B,
        attrs: &RefineAttrs,
    ) -> Vec<f32> {
        let p = h * w;
        let t_max = attrs.iterations;
        let times = [0, t_max / 2, t_max];
        let mut out = std::vec![0f32; p];
        for (k, (&a, &s)) in aff.iter().zip(&KERNELS).enumerate() {
            let mut off = [(0isize, 0isize); 48];
            let nn = offsets(s, &mut off);
            let two_s2 = 2.0 * attrs.sigma[k] * attrs.sigma[k];
            let g: Vec<f32> = off[..nn]
                .iter()
                .map(|&(dy, dx)| exp(-((dx * dx + dy * dy) as f32) / two_s2))
                .collect();
            let mut cur = d0.to_vec();
            for t in 0..=t_max {
                if t > 0 {
                    cur = (0..p)
                        .map(|i| step_pixel(a, &off[..nn], &g, h, w, &cur, i / w, i % w))
                        .collect();
                }
                for (ti, &tt) in times.iter().enumerate() {
                    if tt == t {
                        for i in 0..p {
                            out[i] += (softmax3(tmix, i)[ti] * softmax3(kmix, i)[k]) * cur[i];
                        }
                    }
                }
            }
        }
        out
    }

    #[test]
    fn every_kernel_set_gives_the_per_pixel_bits() {
        let mut seed = 12345u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for (h, w) in [(9usize, 23usize), (16, 40), (3, 5)] {
            let p = h * w;
            let codes = |n: usize, next: &mut dyn FnMut() -> u32| -> Vec<i8> {
                (0..n).map(|_| next() as i8).collect()
            };
            let a3 = codes(8 * p, &mut next);
            let a5 = codes(24 * p, &mut next);
            let a7 = codes(48 * p, &mut next);
            let km = codes(3 * p, &mut next);
            let tm = codes(3 * p, &mut next);
            let d0: Vec<f32> = (0..p)
                .map(|_| 0.5 + (next() % 1000) as f32 * 0.007)
                .collect();
            fn m(d: &[i8], c: usize) -> I8Map<'_> {
                let q = QParams {
                    scale: 0.03,
                    zero_point: -20,
                };
                I8Map::new(d, q, c, d.len() / c).unwrap()
            }
            let (m3, m5, m7, kmx, tmx) = (m(&a3, 8), m(&a5, 24), m(&a7, 48), m(&km, 3), m(&tm, 3));
            let attrs = RefineAttrs {
                iterations: 4,
                sigma: [1.0, 1.5, 2.0],
            };
            let want = refine_per_pixel(&d0, h, w, [&m3, &m5, &m7], &kmx, &tmx, &attrs);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut out = std::vec![0f32; p];
                let mut scratch = std::vec![0f32; 2 * p];
                refine_with(
                    isa,
                    &d0,
                    h,
                    w,
                    [&m3, &m5, &m7],
                    &kmx,
                    &tmx,
                    &attrs,
                    &mut out,
                    &mut scratch,
                )
                .unwrap();
                let same = out
                    .iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    same,
                    "{} at {h}x{w}: lanes differ from the per-pixel order",
                    isa.name()
                );
            }
        }
    }

    #[test]
    fn constant_depth_is_a_fixed_point() {
        let (h, w) = (5, 6);
        let aff3: Vec<f32> = (0..8 * h * w)
            .map(|i| ((i * 7) % 5) as f32 * 0.3 - 0.2)
            .collect();
        let out = run(
            &std::vec![2.5; h * w],
            h,
            w,
            &aff3,
            [0.3, -1.0, 2.0],
            [1.0, 0.0, -1.0],
            6,
        );
        assert!(out.iter().all(|&v| (v - 2.5).abs() < 1e-5), "{out:?}");
    }

    #[test]
    fn rejects_bad_attrs_and_shapes() {
        let d0 = [1.0f32; 4];
        let a = std::vec![0f32; 48 * 4];
        let m = [0f32; 12];
        let mut o = [0f32; 4];
        let mut s = [0f32; 8];
        let bad_t = RefineAttrs {
            iterations: 3,
            sigma: [1.0; 3],
        };
        assert_eq!(
            float::refine(&d0, 2, 2, [&a, &a, &a], &m, &m, &bad_t, &mut o, &mut s),
            Err(KernelError::Attr)
        );
        let ok = RefineAttrs {
            iterations: 2,
            sigma: [1.0; 3],
        };
        assert_eq!(
            float::refine(&d0, 2, 2, [&a, &a, &a], &m, &m, &ok, &mut o, &mut s[..7]),
            Err(KernelError::Shape)
        );
        assert_eq!(
            float::refine(&d0, 2, 2, [&a[..31], &a, &a], &m, &m, &ok, &mut o, &mut s),
            Err(KernelError::Shape)
        );
    }
}
