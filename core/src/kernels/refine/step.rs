//! One propagation step of one refinement branch for one output row, in the order the module
//! doc of [`super`] fixes, with a path per kernel set: AVX2 / AVX-512 runs of 8 or 16 pixels
//! (x86), neighbour-major chunks for the portable set (Cortex-M, aarch64, the reference),
//! `L`-pixel lane groups for f32 maps, and [`step_pixel`] with per-neighbour bounds tests at
//! the left and right borders. Neighbours outside the image are skipped; the rest add their
//! terms in raster order. Every path adds the same terms in the same order per pixel, so the
//! bits do not depend on which ran.

use super::{I8Map, Map, Neighbourhood};
use crate::kernels::isa::Isa;
use crate::kernels::requant::QParams;
use crate::kernels::scalar::{exp, relu};
use crate::kernels::KernelError;

/// Most neighbours of a branch (7×7 − 1).
pub const MAX_NEIGHBOURS: usize = 48;

/// Pixels per lane group of the portable path: 4 where the baseline has 4-wide vectors (SSE2,
/// NEON), 1 on scalar FPUs (Cortex-M), where lane arrays only cost loads and stores.
const PORTABLE_LANES: usize = if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
    4
} else {
    1
};

/// The fixed tables of one branch at one image width: neighbour offsets in raster order
/// (centre skipped; [`Neighbourhood`] picks them), their Gaussians, and the offsets in a row-major buffer `w` wide.
#[derive(Clone, Debug)]
pub struct Branch {
    pub(super) off: [(isize, isize); MAX_NEIGHBOURS],
    pub(super) delta: [isize; MAX_NEIGHBOURS],
    pub(super) g: [f32; MAX_NEIGHBOURS],
    n: usize,
    rad: usize,
    /// `relu(dequantise(code))` per code of the int8 affinities of this branch, for the scalar
    /// path (`None` until [`Branch::set_quant`]).
    lut: Option<(QParams, [f32; 256])>,
}

impl Branch {
    /// Tables of the `size × size` window (odd, ≤ 7) with spatial σ `sigma`, its neighbours
    /// chosen by `nb`, `w` pixels wide.
    pub fn new(size: usize, sigma: f32, nb: Neighbourhood, w: usize) -> Branch {
        let rad = (size / 2).min(3);
        let mut b = Branch {
            off: [(0, 0); MAX_NEIGHBOURS],
            delta: [0; MAX_NEIGHBOURS],
            g: [0.0; MAX_NEIGHBOURS],
            n: 0,
            rad,
            lut: None,
        };
        let r = rad as isize;
        let two_s2 = 2.0 * sigma * sigma;
        for dy in -r..=r {
            for dx in -r..=r {
                if nb.contains(size, (dy, dx)) {
                    b.off[b.n] = (dy, dx);
                    b.delta[b.n] = dy * w as isize + dx;
                    b.g[b.n] = exp(-((dx * dx + dy * dy) as f32) / two_s2);
                    b.n += 1;
                }
            }
        }
        b
    }

    /// Neighbours (`size² − 1` for the whole window, 8 dilated).
    pub fn neighbours(&self) -> usize {
        self.n
    }

    /// Window radius.
    pub fn radius(&self) -> usize {
        self.rad
    }

    /// The neighbours (a contiguous run in raster order) whose row lies inside an image `h`
    /// rows high, for a pixel of row `y`.
    pub fn inside_rows(&self, h: usize, y: usize) -> core::ops::Range<usize> {
        let inside = |j: &usize| {
            let ny = y as isize + self.off[*j].0;
            ny >= 0 && ny < h as isize
        };
        let start = (0..self.n).find(inside).unwrap_or(self.n);
        let end = (start..self.n).rev().find(inside).map_or(start, |j| j + 1);
        start..end
    }

    /// Prepares the scalar path's table for int8 affinities quantised with `q`.
    pub fn set_quant(&mut self, q: QParams) {
        if self.lut.is_some_and(|(have, _)| have == q) {
            return;
        }
        let mut t = [0f32; 256];
        for (code, v) in t.iter_mut().enumerate() {
            *v = relu(q.dequantize(code as u8 as i8));
        }
        self.lut = Some((q, t));
    }
}

/// Where row `y` lives: its affinities start at `aff` in the affinity map (channel `j` at
/// `j · plane + aff`), the previous iteration's row at `cur` in the depth buffer (rows `w`
/// apart, rows `y − r ..= y + r` that lie in the image present).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowAt {
    /// Index of `(y, x = 0)` in channel 0 of the affinity map.
    pub aff: usize,
    /// Index of `(y, x = 0)` in the depth buffer.
    pub cur: usize,
}

/// Computes row `y` (of an `h × w` image) of one propagation step into `nxt[..w]`, from the
/// previous iteration's rows in `cur` and the branch's affinities `a`, both located by `at`.
/// `Err(Shape)` where a row, the window or an affinity channel is not where `at` says.
#[allow(clippy::too_many_arguments)]
pub fn step_row<A: Map>(
    isa: Isa,
    a: &A,
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) -> Result<(), KernelError> {
    let up = br.rad.min(y);
    let down = br.rad.min(h.saturating_sub(y + 1));
    let rows_ok = y < h
        && at.cur >= up * w
        && at
            .cur
            .checked_add((down + 1) * w)
            .is_some_and(|e| e <= cur.len());
    let aff_ok = a.channels() >= br.n && at.aff.checked_add(w).is_some_and(|e| e <= a.plane());
    if !rows_ok || !aff_ok || nxt.len() < w {
        return Err(KernelError::Shape);
    }
    let nxt = &mut nxt[..w];
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512Vnni if Isa::Avx2.available() => match a.as_i8() {
            Some(m) => row_i8_avx2(isa, m, br, h, w, y, at, cur, nxt),
            // SAFETY: AVX2 is available (checked).
            None => unsafe { row_avx2(a, br, h, w, y, at, cur, nxt) },
        },
        _ => match (a.as_i8(), &br.lut) {
            (Some(m), Some((q, lut))) if *q == m.q() => {
                return row_i8_chunks(isa, m, lut, br, h, w, y, at, cur, nxt)
            }
            _ => row_lanes::<A, PORTABLE_LANES>(a, br, h, w, y, at, cur, nxt),
        },
    }
    Ok(())
}

/// Pixels per chunk of [`row_i8_chunks`] (its two f32 accumulator rows live on the stack).
#[cfg(not(target_arch = "aarch64"))]
const CHUNK: usize = 64;
/// On aarch64 (a large stack), a whole row of the shipped sizes in one chunk: the per-chunk
/// look-ups of the neighbours' runs once per row (the same operations per pixel, so the same
/// bits).
#[cfg(target_arch = "aarch64")]
const CHUNK: usize = 256;

/// Row `y` on an int8 map for the portable kernel set: the columns whose windows lie inside
/// the image in chunks of [`CHUNK`] pixels, four neighbours at a time over each chunk
/// (`relu(dequantise(q))` from the branch's table, the same f32 values), so the inner loop has
/// no bounds test and vectorises where the target has vectors; every pixel still adds its terms
/// in neighbour order. Neighbour rows outside the image are skipped ([`Branch::inside_rows`]);
/// the `r` columns at each side go through [`step_pixel`].
#[allow(clippy::too_many_arguments)]
fn row_i8_chunks(
    isa: Isa,
    a: &I8Map,
    lut: &[f32; 256],
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) -> Result<(), KernelError> {
    // The kernel set picks the NEON chunk loop on aarch64; other targets have one loop.
    #[cfg(not(target_arch = "aarch64"))]
    let _ = isa;
    let rad = br.rad;
    let (x0, x1) = if w > 2 * rad { (rad, w - rad) } else { (w, w) };
    let inside = br.inside_rows(h, y);
    // On aarch64 the border columns four at a time (masked lanes), else pixel by pixel.
    #[cfg(target_arch = "aarch64")]
    let edges = matches!(isa, Isa::Neon | Isa::NeonDot)
        && x0 < x1
        && w >= 4
        && x0 <= 4
        && w - x1 <= 4
        && edges_neon(a, lut, br, &inside, w, (x0, x1), at, cur, nxt);
    #[cfg(not(target_arch = "aarch64"))]
    let edges = false;
    if !edges {
        for x in (0..x0.min(w)).chain(x1.max(x0)..w) {
            nxt[x] = border_pixel(a, lut, br, &inside, w, x, at, cur)?;
        }
    }
    let mut x = x0;
    while x < x1 {
        let len = (x1 - x).min(CHUNK);
        // The sums, then the accumulators, `CHUNK` apart (the Cortex-M loop's layout).
        // Only the chunk's `len` of each are written (zeros, the previous iteration's values)
        // and then read: the rest of the store stays uninitialised (zeroing all of it cost
        // more than the chunk's own work at the image widths shipped).
        let ic = at.cur + x;
        let start = cur.get(ic..ic + len).ok_or(KernelError::Shape)?;
        let mut store = core::mem::MaybeUninit::<[f32; 2 * CHUNK]>::uninit();
        let base = store.as_mut_ptr().cast::<f32>();
        // SAFETY: `len ≤ CHUNK`, so `base .. base + len` and `base + CHUNK .. + len` lie in the
        // store and do not overlap; both are written here (all-zero bits are `+0.0`) before the
        // slices over them are made, and `start` (another buffer) holds `len` values.
        let (s, acc) = unsafe {
            base.write_bytes(0, len);
            core::ptr::copy_nonoverlapping(start.as_ptr(), base.add(CHUNK), len);
            (
                core::slice::from_raw_parts_mut(base, len),
                core::slice::from_raw_parts_mut(base.add(CHUNK), len),
            )
        };
        // Neighbour j's codes and previous-iteration values over the chunk.
        let terms = |j: usize| -> Result<(&[i8], &[f32], f32), KernelError> {
            let ia = j * a.plane() + at.aff + x;
            let codes = a.data().get(ia..ia + len).ok_or(KernelError::Shape)?;
            let c0 = ic
                .checked_add_signed(br.delta[j])
                .ok_or(KernelError::Shape)?;
            let nb = cur.get(c0..c0 + len).ok_or(KernelError::Shape)?;
            Ok((codes, nb, br.g[j]))
        };
        let mut j = inside.start;
        while j + 4 <= inside.end {
            let [(q0, d0, g0), (q1, d1, g1), (q2, d2, g2), (q3, d3, g3)] =
                [terms(j)?, terms(j + 1)?, terms(j + 2)?, terms(j + 3)?];
            // Every slice is `len` long: the indexing below needs no bounds test.
            let (q0, q1, q2, q3) = (&q0[..len], &q1[..len], &q2[..len], &q3[..len]);
            let (d0, d1, d2, d3) = (&d0[..len], &d1[..len], &d2[..len], &d3[..len]);
            #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
            {
                use crate::kernels::arm::refine as arm;
                const _: () = assert!(arm::CHUNK == CHUNK);
                let q = [q0.as_ptr(), q1.as_ptr(), q2.as_ptr(), q3.as_ptr()];
                let d = [d0.as_ptr(), d1.as_ptr(), d2.as_ptr(), d3.as_ptr()];
                // SAFETY: the eight slices hold `len` ≥ 1 elements each; `s` starts `sums`,
                // whose accumulators lie CHUNK on; len ≤ CHUNK.
                unsafe { arm::four(q, d, [g0, g1, g2, g3], lut, s.as_mut_ptr(), len) };
                j += 4;
                continue;
            }
            #[cfg(target_arch = "aarch64")]
            if matches!(isa, Isa::Neon | Isa::NeonDot) {
                use crate::kernels::aarch64::refine as neon;
                let (q, d) = ([q0, q1, q2, q3], [d0, d1, d2, d3]);
                if neon::four(q, d, [g0, g1, g2, g3], (lut, a.q()), s, acc) {
                    j += 4;
                    continue;
                }
            }
            #[allow(unreachable_code)]
            for i in 0..len {
                let r0 = lut[q0[i] as u8 as usize] * g0;
                let r1 = lut[q1[i] as u8 as usize] * g1;
                let r2 = lut[q2[i] as u8 as usize] * g2;
                let r3 = lut[q3[i] as u8 as usize] * g3;
                s[i] = (((s[i] + r0) + r1) + r2) + r3;
                acc[i] = (((acc[i] + r0 * d0[i]) + r1 * d1[i]) + r2 * d2[i]) + r3 * d3[i];
            }
            j += 4;
        }
        for j in j..inside.end {
            let (codes, nb, g) = terms(j)?;
            for (((s, acc), &q), &d) in s.iter_mut().zip(acc.iter_mut()).zip(codes).zip(nb) {
                let r = lut[q as u8 as usize] * g;
                *s += r;
                *acc += r * d;
            }
        }
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot) {
            crate::kernels::aarch64::refine::divide(&mut nxt[x..x + len], s, acc);
            x += len;
            continue;
        }
        for ((o, &s), &acc) in nxt[x..x + len].iter_mut().zip(s.iter()).zip(acc.iter()) {
            *o = acc / (1.0 + s);
        }
        x += len;
    }
    Ok(())
}

/// The border columns `0 .. x0` and `x1 .. w` of [`row_i8_chunks`] (`x0 ≤ 4 ≤ w`) as two
/// groups of four pixels (`0 .. 4` and `w − 4 .. w`) through the NEON
/// [`crate::kernels::aarch64::refine::edge4`]: each lane adds the terms of the neighbours inside
/// the image in [`border_pixel`]'s order and skips the others, so a border pixel gets
/// [`border_pixel`]'s bits; only the border lanes are written. `false` (nothing written) where
/// a group's reads would leave the buffers (then [`border_pixel`] runs).
#[cfg(target_arch = "aarch64")]
#[allow(clippy::too_many_arguments)]
fn edges_neon(
    a: &I8Map,
    lut: &[f32; 256],
    br: &Branch,
    inside: &core::ops::Range<usize>,
    w: usize,
    (x0, x1): (usize, usize),
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) -> bool {
    use crate::kernels::aarch64::refine::edge4;
    let (codes, plane) = (a.data(), a.plane());
    let js = inside.clone();
    let terms = (
        &br.delta[js.clone()],
        &br.off[js.clone()],
        &br.g[js.clone()],
    );
    let group = |gx: usize| {
        let q0 = js.start * plane + at.aff + gx;
        edge4((codes, q0, plane), (cur, at.cur + gx), terms, lut, gx, w)
    };
    let (Some(left), Some(right)) = (group(0), group(w - 4)) else {
        return false;
    };
    nxt[..x0].copy_from_slice(&left[..x0]);
    let r = x1 - (w - 4);
    nxt[x1..w].copy_from_slice(&right[r..]);
    true
}

/// [`step_pixel`] on an int8 map through the branch's table (`lut[q] = relu(dequantise(q))`, the
/// same f32 value), with the row test done once by `inside` ([`Branch::inside_rows`]): the `r`
/// border columns of [`row_i8_chunks`].
#[allow(clippy::too_many_arguments)]
#[inline]
fn border_pixel(
    a: &I8Map,
    lut: &[f32; 256],
    br: &Branch,
    inside: &core::ops::Range<usize>,
    w: usize,
    x: usize,
    at: RowAt,
    cur: &[f32],
) -> Result<f32, KernelError> {
    let (ia, ic) = (at.aff + x, at.cur + x);
    let (codes, plane) = (a.data(), a.plane());
    let mut s = 0.0f32;
    let mut acc = *cur.get(ic).ok_or(KernelError::Shape)?;
    for j in inside.clone() {
        let nx = x as isize + br.off[j].1;
        if nx < 0 || nx >= w as isize {
            continue;
        }
        let q = *codes.get(j * plane + ia).ok_or(KernelError::Shape)?;
        let d = ic
            .checked_add_signed(br.delta[j])
            .and_then(|i| cur.get(i))
            .ok_or(KernelError::Shape)?;
        let r = lut[q as u8 as usize] * br.g[j];
        s += r;
        acc += r * d;
    }
    Ok(acc / (1.0 + s))
}

/// Row `y` on an int8 map with the AVX2 / AVX-512 run kernel for the interior pixels and
/// masked 8-pixel chunks for the rest.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
fn row_i8_avx2(
    isa: Isa,
    a: &I8Map,
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) {
    use crate::kernels::x86_64::refine as simd;
    let (n, rad) = (br.n, br.rad);
    let (mut x0, mut x1) = (0, 0);
    if w > 2 * rad {
        let wide = isa == Isa::Avx512Vnni && Isa::Avx512Vnni.available();
        let lanes = if wide { 16 } else { 8 };
        x0 = rad;
        x1 = rad + (w - 2 * rad) / lanes * lanes;
        let inside = br.inside_rows(h, y);
        let args = (inside.start, &br.delta[inside.clone()], &br.g[inside]);
        // SAFETY: AVX2 (and AVX-512 F for `wide`) is available (the caller's match and the test
        // above); `step_row` checked that `a` has ≥ n channels holding `at.aff .. + w` and that
        // the rows of y − rad ..= y + rad inside the image are in `cur` around `at.cur`; the
        // neighbours passed are those whose row is inside, so every window of x0..x1 reads
        // inside both.
        unsafe {
            if wide {
                simd::step_run512(a, args, at, x0, x1, cur, nxt)
            } else {
                simd::step_run(a, args, at, x0, x1, cur, nxt)
            }
        };
    }
    if w < 8 {
        for x in (0..x0).chain(x1..w) {
            nxt[x] = step_pixel(a, br, h, w, y, x, at, cur);
        }
        return;
    }
    // The rest of the row in masked chunks of 8 (a chunk may overlap the interior run or the
    // previous chunk; it writes the same values, which depend on `cur` only).
    for xc in (0..x0).step_by(8).chain((x1..w).step_by(8)) {
        let xc = xc.min(w - 8);
        // SAFETY: AVX2 is available (the caller's match); `step_row` checked the affinity row
        // and that the image rows around y are in `cur`; xc + 8 ≤ w.
        unsafe { simd::step_masked(a, &br.off[..n], &br.g[..n], h, w, y, xc, at, cur, nxt) };
    }
}

/// # Safety
/// The CPU must have AVX2 (the only requirement: `row_lanes` indexes the slices with bounds
/// checks; the feature only lets it be vectorised).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn row_avx2<A: Map>(
    a: &A,
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) {
    row_lanes::<A, 8>(a, br, h, w, y, at, cur, nxt)
}

/// Row `y`, `L` pixels at a time where their windows lie inside the image.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn row_lanes<A: Map, const L: usize>(
    a: &A,
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let (n, rad) = (br.n, br.rad);
    let inner_row = y >= rad && y + rad < h;
    let mut x = 0;
    while x < w {
        if !(inner_row && x >= rad && x + L - 1 + rad < w) {
            nxt[x] = step_pixel(a, br, h, w, y, x, at, cur);
            x += 1;
            continue;
        }
        let (ia, ic) = (at.aff + x, at.cur + x);
        let mut s = [0f32; L];
        let c: &[f32; L] = cur[ic..ic + L].try_into().unwrap_or(&[0.0; L]);
        let mut acc = *c;
        for (j, (&gj, &dj)) in br.g[..n].iter().zip(&br.delta).enumerate() {
            let v = a.values::<L>(j, ia);
            let k = (ic as isize + dj) as usize;
            let cn: &[f32; L] = cur[k..k + L].try_into().unwrap_or(&[0.0; L]);
            for l in 0..L {
                let r = relu(v[l]) * gj;
                s[l] += r;
                acc[l] += r * cn[l];
            }
        }
        let mut d = [0f32; L];
        for l in 0..L {
            d[l] = acc[l] / (1.0 + s[l]);
        }
        nxt[x..x + L].copy_from_slice(&d);
        x += L;
    }
}

/// Pixel `(y, x)` of one step with per-neighbour bounds tests (neighbours outside the image are
/// skipped).
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn step_pixel<A: Map>(
    a: &A,
    br: &Branch,
    h: usize,
    w: usize,
    y: usize,
    x: usize,
    at: RowAt,
    cur: &[f32],
) -> f32 {
    let (ia, ic) = (at.aff + x, at.cur + x);
    let mut s = 0.0f32;
    let mut acc = cur[ic];
    for j in 0..br.n {
        let (dy, dx) = br.off[j];
        let (ny, nx) = (y as isize + dy, x as isize + dx);
        if ny < 0 || nx < 0 || ny >= h as isize || nx >= w as isize {
            continue;
        }
        let r = relu(a.value(j, ia)) * br.g[j];
        s += r;
        acc += r * cur[(ic as isize + br.delta[j]) as usize];
    }
    acc / (1.0 + s)
}
