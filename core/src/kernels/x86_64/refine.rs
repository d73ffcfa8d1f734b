//! AVX2 / AVX-512 refinement on int8 maps, 8 or 16 pixels per vector: [`crate::kernels::refine`]'s step and
//! output accumulation with every pixel's operations in the module doc's order (IEEE
//! multiply, add, divide, max, table gather; no FMA), so the bits equal the per-pixel path's.

use crate::kernels::refine::I8Map;
use crate::kernels::refine::RowAt;
use core::arch::x86_64::*;

/// Dequantised codes `i..i + 8` of channel `c`: `scale · (q − zp)`.
///
/// # Safety
/// The CPU must have AVX2 and codes `c·plane + i .. c·plane + i + 8` must lie inside `m`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn load8(m: &I8Map, c: usize, i: usize) -> __m256 {
    let p = m.data().as_ptr().add(c * m.plane() + i);
    <__m256 as Lanes>::dequant(p, m.q().zero_point, m.q().scale)
}

/// The f32 vector operations the interior step needs, for 8 (AVX2) and 16 (AVX-512) lanes.
/// Every method is one IEEE instruction (or a load), so both widths give each pixel the same
/// operations in the same order.
///
/// # Safety
/// Every method needs the CPU feature of its vector type (AVX2 for `__m256`, AVX-512 F for
/// `__m512`); `dequant`, `load` and `store` read or write `L` elements at `p`, which must be
/// valid for that. The implementations below carry this contract.
trait Lanes: Copy {
    /// Pixels per vector.
    const L: usize;
    unsafe fn zero() -> Self;
    unsafe fn splat(v: f32) -> Self;
    /// `scale · (q − zp)` of the `L` codes at `p`.
    unsafe fn dequant(p: *const i8, zp: i32, scale: f32) -> Self;
    unsafe fn max(a: Self, b: Self) -> Self;
    unsafe fn add(a: Self, b: Self) -> Self;
    unsafe fn mul(a: Self, b: Self) -> Self;
    unsafe fn div(a: Self, b: Self) -> Self;
    unsafe fn load(p: *const f32) -> Self;
    unsafe fn store(p: *mut f32, v: Self);
}

// SAFETY: each method is one AVX2 instruction (or an unaligned load/store of 8 lanes at `p`),
// under the [`Lanes`] contract: the caller has AVX2 and `p` valid for 8 elements.
impl Lanes for __m256 {
    const L: usize = 8;
    #[inline(always)]
    unsafe fn zero() -> Self {
        _mm256_setzero_ps()
    }
    #[inline(always)]
    unsafe fn splat(v: f32) -> Self {
        _mm256_set1_ps(v)
    }
    #[inline(always)]
    unsafe fn dequant(p: *const i8, zp: i32, scale: f32) -> Self {
        let q = _mm256_cvtepi8_epi32(_mm_loadl_epi64(p as *const __m128i));
        let d = _mm256_sub_epi32(q, _mm256_set1_epi32(zp));
        _mm256_mul_ps(_mm256_set1_ps(scale), _mm256_cvtepi32_ps(d))
    }
    #[inline(always)]
    unsafe fn max(a: Self, b: Self) -> Self {
        _mm256_max_ps(a, b)
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        _mm256_add_ps(a, b)
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        _mm256_mul_ps(a, b)
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        _mm256_div_ps(a, b)
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        _mm256_loadu_ps(p)
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: Self) {
        _mm256_storeu_ps(p, v)
    }
}

// SAFETY: each method is one AVX-512 F instruction (or an unaligned load/store of 16 lanes at
// `p`), under the [`Lanes`] contract: the caller has AVX-512 F and `p` valid for 16 elements.
impl Lanes for __m512 {
    const L: usize = 16;
    #[inline(always)]
    unsafe fn zero() -> Self {
        _mm512_setzero_ps()
    }
    #[inline(always)]
    unsafe fn splat(v: f32) -> Self {
        _mm512_set1_ps(v)
    }
    #[inline(always)]
    unsafe fn dequant(p: *const i8, zp: i32, scale: f32) -> Self {
        let q = _mm512_cvtepi8_epi32(_mm_loadu_si128(p as *const __m128i));
        let d = _mm512_sub_epi32(q, _mm512_set1_epi32(zp));
        _mm512_mul_ps(_mm512_set1_ps(scale), _mm512_cvtepi32_ps(d))
    }
    #[inline(always)]
    unsafe fn max(a: Self, b: Self) -> Self {
        _mm512_max_ps(a, b)
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        _mm512_add_ps(a, b)
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        _mm512_mul_ps(a, b)
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        _mm512_div_ps(a, b)
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        _mm512_loadu_ps(p)
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: Self) {
        _mm512_storeu_ps(p, v)
    }
}

/// Pixels `x0..x1` of a row located by `at` (`x1 − x0` a multiple of `L`) of one propagation
/// step into `nxt[x0..x1]`, `L` pixels per vector, over the neighbours `j0 ..` whose offsets
/// and Gaussians are `delta`, `g` (those whose row is inside the image; their columns inside
/// for every pixel of `x0..x1`).
///
/// # Safety
/// The conditions of [`step_run`] with `x1 − x0` a multiple of `V::L`, and the CPU feature
/// of `V` (see [`Lanes`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn step_lanes<V: Lanes>(
    a: &I8Map,
    (j0, delta, g): (usize, &[isize], &[f32]),
    at: RowAt,
    x0: usize,
    x1: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let n = delta.len().min(48);
    let (zp, scale) = (a.q().zero_point, a.q().scale);
    let data = a.data().as_ptr();
    let plane = a.plane();
    let zero = V::zero();
    let one = V::splat(1.0);
    let c = cur.as_ptr();
    let mut x = x0;
    while x + V::L <= x1 {
        let (ia, i) = (at.aff + x, at.cur + x);
        let mut s = zero;
        let mut acc = V::load(c.add(i));
        for (j, (&gj, &dj)) in g[..n].iter().zip(delta).enumerate() {
            let v = V::max(V::dequant(data.add((j0 + j) * plane + ia), zp, scale), zero);
            let r = V::mul(v, V::splat(gj));
            s = V::add(s, r);
            let cn = V::load(c.offset(i as isize + dj));
            acc = V::add(acc, V::mul(r, cn));
        }
        let d = V::div(acc, V::add(one, s));
        V::store(nxt.as_mut_ptr().add(x), d);
        x += V::L;
    }
}

/// `step_lanes` with 8 lanes over `neighbours = (j0, delta, g)`. Callers check that `a` has
/// `j0 + delta.len()` channels holding `at.aff + x` for `x < x1`, that every
/// `at.cur + x + delta` of `x0..x1` lies in `cur`, and that `nxt` holds `x1` values.
///
/// # Safety
/// The CPU must have AVX2 and the conditions above must hold.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn step_run(
    a: &I8Map,
    neighbours: (usize, &[isize], &[f32]),
    at: RowAt,
    x0: usize,
    x1: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    step_lanes::<__m256>(a, neighbours, at, x0, x1, cur, nxt)
}

/// [`step_run`] with 16 lanes (`x1 − x0` a multiple of 16).
///
/// # Safety
/// The CPU must have AVX-512 F and the conditions of [`step_run`] must hold.
#[target_feature(enable = "avx512f,avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn step_run512(
    a: &I8Map,
    neighbours: (usize, &[isize], &[f32]),
    at: RowAt,
    x0: usize,
    x1: usize,
    cur: &[f32],
    nxt: &mut [f32],
) {
    step_lanes::<__m512>(a, neighbours, at, x0, x1, cur, nxt)
}

/// Codes `i..i + 8` of channel `c` as i32.
///
/// # Safety
/// The CPU must have AVX2 and codes `c·plane + i .. c·plane + i + 8` must lie inside `m`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn codes8(m: &I8Map, c: usize, i: usize) -> __m256i {
    let p = m.data().as_ptr().add(c * m.plane() + i);
    _mm256_cvtepi8_epi32(_mm_loadl_epi64(p as *const __m128i))
}

/// `Mix::at` of pixels `i..i + 8` of a 3-channel int8 map with its exponential table `e`.
///
/// # Safety
/// The CPU must have AVX2, `m` must have 3 channels and pixels `i .. i + 8` must lie inside
/// each; the gathers index `e` with `max − q ∈ 0..=255`, inside the table.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn softmax3(m: &I8Map, e: &[f32; 256], i: usize) -> [__m256; 3] {
    let q = [codes8(m, 0, i), codes8(m, 1, i), codes8(m, 2, i)];
    let mx = _mm256_max_epi32(_mm256_max_epi32(q[0], q[1]), q[2]);
    // max − q ∈ 0..=255 for int8 codes: inside the table.
    let e = q.map(|q| _mm256_i32gather_ps::<4>(e.as_ptr(), _mm256_sub_epi32(mx, q)));
    let s = _mm256_add_ps(_mm256_add_ps(e[0], e[1]), e[2]);
    e.map(|e| _mm256_div_ps(e, s))
}

/// `out[i] += (tmix.at(first + i)[ti] · kmix.at(first + i)[k]) · cur[i]` (`refine::Mix`) for
/// the first `⌊p/8⌋·8` values, which are the map pixels `first ..`; returns how many.
///
/// # Safety
/// The CPU must have AVX2 and both maps 3 channels over ≥ `first + p` pixels.
#[target_feature(enable = "avx2")]
pub unsafe fn accumulate(
    out: &mut [f32],
    cur: &[f32],
    tmix: (&I8Map, &[f32; 256]),
    kmix: (&I8Map, &[f32; 256]),
    ti: usize,
    k: usize,
    first: usize,
) -> usize {
    let p = out.len().min(cur.len());
    let mut i = 0;
    while i + 8 <= p {
        let t = softmax3(tmix.0, tmix.1, first + i)[ti.min(2)];
        let m = softmax3(kmix.0, kmix.1, first + i)[k.min(2)];
        let o = out.as_mut_ptr().add(i);
        let add = _mm256_mul_ps(_mm256_mul_ps(t, m), _mm256_loadu_ps(cur.as_ptr().add(i)));
        _mm256_storeu_ps(o, _mm256_add_ps(_mm256_loadu_ps(o), add));
        i += 8;
    }
    i
}

/// Pixels `x0..x0 + 8` (`x0 + 8 ≤ w`) of row `y`, located by `at`, of one propagation step with
/// neighbours outside the image skipped per lane (their sums keep the lane's previous value),
/// as the per-pixel path skips them. Callers check that `a` has `off.len()`
/// channels holding `at.aff .. + w`, that the image rows around `y` lie in `cur` around
/// `at.cur`, and that `nxt` holds `w` values.
///
/// # Safety
/// The CPU must have AVX2 and the conditions above must hold.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn step_masked(
    a: &I8Map,
    off: &[(isize, isize)],
    g: &[f32],
    h: usize,
    w: usize,
    y: usize,
    x0: usize,
    at: RowAt,
    cur: &[f32],
    nxt: &mut [f32],
) {
    let n = off.len().min(48).min(g.len());
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let (ia, i) = (at.aff + x0, at.cur + x0);
    let c = cur.as_ptr();
    let own = _mm256_loadu_ps(c.add(i));
    let mut s = zero;
    let mut acc = own;
    for j in 0..n {
        let (dy, dx) = off[j];
        let ny = y as isize + dy;
        if ny < 0 || ny >= h as isize {
            continue;
        }
        let xs = _mm256_add_epi32(lane, _mm256_set1_epi32((x0 as isize + dx) as i32));
        let valid = _mm256_and_si256(
            _mm256_cmpgt_epi32(xs, _mm256_set1_epi32(-1)),
            _mm256_cmpgt_epi32(_mm256_set1_epi32(w as i32), xs),
        );
        let keep = _mm256_castsi256_ps(valid);
        let v = _mm256_max_ps(load8(a, j, ia), zero);
        let r = _mm256_mul_ps(v, _mm256_set1_ps(g[j]));
        s = _mm256_blendv_ps(s, _mm256_add_ps(s, r), keep);
        let k = i as isize + dy * w as isize + dx;
        // Masked-off lanes are not read (maskload does not fault on them) and not added.
        let cn = _mm256_maskload_ps(c.offset(k), valid);
        acc = _mm256_blendv_ps(acc, _mm256_add_ps(acc, _mm256_mul_ps(r, cn)), keep);
    }
    let d = _mm256_div_ps(acc, _mm256_add_ps(one, s));
    _mm256_storeu_ps(nxt.as_mut_ptr().add(x0), d);
}
