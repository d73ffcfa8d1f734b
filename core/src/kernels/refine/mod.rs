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
//! raster order: for neighbours `j` in raster order, `r_j = relu(aff_k[j]) · g_j` (0 outside
//! the image, where `D_j` stands for the pixel's own `D`), `S += r_j` from `S = 0` and
//! `A += r_j · D_j` from `A = D`, then `D' = A / (1 + S)`: one pass over the neighbours, one
//! division. This is docs/graph.md's `w_c·D + Σ w_j·D_j` with `w_j = r_j/(1 + S)` and
//! `w_c = 1/(1 + S)`, rounded differently. The Gaussians `g_j = exp(−(dx²+dy²)/(2σ_k²))` are
//! computed once per run with [`super::scalar::exp`]. After `t ∈ {0, T/2, T}` the output gains
//! `(τ_t · σ_k) · D_{k,t}` with `σ`, `τ` the per-pixel 3-way softmaxes of kmix / tmix
//! ([`Mix`]: on int8 maps the exponentials come from a 256-entry table of the code distance).
//! The output map is the accumulator.
//!
//! **Streaming (a wavefront over rows).** No iteration and no affinity map is ever held whole.
//! Per branch of radius `r`, pass step `s` computes row `s − t·r` of iteration `t` for
//! `t = 1..=T` in that order: the rows `y − r ..= y + r` of iteration `t − 1` it reads were
//! computed at this or an earlier step. Each iteration `1..T` keeps a window of
//! [`WINDOW_ROWS`] rows; the affinities come row by row from an [`AffinityRows`] source, which
//! must keep rows `s − T·r ..= s − r` readable (a ring of [`ring_rows`] rows, or the whole map:
//! [`WholeMaps`]). `D_0` comes row by row from a [`DepthRows`] source (row `s` at step `s`, into
//! iteration 0's window) and kmix/tmix from a [`MixRows`] source that keeps rows
//! `s − T·3 ..= s` readable ([`mix_ring_rows`]); the `t = 0` terms of row `s` are added at step
//! `s`. Every pixel still gets the operations above in the same order, so the bits equal the
//! whole-map order's. Scratch: [`scratch_len`] f32 (`(T·`[`WINDOW_ROWS`]` + 1)·W`), against `2·H·W` for
//! ping-pong maps.

mod heads;
mod step;

pub use heads::{ConvRows, Head, MixConvRows};
pub use step::{step_pixel, step_row, Branch, RowAt, MAX_NEIGHBOURS};

use super::isa::Isa;
use super::requant::QParams;
use super::resize::upsample_bilinear_f32_row;
use super::scalar::exp;
use super::{KernelError, Shape};

/// Most iterations accepted.
pub const MAX_ITERATIONS: usize = 64;
/// Kernel sizes of the three branches.
pub const KERNELS: [usize; 3] = [3, 5, 7];

/// Which pixels of a branch's `s × s` window are its neighbours (docs/graph.md `refine`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Neighbourhood {
    /// Every pixel of the window but the centre: 8, 24, 48 neighbours (the paper's).
    #[default]
    Window,
    /// The 8 pixels of a 3×3 window dilated by `s / 2` (1, 2, 3): 8 neighbours per branch.
    Dilated,
}

impl Neighbourhood {
    /// The blob's code (docs/blob.md): 0 window, 1 dilated.
    pub fn code(self) -> u16 {
        match self {
            Neighbourhood::Window => 0,
            Neighbourhood::Dilated => 1,
        }
    }

    /// The neighbourhood of a blob code, `None` for an unknown one.
    pub fn from_code(code: u16) -> Option<Self> {
        match code {
            0 => Some(Neighbourhood::Window),
            1 => Some(Neighbourhood::Dilated),
            _ => None,
        }
    }

    /// Neighbours (affinity channels) of the `size × size` branch.
    pub fn neighbours(self, size: usize) -> usize {
        match self {
            Neighbourhood::Window => (size * size).saturating_sub(1),
            Neighbourhood::Dilated => 8,
        }
    }

    /// Whether window offset `(dy, dx)` of the `size × size` branch is a neighbour.
    pub fn contains(self, size: usize, (dy, dx): (isize, isize)) -> bool {
        let r = (size / 2) as isize;
        let inside = dy.abs() <= r && dx.abs() <= r && (dy, dx) != (0, 0);
        match self {
            Neighbourhood::Window => inside,
            Neighbourhood::Dilated => inside && dy % r.max(1) == 0 && dx % r.max(1) == 0,
        }
    }
}

/// Attributes of `refine`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineAttrs {
    /// `T` (even, ≤ [`MAX_ITERATIONS`]).
    pub iterations: usize,
    /// `[σ3, σ5, σ7]` of the spatial Gaussians (> 0).
    pub sigma: [f32; 3],
    /// The neighbours of each branch.
    pub neighbourhood: Neighbourhood,
}

impl RefineAttrs {
    /// Affinity channels of branch `k` (0, 1, 2 for kernels 3, 5, 7).
    pub fn neighbours(&self, k: usize) -> usize {
        self.neighbourhood.neighbours(KERNELS[k.min(2)])
    }
}

/// A multi-channel `H×W` map read as f32 (int8 maps dequantise on the fly).
pub trait Map {
    /// Channels available.
    fn channels(&self) -> usize;
    /// Pixels per channel (the channel stride).
    fn plane(&self) -> usize;
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
    fn plane(&self) -> usize {
        self.plane
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
    fn plane(&self) -> usize {
        self.plane
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

impl<M: Map> Map for &M {
    fn channels(&self) -> usize {
        (**self).channels()
    }
    fn plane(&self) -> usize {
        (**self).plane()
    }
    #[inline]
    fn value(&self, c: usize, i: usize) -> f32 {
        (**self).value(c, i)
    }
    fn as_i8(&self) -> Option<&I8Map<'_>> {
        (**self).as_i8()
    }
    #[inline(always)]
    fn values<const L: usize>(&self, c: usize, i: usize) -> [f32; L] {
        (**self).values::<L>(c, i)
    }
}

/// Where the refinement reads its affinities, one row at a time (module doc, "Streaming").
pub trait AffinityRows {
    /// The map [`AffinityRows::view`] returns.
    type View<'v>: Map
    where
        Self: 'v;
    /// Makes row `y` of branch `k` (`0..3`: kernels 3, 5, 7) readable. Rows of a branch are
    /// asked for in increasing order, once each.
    fn compute(&mut self, k: usize, y: usize) -> Result<(), KernelError>;
    /// The map holding row `y` of branch `k` and the index of its pixel `(y, 0)` in channel 0
    /// (valid for rows `y − (T − 1)·r ..= y` of the latest [`AffinityRows::compute`]). One
    /// branch's rows share one quantisation.
    fn view(&self, k: usize, y: usize) -> Result<(Self::View<'_>, usize), KernelError>;
}

/// [`AffinityRows`] over three whole `H×W` maps.
#[derive(Clone, Copy, Debug)]
pub struct WholeMaps<'m, A: Map> {
    maps: [&'m A; 3],
    w: usize,
}

impl<'m, A: Map> WholeMaps<'m, A> {
    /// The maps of kernels 3, 5 and 7 (at least 8, 24 and 48 channels) of an image `w` wide.
    pub fn new(maps: [&'m A; 3], w: usize) -> Self {
        WholeMaps { maps, w }
    }
}

impl<A: Map> AffinityRows for WholeMaps<'_, A> {
    type View<'v>
        = &'v A
    where
        Self: 'v;
    fn compute(&mut self, _k: usize, _y: usize) -> Result<(), KernelError> {
        Ok(())
    }
    fn view(&self, k: usize, y: usize) -> Result<(&A, usize), KernelError> {
        Ok((self.maps[k.min(2)], y * self.w))
    }
}

/// Where the refinement reads its initial depth `D_0`, one row at a time.
pub trait DepthRows {
    /// Writes row `y` of `D_0` (`w` values) into `dst`. Within a branch rows are asked for in
    /// increasing order, once each; the next branch starts again at row 0.
    fn row(&mut self, y: usize, dst: &mut [f32]) -> Result<(), KernelError>;
}

/// [`DepthRows`] over a whole `H×W` map.
#[derive(Clone, Copy, Debug)]
pub struct WholeDepth<'a> {
    d0: &'a [f32],
    w: usize,
}

impl<'a> WholeDepth<'a> {
    /// `d0` holds `H×W` values of an image `w` wide.
    pub fn new(d0: &'a [f32], w: usize) -> Self {
        WholeDepth { d0, w }
    }
}

impl DepthRows for WholeDepth<'_> {
    fn row(&mut self, y: usize, dst: &mut [f32]) -> Result<(), KernelError> {
        let w = self.w;
        let src = y
            .checked_mul(w)
            .and_then(|a| self.d0.get(a..a.checked_add(w)?))
            .ok_or(KernelError::Shape)?;
        dst.get_mut(..w)
            .ok_or(KernelError::Shape)?
            .copy_from_slice(src);
        Ok(())
    }
}

/// [`DepthRows`] resizing a lower-resolution f32 map row by row
/// ([`crate::kernels::resize::upsample_bilinear_f32_row`], the bits of the whole resize), so
/// that `D_0` is never stored at full resolution.
#[derive(Clone, Copy, Debug)]
pub struct UpsampledDepth<'a> {
    input: &'a [f32],
    in_shape: Shape,
    out_shape: Shape,
}

impl<'a> UpsampledDepth<'a> {
    /// `input` (`in_shape`, one channel) resized to `h × w`.
    pub fn new(input: &'a [f32], in_shape: Shape, h: usize, w: usize) -> Self {
        UpsampledDepth {
            input,
            in_shape,
            out_shape: Shape::new(1, h, w),
        }
    }
}

impl DepthRows for UpsampledDepth<'_> {
    fn row(&mut self, y: usize, dst: &mut [f32]) -> Result<(), KernelError> {
        upsample_bilinear_f32_row(self.input, self.in_shape, 0, y, dst, self.out_shape)
    }
}

/// Where the refinement reads its kmix and tmix maps (3 channels each), one row at a time.
pub trait MixRows {
    /// The map [`MixRows::view`] returns.
    type View<'v>: Map
    where
        Self: 'v;
    /// Makes row `y` of both maps readable. Within a branch rows are asked for in increasing
    /// order, once each; the next branch starts again at row 0.
    fn compute(&mut self, y: usize) -> Result<(), KernelError>;
    /// The kmix and tmix maps holding row `y` and the index of its pixel `(y, 0)` in channel 0
    /// (valid for rows `y − T·3 ..= y` of the latest [`MixRows::compute`], [`mix_ring_rows`]).
    /// Each map's rows share one quantisation.
    fn view(&self, y: usize) -> Result<(Self::View<'_>, Self::View<'_>, usize), KernelError>;
}

/// [`MixRows`] over whole `H×W` kmix and tmix maps.
#[derive(Clone, Copy, Debug)]
pub struct WholeMix<'m, B: Map> {
    kmix: &'m B,
    tmix: &'m B,
    w: usize,
}

impl<'m, B: Map> WholeMix<'m, B> {
    /// kmix and tmix (≥ 3 channels each) of an image `w` wide.
    pub fn new(kmix: &'m B, tmix: &'m B, w: usize) -> Self {
        WholeMix { kmix, tmix, w }
    }
}

impl<B: Map> MixRows for WholeMix<'_, B> {
    type View<'v>
        = &'v B
    where
        Self: 'v;
    fn compute(&mut self, _y: usize) -> Result<(), KernelError> {
        Ok(())
    }
    fn view(&self, y: usize) -> Result<(&B, &B, usize), KernelError> {
        Ok((self.kmix, self.tmix, y * self.w))
    }
}

/// Rows a streaming [`MixRows`] must keep readable at once in an image `h` rows high:
/// `T·3 + 1` (the `t = T` terms of the widest branch come `T·3` rows after the `t = 0` ones),
/// at most `h`.
pub fn mix_ring_rows(h: usize, iterations: usize) -> usize {
    iterations
        .saturating_mul(KERNELS[2] / 2)
        .saturating_add(1)
        .min(h.max(1))
}

/// Rows each iteration's window holds (≥ `2r + 1` for the largest radius, 3).
pub const WINDOW_ROWS: usize = 8;

/// f32 scratch elements [`refine_with`] needs for an image `w` wide and `iterations` steps:
/// a window per iteration `0..T` and the last iteration's row, then the two mixing maps'
/// softmax tables ([`Mix`], 2 × 256; in the arena rather than on a microcontroller's stack).
pub fn scratch_len(w: usize, iterations: usize) -> usize {
    windows_len(w, iterations).saturating_add(MIX_TABLES)
}

/// f32 elements of the softmax tables at the end of [`refine_with`]'s scratch.
const MIX_TABLES: usize = 2 * 256;

/// The first 256 elements of `s` as one [`Mix`] table's storage.
fn mix_store(s: &mut [f32]) -> Result<&mut [f32; 256], KernelError> {
    s.get_mut(..256)
        .and_then(|s| s.try_into().ok())
        .ok_or(KernelError::Shape)
}

/// The windows' part of [`scratch_len`].
fn windows_len(w: usize, iterations: usize) -> usize {
    iterations
        .max(1)
        .saturating_mul(WINDOW_ROWS)
        .saturating_add(1)
        .saturating_mul(w)
}

/// Affinity rows of branch `k` a streaming [`AffinityRows`] must keep readable at once in an
/// image `h` rows high: `(T − 1)·r + 1`, at most `h` (0 when `T = 0`: no row is read).
pub fn ring_rows(k: usize, h: usize, iterations: usize) -> usize {
    if iterations == 0 {
        return 0;
    }
    ((iterations - 1) * (KERNELS[k.min(2)] / 2) + 1).min(h.max(1))
}

/// Bytes of one int8 ring holding [`ring_rows`] rows of any branch's channels, `w` wide (the
/// branches run one after another, so one ring serves all three).
pub fn ring_bytes(h: usize, w: usize, attrs: &RefineAttrs) -> usize {
    (0..3)
        .map(|k| {
            ring_rows(k, h, attrs.iterations)
                .saturating_mul(attrs.neighbours(k))
                .saturating_mul(w)
        })
        .max()
        .unwrap_or(0)
}

/// The per-pixel softmax of a 3-channel mixing map (kmix or tmix). On int8 maps the
/// exponentials come from a table made once per run, `E[d] = exp(−d·scale)` for the code
/// distance `d = max code − code` (0..=255): `e_c = E[max − q_c]`; on f32 maps
/// `e_c = exp(v_c − max v)`. Then `s = (e_0 + e_1) + e_2` and `p_c = e_c / s`.
#[derive(Debug)]
pub struct Mix<'t> {
    table: Option<&'t [f32; 256]>,
}

impl<'t> Mix<'t> {
    /// The mix of maps quantised as `map`; its table, when `map` is int8, made here in `store`.
    pub fn new_in<B: Map>(map: &B, store: &'t mut [f32; 256]) -> Self {
        let table = map.as_i8().map(|m| {
            let scale = m.q().scale;
            for (d, v) in store.iter_mut().enumerate() {
                *v = exp(-(d as f32) * scale);
            }
            &*store
        });
        Mix { table }
    }

    /// Component `c` (`< 3`) of the softmax of `map` at pixel `i`: [`Mix::at`]`(map, i)[c]`,
    /// the same bits, with one division instead of three.
    #[inline(always)]
    pub fn one<B: Map>(&self, map: &B, i: usize, c: usize) -> f32 {
        let e = match (map.as_i8(), self.table) {
            (Some(m), Some(t)) => {
                let (d, p) = (m.data(), m.plane());
                let q0 = i32::from(d[i]);
                let q1 = i32::from(d[p + i]);
                let q2 = i32::from(d[2 * p + i]);
                let mx = q0.max(q1).max(q2);
                let e = |q: i32| t[(mx - q) as usize & 255];
                [e(q0), e(q1), e(q2)]
            }
            _ => {
                let v = [0, 1, 2].map(|c| map.value(c, i));
                let mx = v[0].max(v[1]).max(v[2]);
                v.map(|v| exp(v - mx))
            }
        };
        e[c] / (e[0] + e[1] + e[2])
    }

    /// The softmax of `map` at pixel `i`.
    #[inline]
    pub fn at<B: Map>(&self, map: &B, i: usize) -> [f32; 3] {
        let e = match (map.as_i8(), self.table) {
            (Some(m), Some(t)) => {
                let q = [0, 1, 2].map(|c| i32::from(m.data()[c * m.plane() + i]));
                let mx = q[0].max(q[1]).max(q[2]);
                q.map(|q| t[(mx - q) as usize & 255])
            }
            _ => {
                let v = [0, 1, 2].map(|c| map.value(c, i));
                let mx = v[0].max(v[1]).max(v[2]);
                v.map(|v| exp(v - mx))
            }
        };
        let s = e[0] + e[1] + e[2];
        e.map(|e| e / s)
    }
}

/// One mixing map's view with its [`Mix`].
type MixAt<'a, B> = (&'a B, &'a Mix<'a>);

/// A row of a branch's kmix weights `σ_k` (`Mix::one` of its component `k`) that the NEON
/// [`accumulate`] keeps for the row's later terms: computed and stored (`Fill`), read back
/// (`Use`, the same values), or neither (`Compute`). Only the leading values the vector loop
/// does are stored or read.
pub enum SkRow<'a> {
    /// Compute `σ_k` (nothing cached).
    Compute,
    /// Compute `σ_k` and store it here.
    Fill(&'a mut [f32]),
    /// Read `σ_k` from here (a `Fill` of the same row, branch and maps).
    Use(&'a [f32]),
}

/// Rows of the aarch64 `σ_k` cache of [`refine_with`] (a branch's rows `s − T·r ..= s`).
#[cfg(target_arch = "aarch64")]
const SK_ROWS: usize = 13;
/// Widest row the aarch64 `σ_k` cache holds.
#[cfg(target_arch = "aarch64")]
const SK_W: usize = 256;

/// The int8 map and its table, where the map is int8 and the mix has a table.
fn int8<'a, B: Map>((map, mix): MixAt<'a, B>) -> Option<(&'a I8Map<'a>, &'a [f32; 256])> {
    Some((map.as_i8()?, mix.table?))
}

/// Checks `T` and the σs.
fn check_attrs(attrs: &RefineAttrs) -> Result<(), KernelError> {
    let t = attrs.iterations;
    if t > MAX_ITERATIONS
        || !t.is_multiple_of(2)
        || attrs.sigma.iter().any(|s| s.is_nan() || *s <= 0.0)
    {
        return Err(KernelError::Attr);
    }
    Ok(())
}

/// Runs the propagation (module doc) on three whole maps with the fastest kernel set of this
/// CPU. `d0`, `out`: `h·w` f32; `aff[k]`: `s_k² − 1` channels; `kmix`, `tmix`: 3 channels;
/// `scratch`: ≥ [`scratch_len`] f32.
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
    let maps_ok = [kmix, tmix]
        .iter()
        .all(|m| m.channels() >= 3 && m.plane() >= h.saturating_mul(w));
    if d0.len() < h.saturating_mul(w) || !maps_ok {
        return Err(KernelError::Shape);
    }
    let sources = Sources {
        depth: &mut WholeDepth::new(d0, w),
        aff: &mut WholeMaps::new(aff, w),
        mix: &mut WholeMix::new(kmix, tmix, w),
    };
    refine_with(Isa::best(), sources, h, w, attrs, out, scratch)
}

/// One iteration's window of rows in its scratch slice: image row `base` at slot 0, `len` rows.
#[derive(Clone, Copy, Debug, Default)]
struct Window {
    base: usize,
    len: usize,
}

impl Window {
    /// Makes room for image row `y` (the next one) in `buf` (rows `w` apart), keeping the last
    /// `keep` rows; returns its slot.
    fn push(&mut self, buf: &mut [f32], w: usize, keep: usize, y: usize) -> usize {
        if self.len == WINDOW_ROWS {
            let keep = keep.min(WINDOW_ROWS);
            buf.copy_within((WINDOW_ROWS - keep) * w..WINDOW_ROWS * w, 0);
            self.base += WINDOW_ROWS - keep;
            self.len = keep;
        }
        if self.len == 0 {
            self.base = y;
        }
        self.len += 1;
        y - self.base
    }
}

/// The three row sources of one refinement: `D_0`, the affinities and the mixing maps, whole
/// ([`WholeDepth`], [`WholeMaps`], [`WholeMix`]) or computed row by row.
pub struct Sources<'s, D: DepthRows, R: AffinityRows, M: MixRows> {
    /// `D_0`.
    pub depth: &'s mut D,
    /// The affinities of kernels 3, 5, 7.
    pub aff: &'s mut R,
    /// kmix and tmix.
    pub mix: &'s mut M,
}

/// As [`refine`] with kernel set `isa` and every input from a row source (whole maps or
/// computed row by row): the x86 sets run 8 or 16 pixels per vector, every pixel's own
/// operations in the module doc's order, so the bits do not change. `out`: `h·w` f32.
pub fn refine_with<D: DepthRows, R: AffinityRows, M: MixRows>(
    isa: Isa,
    src: Sources<'_, D, R, M>,
    h: usize,
    w: usize,
    attrs: &RefineAttrs,
    out: &mut [f32],
    scratch: &mut [f32],
) -> Result<(), KernelError> {
    check_attrs(attrs)?;
    let p = h.checked_mul(w).ok_or(KernelError::Shape)?;
    let t_max = attrs.iterations;
    if out.len() < p || scratch.len() < scratch_len(w, t_max) || p == 0 {
        return Err(KernelError::Shape);
    }
    let Sources { depth, aff, mix } = src;
    let times = [0, t_max / 2, t_max];
    let (scratch, tables) = scratch.split_at_mut(windows_len(w, t_max));
    let (t_store, k_store) = tables.split_at_mut(256);
    let (t_store, k_store) = (mix_store(t_store)?, mix_store(k_store)?);
    let mixes = {
        mix.compute(0)?;
        let (km, tm, _) = mix.view(0)?;
        (Mix::new_in(&tm, t_store), Mix::new_in(&km, k_store))
    };
    let out = &mut out[..p];
    out.fill(0.0);
    let win_len = WINDOW_ROWS * w;
    // aarch64: each row's `σ_k` computed at its first term (t = 0) and read back at its later
    // ones, in a ring of the rows a branch still adds to (on the stack).
    #[cfg(target_arch = "aarch64")]
    let mut sk_store = [[0f32; SK_W]; SK_ROWS];
    for (k, &size) in KERNELS.iter().enumerate() {
        let mut br = Branch::new(size, attrs.sigma[k], attrs.neighbourhood, w);
        let r = br.radius();
        #[cfg(target_arch = "aarch64")]
        let cached = matches!(isa, Isa::Neon | Isa::NeonDot)
            && w <= SK_W
            && t_max.saturating_mul(r) < SK_ROWS;
        #[cfg(target_arch = "aarch64")]
        let mut sk_tag = [usize::MAX; SK_ROWS];
        // Window t holds rows of iteration t (t = 0: D_0), for t < T.
        let mut win = [Window::default(); MAX_ITERATIONS];
        for s in 0..h + t_max * r {
            if s < h {
                // Iteration 0 of row s, and its t = 0 terms.
                if k > 0 || s > 0 {
                    mix.compute(s)?;
                }
                let slot = win[0].push(&mut scratch[..win_len], w, 2 * r, s);
                let d = &mut scratch[slot * w..(slot + 1) * w];
                depth.row(s, d)?;
                let (km, tm, at) = mix.view(s)?;
                check_mix(&km, &tm, at, w)?;
                for (ti, _) in times.iter().enumerate().filter(|(_, &t)| t == 0) {
                    let o = &mut out[s * w..(s + 1) * w];
                    #[cfg(target_arch = "aarch64")]
                    let sk = match s % SK_ROWS {
                        q if cached && sk_tag[q] == s => SkRow::Use(&sk_store[q][..]),
                        q if cached => {
                            sk_tag[q] = s;
                            SkRow::Fill(&mut sk_store[q][..])
                        }
                        _ => SkRow::Compute,
                    };
                    #[cfg(not(target_arch = "aarch64"))]
                    let sk = SkRow::Compute;
                    accumulate(isa, o, d, (&tm, &mixes.0), (&km, &mixes.1), ti, k, at, sk);
                }
            }
            for t in 1..=t_max {
                let Some(y) = s.checked_sub(t * r).filter(|&y| y < h) else {
                    continue;
                };
                if t == 1 {
                    aff.compute(k, y)?;
                }
                let (map, a_at) = aff.view(k, y)?;
                if let Some(m) = map.as_i8() {
                    br.set_quant(m.q());
                }
                let (done, rest) = scratch.split_at_mut(t * win_len);
                let prev = win[t - 1];
                let cur = &done[(t - 1) * win_len..];
                let c_at = (y - prev.base) * w;
                let dst = if t < t_max {
                    let slot = win[t].push(&mut rest[..win_len], w, 2 * r, y);
                    &mut rest[slot * w..(slot + 1) * w]
                } else {
                    &mut rest[..w]
                };
                let at = RowAt {
                    aff: a_at,
                    cur: c_at,
                };
                step_row(isa, &map, &br, h, w, y, at, cur, dst)?;
                if times.contains(&t) {
                    let (km, tm, m_at) = mix.view(y)?;
                    check_mix(&km, &tm, m_at, w)?;
                    for (ti, _) in times.iter().enumerate().filter(|(_, &tt)| tt == t) {
                        let o = &mut out[y * w..(y + 1) * w];
                        #[cfg(target_arch = "aarch64")]
                        let sk = match y % SK_ROWS {
                            q if cached && sk_tag[q] == y => SkRow::Use(&sk_store[q][..]),
                            _ => SkRow::Compute,
                        };
                        #[cfg(not(target_arch = "aarch64"))]
                        let sk = SkRow::Compute;
                        let (tmx, kmx) = ((&tm, &mixes.0), (&km, &mixes.1));
                        accumulate(isa, o, dst, tmx, kmx, ti, k, m_at, sk);
                    }
                }
            }
        }
    }
    Ok(())
}

/// `Err(Shape)` unless both mixing maps hold 3 channels of the row at `at`, `w` wide.
fn check_mix<B: Map>(km: &B, tm: &B, at: usize, w: usize) -> Result<(), KernelError> {
    let fits = |m: &B| m.channels() >= 3 && at.checked_add(w).is_some_and(|e| e <= m.plane());
    if fits(km) && fits(tm) {
        Ok(())
    } else {
        Err(KernelError::Shape)
    }
}

/// [`accumulate`] on int8 mixing maps, scalar: the three channel rows sliced once, so the
/// loop has no index arithmetic or bounds test, and the [`Mix::one`] arithmetic inline (the
/// same operations, so the same bits). `false` (nothing done) if a map is short or `ti`, `k` ≥ 3.
fn accumulate_i8(
    out: &mut [f32],
    cur: &[f32],
    (tm, tt): (&I8Map, &[f32; 256]),
    (km, kt): (&I8Map, &[f32; 256]),
    ti: usize,
    k: usize,
    first: usize,
) -> bool {
    let p = out.len().min(cur.len());
    fn rows<'m>(m: &'m I8Map, first: usize, p: usize) -> Option<[&'m [i8]; 3]> {
        let row = |c: usize| m.data().get(c * m.plane() + first..)?.get(..p);
        (m.channels() >= 3 && first + p <= m.plane()).then_some([row(0)?, row(1)?, row(2)?])
    }
    let (Some(t), Some(m)) = (rows(tm, first, p), rows(km, first, p)) else {
        return false;
    };
    if ti >= 3 || k >= 3 {
        return false;
    }
    // The softmax component `c` of codes `q0..q2` through table `e` (Mix::one; scalars, as
    // array adapters stay loops at opt-level "s"): the numerator is one of the three terms of
    // the sum, so it is picked, not looked up again (the same value, so the same bits).
    #[inline(always)]
    fn one<const C: usize>(q0: i8, q1: i8, q2: i8, e: &[f32; 256]) -> f32 {
        let (q0, q1, q2) = (i32::from(q0), i32::from(q1), i32::from(q2));
        let mx = q0.max(q1).max(q2);
        let at = |q: i32| e[(mx - q) as u8 as usize];
        let (a0, a1, a2) = (at(q0), at(q1), at(q2));
        let num = match C {
            0 => a0,
            1 => a1,
            _ => a2,
        };
        num / (a0 + a1 + a2)
    }
    // One loop per pair of components (constants, so each loop picks without a test), in two
    // passes over chunks of `CH` pixels (the first writes `ct`, the second reads it), so each
    // loop's pointers stay in registers; every slice exactly as long as the chunk, so the loops
    // have no bounds test.
    #[inline(always)]
    fn run<const TI: usize, const K: usize>(
        out: &mut [f32],
        cur: &[f32],
        t: [&[i8]; 3],
        m: [&[i8]; 3],
        (tt, kt): (&[f32; 256], &[f32; 256]),
    ) {
        const CH: usize = 32;
        let p = out.len().min(cur.len());
        let mut cts = [0f32; CH];
        let mut x = 0;
        while x < p {
            let n = (p - x).min(CH);
            let r = x..x + n;
            let (t0, t1, t2) = (&t[0][r.clone()], &t[1][r.clone()], &t[2][r.clone()]);
            for (((c, &a), &b), &d) in cts[..n].iter_mut().zip(t0).zip(t1).zip(t2) {
                *c = one::<TI>(a, b, d, tt);
            }
            let (k0, k1, k2) = (&m[0][r.clone()], &m[1][r.clone()], &m[2][r.clone()]);
            let (o, cu) = (&mut out[r.clone()], &cur[r]);
            for i in 0..n {
                let ck = one::<K>(k0[i], k1[i], k2[i], kt);
                o[i] += (cts[i] * ck) * cu[i];
            }
            x += n;
        }
    }
    let (out, cur, e) = (&mut out[..p], &cur[..p], (tt, kt));
    match (ti, k) {
        (0, 0) => run::<0, 0>(out, cur, t, m, e),
        (0, 1) => run::<0, 1>(out, cur, t, m, e),
        (0, _) => run::<0, 2>(out, cur, t, m, e),
        (1, 0) => run::<1, 0>(out, cur, t, m, e),
        (1, 1) => run::<1, 1>(out, cur, t, m, e),
        (1, _) => run::<1, 2>(out, cur, t, m, e),
        (_, 0) => run::<2, 0>(out, cur, t, m, e),
        (_, 1) => run::<2, 1>(out, cur, t, m, e),
        (_, _) => run::<2, 2>(out, cur, t, m, e),
    }
    true
}

/// The vector part of [`accumulate`]: how many leading values it did (0 where the set has no
/// vector path or a map is not int8).
#[allow(clippy::too_many_arguments)]
fn accumulate_vector<B: Map>(
    isa: Isa,
    out: &mut [f32],
    cur: &[f32],
    tmix: MixAt<'_, B>,
    kmix: MixAt<'_, B>,
    ti: usize,
    k: usize,
    first: usize,
    sk: SkRow<'_>,
) -> usize {
    #[cfg(target_arch = "x86_64")]
    if matches!(isa, Isa::Avx2 | Isa::Avx512Vnni) && Isa::Avx2.available() {
        if let (Some(t), Some(m)) = (int8(tmix), int8(kmix)) {
            let p = out.len().min(cur.len());
            let fits = |m: &I8Map| m.channels >= 3 && m.plane >= first + p;
            if fits(t.0) && fits(m.0) {
                // SAFETY: AVX2 is available; both maps hold 3 channels of ≥ first + p pixels.
                return unsafe { super::x86_64::refine::accumulate(out, cur, t, m, ti, k, first) };
            }
        }
    }
    #[cfg(target_arch = "aarch64")]
    if matches!(isa, Isa::Neon | Isa::NeonDot) {
        if let (Some(t), Some(m)) = (int8(tmix), int8(kmix)) {
            let p = out.len().min(cur.len());
            fn rows<'m>(m: &'m I8Map, first: usize, p: usize) -> Option<[&'m [i8]; 3]> {
                let row = |c: usize| m.data.get(c * m.plane + first..)?.get(..p);
                (m.channels >= 3 && first + p <= m.plane).then_some([row(0)?, row(1)?, row(2)?])
            }
            if let (Some(tr), Some(mr)) = (rows(t.0, first, p), rows(m.0, first, p)) {
                let (out, cur) = (&mut out[..p], &cur[..p]);
                return super::aarch64::refine::accumulate(out, cur, tr, mr, t.1, m.1, ti, k, sk);
            }
        }
    }
    let _ = (isa, out, cur, tmix, kmix, ti, k, first, sk);
    0
}

/// `out[i] += (tmix.at(first + i)[ti] · kmix.at(first + i)[k]) · cur[i]` for the values of
/// `out` and `cur` (map pixels `first ..`).
#[allow(clippy::too_many_arguments)]
fn accumulate<B: Map>(
    isa: Isa,
    out: &mut [f32],
    cur: &[f32],
    tmix: MixAt<'_, B>,
    kmix: MixAt<'_, B>,
    ti: usize,
    k: usize,
    first: usize,
    sk: SkRow<'_>,
) {
    let p = out.len().min(cur.len());
    let done = accumulate_vector(isa, out, cur, tmix, kmix, ti, k, first, sk);
    if done == 0 {
        if let (Some(t), Some(m)) = (int8(tmix), int8(kmix)) {
            if accumulate_i8(&mut out[..p], &cur[..p], t, m, ti, k, first) {
                return;
            }
        }
    }
    for i in done..p {
        let coef = tmix.1.one(tmix.0, first + i, ti) * kmix.1.one(kmix.0, first + i, k);
        out[i] += coef * cur[i];
    }
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
            neighbourhood: Neighbourhood::Window,
        };
        let mut out = std::vec![0f32; p];
        let mut scratch = std::vec![0f32; scratch_len(w, t)];
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
    fn dilated_branches_take_the_ring_of_their_window() {
        for (k, size) in KERNELS.into_iter().enumerate() {
            let br = Branch::new(size, 1.5, Neighbourhood::Dilated, 20);
            let r = (size / 2) as isize;
            let want: Vec<(isize, isize)> = [-r, 0, r]
                .into_iter()
                .flat_map(|dy| [-r, 0, r].map(|dx| (dy, dx)))
                .filter(|&o| o != (0, 0))
                .collect();
            assert_eq!(br.neighbours(), 8, "kernel {size}");
            assert_eq!(&br.off[..8], &want[..], "kernel {size}");
            assert_eq!(br.radius(), size / 2);
            for (j, &(dy, dx)) in want.iter().enumerate() {
                assert_eq!(br.delta[j], dy * 20 + dx);
                let g = exp(-((dy * dy + dx * dx) as f32) / (2.0 * 1.5 * 1.5));
                assert_eq!(br.g[j].to_bits(), g.to_bits());
            }
            let attrs = RefineAttrs {
                iterations: 2,
                sigma: [1.0; 3],
                neighbourhood: Neighbourhood::Dilated,
            };
            assert_eq!(attrs.neighbours(k), 8);
            let whole = Branch::new(size, 1.5, Neighbourhood::Window, 20);
            assert_eq!(whole.neighbours(), size * size - 1);
        }
        assert_eq!(
            Neighbourhood::from_code(Neighbourhood::Dilated.code()),
            Some(Neighbourhood::Dilated)
        );
        assert_eq!(Neighbourhood::from_code(0), Some(Neighbourhood::Window));
        assert_eq!(Neighbourhood::from_code(2), None);
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

    /// The whole-map order of the module doc: each iteration over the whole image with every
    /// pixel through [`step_pixel`], the scalar [`Mix::at`], ping-pong maps.
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
        let (mut ts, mut ks) = ([0f32; 256], [0f32; 256]);
        let (tm, km) = (Mix::new_in(tmix, &mut ts), Mix::new_in(kmix, &mut ks));
        for (k, (&a, &s)) in aff.iter().zip(&KERNELS).enumerate() {
            let br = Branch::new(s, attrs.sigma[k], attrs.neighbourhood, w);
            let mut cur = d0.to_vec();
            for t in 0..=t_max {
                if t > 0 {
                    cur = (0..p)
                        .map(|i| {
                            let at = RowAt {
                                aff: i / w * w,
                                cur: i / w * w,
                            };
                            step_pixel(a, &br, h, w, i / w, i % w, at, &cur)
                        })
                        .collect();
                }
                for (ti, &tt) in times.iter().enumerate() {
                    if tt == t {
                        for i in 0..p {
                            out[i] += (tm.one(tmix, i, ti) * km.one(kmix, i, k)) * cur[i];
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
        use Neighbourhood::{Dilated, Window};
        for (h, w, t, nb) in [
            (9usize, 23usize, 4usize, Window),
            (16, 40, 6, Window),
            (3, 5, 2, Window),
            (45, 19, 6, Window),
            (1, 9, 2, Window),
            (20, 8, 0, Window),
            (31, 33, 8, Window),
            (8, 150, 4, Window), // rows wider than two portable chunks
            (17, 29, 6, Dilated),
            (8, 150, 4, Dilated),
            (4, 7, 2, Dilated),
        ] {
            let p = h * w;
            let codes = |n: usize, next: &mut dyn FnMut() -> u32| -> Vec<i8> {
                (0..n).map(|_| next() as i8).collect()
            };
            let n = [3, 5, 7].map(|s| nb.neighbours(s));
            let a3 = codes(n[0] * p, &mut next);
            let a5 = codes(n[1] * p, &mut next);
            let a7 = codes(n[2] * p, &mut next);
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
            let (m3, m5, m7) = (m(&a3, n[0]), m(&a5, n[1]), m(&a7, n[2]));
            let (kmx, tmx) = (m(&km, 3), m(&tm, 3));
            let attrs = RefineAttrs {
                iterations: t,
                sigma: [1.0, 1.5, 2.0],
                neighbourhood: nb,
            };
            let want = refine_per_pixel(&d0, h, w, [&m3, &m5, &m7], &kmx, &tmx, &attrs);
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut out = std::vec![0f32; p];
                let mut scratch = std::vec![0f32; scratch_len(w, attrs.iterations)];
                let sources = Sources {
                    depth: &mut WholeDepth::new(&d0, w),
                    aff: &mut WholeMaps::new([&m3, &m5, &m7], w),
                    mix: &mut WholeMix::new(&kmx, &tmx, w),
                };
                refine_with(isa, sources, h, w, &attrs, &mut out, &mut scratch).unwrap();
                let same = out
                    .iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    same,
                    "{} at {h}x{w} {nb:?}: lanes differ from the per-pixel order",
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
        let n = scratch_len(2, 2);
        let mut s = std::vec![0f32; n];
        let bad_t = RefineAttrs {
            iterations: 3,
            sigma: [1.0; 3],
            neighbourhood: Neighbourhood::Window,
        };
        assert_eq!(
            float::refine(&d0, 2, 2, [&a, &a, &a], &m, &m, &bad_t, &mut o, &mut s),
            Err(KernelError::Attr)
        );
        let ok = RefineAttrs {
            iterations: 2,
            sigma: [1.0; 3],
            neighbourhood: Neighbourhood::Window,
        };
        assert_eq!(
            float::refine(
                &d0,
                2,
                2,
                [&a, &a, &a],
                &m,
                &m,
                &ok,
                &mut o,
                &mut s[..n - 1]
            ),
            Err(KernelError::Shape)
        );
        assert_eq!(
            float::refine(&d0, 2, 2, [&a[..31], &a, &a], &m, &m, &ok, &mut o, &mut s),
            Err(KernelError::Shape)
        );
        assert_eq!(
            float::refine(&d0, 2, 2, [&a, &a, &a], &m[..11], &m, &ok, &mut o, &mut s),
            Err(KernelError::Shape)
        );
        assert_eq!(
            float::refine(&d0, 2, 2, [&a, &a, &a], &m, &m, &ok, &mut o, &mut s),
            Ok(())
        );
    }
}
