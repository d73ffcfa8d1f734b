//! Depthwise convolution (one input and one output channel per group) for [`super::conv`]:
//! per kernel set, the sums of each channel's taps in 32 bits (16-bit products, exact), then the
//! conv's requantisation; every path gives the reference's bits.
//!
//! - [`bands`] (vector cores: x86 AVX2, aarch64 NEON, where int16 codes also take it, and the
//!   portable set): bands of output rows, each tap one vectorised loop over the band;
//! - [`ring3`] (Cortex-M `SMLAD`, 3×3): a strip of interleaved 16-bit rows, six `SMLAD` per pixel;
//! - [`ring_rows`] (Cortex-M `SMLAD`, other kernels up to 7 wide): a ring of 16-bit rows, each
//!   kernel row's taps as pairs of adjacent columns;
//! - [`pixels`] (Cortex-M, the rest): per pixel, the taps summed in a register;
//! - `rows`: per row and tap, the fallback where a scratch holds no band.

use super::conv::{take, Conv2d, OutRows, RowQuant};
use super::isa::Isa;
use super::pack::{self, PB};
use super::Shape;

/// One depthwise call: the operator, its input and the output rows to write (`dst`, as
/// [`super::conv::conv2d_rows_with`] takes them).
#[derive(Clone, Copy)]
pub(super) struct Depthwise<'a, 'w, T = i8> {
    /// Kernel set.
    pub isa: Isa,
    /// The operator.
    pub op: &'a Conv2d<'w>,
    /// Input codes `[C, H, W]` (int8, or int16 for the `SMLAD` paths: [`rings_of`]).
    pub input: &'a [T],
    /// Input shape.
    pub in_shape: Shape,
    /// Output shape.
    pub out: Shape,
    /// Output rows and channel stride.
    pub dst: &'a OutRows,
}

impl<'a, 'w, T> Depthwise<'a, 'w, T> {
    /// The fields, in declaration order (for the paths to name them locally).
    fn parts(&self) -> (Isa, &'a Conv2d<'w>, &'a [T], Shape, Shape, &'a OutRows) {
        (
            self.isa,
            self.op,
            self.input,
            self.in_shape,
            self.out,
            self.dst,
        )
    }
}

/// Input codes [`bands`] reads: int8, or int16 with zero point 0 ([`super::wide`]).
pub(super) trait Code: Copy + Into<i32> {
    /// Whether every tap product `w · (x − zp)` fits in 16 bits (int8: |w·(x − zp)| ≤ 128·255),
    /// so that the portable tap may multiply in 16 bits.
    const NARROW: bool;
    /// The part of `d[k] = src[k·sx] − zp` that the kernel set converts with vectors; returns
    /// how many (0 where it has none).
    fn widen_fast(isa: Isa, src: &[Self], sx: usize, zp: i32, d: &mut [i16]) -> usize;
    /// A band's converted rows in one call where the kernel set has one
    /// ([`super::aarch64::depthwise::widen_band`], its arguments); `false` (nothing written)
    /// elsewhere.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn widen_band_fast(
        _isa: Isa,
        _chan: &[Self],
        _shape: (usize, usize),
        _first_iy: isize,
        _widths: (usize, usize),
        _sx: usize,
        _spans: &[(usize, usize, usize)],
        _zp: i32,
        _x16: &mut [i16],
    ) -> bool {
        false
    }
}

/// [`Code::widen_band_fast`] of both code types: the NEON sets' one-call band conversion.
#[cfg(target_arch = "aarch64")]
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn widen_band_neon<C: super::aarch64::depthwise::BandCode>(
    isa: Isa,
    chan: &[C],
    shape: (usize, usize),
    first_iy: isize,
    widths: (usize, usize),
    sx: usize,
    spans: &[(usize, usize, usize)],
    zp: i32,
    x16: &mut [i16],
) -> bool {
    use super::aarch64::depthwise::widen_band;
    matches!(isa, Isa::Neon | Isa::NeonDot)
        && widen_band(chan, shape, first_iy, widths, sx, spans, zp, x16)
}

impl Code for i8 {
    const NARROW: bool = true;
    #[inline(always)]
    fn widen_fast(isa: Isa, src: &[i8], sx: usize, zp: i32, d: &mut [i16]) -> usize {
        widen_fast(isa, src, sx, zp, d)
    }
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn widen_band_fast(
        isa: Isa,
        chan: &[i8],
        shape: (usize, usize),
        first_iy: isize,
        widths: (usize, usize),
        sx: usize,
        spans: &[(usize, usize, usize)],
        zp: i32,
        x16: &mut [i16],
    ) -> bool {
        widen_band_neon(isa, chan, shape, first_iy, widths, sx, spans, zp, x16)
    }
}

impl Code for i16 {
    const NARROW: bool = false;
    #[inline(always)]
    fn widen_fast(_: Isa, _: &[i16], _: usize, _: i32, _: &mut [i16]) -> usize {
        0
    }
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn widen_band_fast(
        isa: Isa,
        chan: &[i16],
        shape: (usize, usize),
        first_iy: isize,
        widths: (usize, usize),
        sx: usize,
        spans: &[(usize, usize, usize)],
        zp: i32,
        x16: &mut [i16],
    ) -> bool {
        widen_band_neon(isa, chan, shape, first_iy, widths, sx, spans, zp, x16)
    }
}

/// Depthwise convolution of `call` into `output`: the kernel set's path (module doc), or its
/// fallback where the geometry or the scratch does not suit it.
pub(super) fn conv(call: &Depthwise, output: &mut [i8], scratch: &mut [i32]) {
    let isa = call.isa;
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512Vnni if Isa::Avx2.available() => {
            // SAFETY: AVX2 is available (checked).
            unsafe { avx2(call, output, scratch) }
        }
        Isa::ArmDsp => {
            if !ring3(call, output, scratch) && !ring_rows(call, output, scratch) {
                pixels(call, output, scratch)
            }
        }
        _ => {
            if !bands(call, output, scratch) {
                rows(call, output, scratch)
            }
        }
    }
}

/// Requantises output row `oy` of depthwise channel `c` from its sums `acc` (`out.w` of them),
/// the whole row in one [`Conv2d::finish_run`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn finish_row(
    isa: Isa,
    op: &Conv2d,
    rq: &RowQuant,
    c: usize,
    oy: usize,
    acc: &[i32],
    out: Shape,
    dst: &OutRows,
    output: &mut [i8],
) {
    let at = c * dst.stride + (oy - dst.rows.start) * out.w;
    if let Some(row) = output.get_mut(at..at + out.w) {
        op.finish_run(isa, rq, c, &acc[..out.w.min(acc.len())], row);
    }
}

/// [`pixels`]' sums for `KW` adjacent taps per row (dilation 1 across): fixed-size
/// windows, so the taps unroll without bounds checks. `taps` holds `kh` rows of `KW`.
#[inline(always)]
fn pixel_sums<const KW: usize>(
    strip: &[i32],
    width: usize,
    taps: &[i32],
    sx: usize,
    acc: &mut [i32],
) {
    for (ox, a) in acc.iter_mut().enumerate() {
        let mut sum = 0i32;
        for (row, w) in strip.chunks_exact(width).zip(taps.chunks_exact(KW)) {
            let (Some(x), Ok(w)) = (row.get(ox * sx..ox * sx + KW), <&[i32; KW]>::try_from(w))
            else {
                continue;
            };
            for k in 0..KW {
                sum = sum.wrapping_add(w[k].wrapping_mul(x[k]));
            }
        }
        *a = sum;
    }
}

/// Taps a [`pixels`] kernel keeps in registers (7 × 7).
const MAX_DEPTHWISE_TAPS: usize = 49;

/// Depthwise convolution for cores without vector units (Cortex-M): per channel and output row
/// the `kh` input rows are copied once as `x − zp` words into a zero-padded strip, then every
/// output pixel sums its taps in a register (a load and a multiply-accumulate per tap, no
/// per-tap row of sums to load and store as [`rows`] has). Same sums, same bits.
/// Falls back to [`rows`] for kernels over [`MAX_DEPTHWISE_TAPS`] taps or a scratch
/// too small for the strip.
pub(super) fn pixels(call: &Depthwise, output: &mut [i8], scratch: &mut [i32]) {
    let (isa, op, input, in_shape, out, dst) = call.parts();
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (sy, sx) = (g.stride[0], g.stride[1]);
    let (dy, dx) = (g.dilation[0], g.dilation[1]);
    let (ih, iw) = (in_shape.h, in_shape.w);
    if out.w == 0 {
        return;
    }
    let width = (out.w - 1) * sx + (kw - 1) * dx + 1;
    let acc_len = out.w.div_ceil(PB) * PB;
    if kh * kw > MAX_DEPTHWISE_TAPS || scratch.len() < acc_len + kh * width {
        return rows(call, output, scratch);
    }
    let zp = op.quant.input_zero_point;
    let (acc, rest) = scratch.split_at_mut(acc_len);
    let strip = &mut rest[..kh * width];
    let mut taps = [0i32; MAX_DEPTHWISE_TAPS];
    for c in 0..out.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        for (t, &w) in taps
            .iter_mut()
            .zip(&op.weights[c * kh * kw..(c + 1) * kh * kw])
        {
            *t = i32::from(w);
        }
        let rq = op.row_quant(c, op.channels[c].bias);
        for oy in dst.rows.clone() {
            for (ky, row) in strip.chunks_exact_mut(width).enumerate() {
                let iy = (oy * sy + ky * dy) as isize - g.padding[0] as isize;
                row.fill(0);
                if iy < 0 || iy >= ih as isize {
                    continue;
                }
                let src = &chan[iy as usize * iw..(iy as usize + 1) * iw];
                // strip column p holds input column p − padding (zero outside the image)
                let first = g.padding[1].min(width);
                for (d, &x) in row[first..].iter_mut().zip(src) {
                    *d = i32::from(x) - zp;
                }
            }
            let acc = &mut acc[..out.w];
            match (kw, dx) {
                (3, 1) => pixel_sums::<3>(strip, width, &taps[..kh * 3], sx, acc),
                (5, 1) => pixel_sums::<5>(strip, width, &taps[..kh * 5], sx, acc),
                _ => {
                    for (ox, a) in acc.iter_mut().enumerate() {
                        let mut sum = 0i32;
                        for (ky, row) in strip.chunks_exact(width).enumerate() {
                            let at = &row[ox * sx..];
                            let w = &taps[ky * kw..(ky + 1) * kw];
                            for (kx, &wv) in w.iter().enumerate() {
                                sum = sum.wrapping_add(wv.wrapping_mul(at[kx * dx]));
                            }
                        }
                        *a = sum;
                    }
                }
            }
            finish_row(isa, op, &rq, c, oy, acc, out, dst, output);
        }
    }
}

/// Depthwise convolution for cores with vector units, over bands of output rows: per channel
/// and band, the input rows the band reads are converted once to 16-bit `x − zp` (zero
/// outside the image), split by column phase `ix mod sx` so that every tap of an output row is
/// one contiguous run of them; then each tap adds `w · x` (exact in 16 bits) to the band's rows
/// of i32 sums, a loop the compiler vectorises over the whole row. Same sums, same bits. The
/// band is as tall as the scratch allows; `false` (nothing written) if not one row fits.
#[inline(always)]
pub(super) fn bands<T: Code>(call: &Depthwise<T>, output: &mut [i8], scratch: &mut [i32]) -> bool {
    let (isa, op, input, in_shape, out, dst) = call.parts();
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (sy, sx) = (g.stride[0], g.stride[1]);
    let (dy, dx) = (g.dilation[0], g.dilation[1]);
    let (ih, iw) = (in_shape.h, in_shape.w);
    let ow = out.w;
    if ow == 0 || sx == 0 || sy == 0 || op.weights.len() < out.c * kh * kw {
        return false;
    }
    // One phase of a converted row: the output columns plus the widest tap reach.
    let phase_w = ow + (kw - 1) * dx / sx;
    let row_w = sx * phase_w;
    // At stride 1 the sums of a band are kept `row_w` apart, as the converted rows are, so that
    // each tap is one loop over the whole band; they are packed to `ow` apart before the
    // requantisation.
    let merged = sx == 1 && sy == 1;
    let pitch = if merged { row_w } else { ow };
    // Input rows of a band of `r` output rows, and its scratch (i32 units: the sums, then the
    // 16-bit rows).
    let rows_for = |r: usize| (r - 1) * sy + (kh - 1) * dy + 1;
    let need = |r: usize| r * pitch + (rows_for(r) * row_w).div_ceil(2);
    let mut band = dst.rows.len().max(1);
    while band > 1 && need(band) > scratch.len() {
        band = band.div_ceil(2);
    }
    if need(band) > scratch.len() {
        return false;
    }
    let zp = op.quant.input_zero_point;
    let (sums, rest) = scratch.split_at_mut(band * pitch);
    let (x16, _) = take::<i16>(rest, rows_for(band) * row_w);
    let (ph, pw) = (g.padding[0] as isize, g.padding[1] as isize);
    // The columns of a phase outside the image are the same for every row inside it, and
    // nothing writes them: zeroed once here, not per row (rows outside the image are zeroed
    // whole, below).
    x16.fill(0);
    // Each tap's start in the converted rows (row `ky·dy`, phase `kx·dx mod sx`, column
    // `kx·dx / sx`): the same for every channel and band, so computed once.
    let mut tap_offs = [0usize; MAX_DEPTHWISE_TAPS];
    let n_offs = (kh * kw).min(MAX_DEPTHWISE_TAPS);
    for (t, o) in tap_offs[..n_offs].iter_mut().enumerate() {
        let (ky, kx) = (t / kw, t % kw);
        *o = ky * dy * row_w + (kx * dx) % sx * phase_w + kx * dx / sx;
    }
    let tap_offs = &tap_offs[..n_offs];
    // Per phase (the first few; the rest computed per row): its columns `p_lo .. p_hi` inside
    // the image and the input column of `p_lo`, the same for every row and channel.
    const PHASES: usize = 4;
    let span_of = |phase: usize| {
        let off = phase as isize - pw;
        match pack::valid_cols(off, sx, iw, phase_w) {
            Some((lo, hi)) => (lo, hi + 1, (lo as isize * sx as isize + off) as usize),
            None => (0, 0, 0),
        }
    };
    let mut spans = [(0usize, 0usize, 0usize); PHASES];
    for (phase, sp) in spans.iter_mut().enumerate().take(sx) {
        *sp = span_of(phase);
    }
    for c in 0..out.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let w = &op.weights[c * kh * kw..(c + 1) * kh * kw];
        let rq = op.row_quant(c, op.channels[c].bias);
        let mut oy0 = dst.rows.start;
        while oy0 < dst.rows.end {
            let n = band.min(dst.rows.end - oy0);
            let first_iy = (oy0 * sy) as isize - ph;
            // The band's input rows, phase by phase: column p of phase φ is input column
            // p·sx + φ − pw (in one call where the kernel set has one).
            let band_rows = &mut x16[..rows_for(n) * row_w];
            let shape = (ih, iw);
            let spans_all = &spans[..sx.min(PHASES)];
            let widths = (row_w, phase_w);
            let done = sx <= PHASES
                && T::widen_band_fast(
                    isa, chan, shape, first_iy, widths, sx, spans_all, zp, band_rows,
                );
            let rows_left = if done { 0 } else { rows_for(n) };
            for (r, row) in x16.chunks_exact_mut(row_w).take(rows_left).enumerate() {
                let iy = first_iy + r as isize;
                let src = (0..ih as isize)
                    .contains(&iy)
                    .then(|| &chan[iy as usize * iw..][..iw]);
                let Some(src) = src else {
                    row.fill(0);
                    continue;
                };
                for (phase, dst_phase) in row.chunks_exact_mut(phase_w).enumerate() {
                    // Columns p_lo .. p_hi of this phase lie inside the image.
                    let (p_lo, p_hi, first) = match spans.get(phase) {
                        Some(&sp) => sp,
                        None => span_of(phase),
                    };
                    if p_lo < p_hi {
                        let d = &mut dst_phase[p_lo..p_hi];
                        let done = T::widen_fast(isa, &src[first..], sx, zp, d);
                        let (d, first) = (&mut d[done..], first + done * sx);
                        if sx == 1 {
                            for (d, &x) in d.iter_mut().zip(&src[first..]) {
                                *d = (x.into() - zp) as i16;
                            }
                        } else {
                            for (d, &x) in d.iter_mut().zip(src[first..].iter().step_by(sx)) {
                                *d = (x.into() - zp) as i16;
                            }
                        }
                    }
                }
            }
            // Row j's sums at `j·pitch`; `span` covers the last row's `ow`.
            let span = (n - 1) * pitch + ow;
            let sums = &mut sums[..span];
            let vector_done = neon_taps(call, c, x16, (pitch, row_w, tap_offs), sums);
            if !vector_done {
                sums.fill(0);
            }
            // The taps' rows left to the loop below: none where the vector kernel did them.
            let rows_left = if vector_done { 0 } else { kh };
            for ky in 0..rows_left {
                for kx in 0..kw {
                    let wv = i16::from(w[ky * kw + kx]);
                    let col = (kx * dx) % sx * phase_w + kx * dx / sx;
                    // int8: |w| ≤ 128 and |x − zp| ≤ 255, the product fits i16 exactly;
                    // int16 codes multiply in 32 bits (|w·x| ≤ 2²², exact).
                    let tap = |acc: &mut [i32], x: &[i16]| {
                        for (a, &x) in acc.iter_mut().zip(x) {
                            let p = if T::NARROW {
                                i32::from(wv.wrapping_mul(x))
                            } else {
                                i32::from(wv) * i32::from(x)
                            };
                            *a = a.wrapping_add(p);
                        }
                    };
                    if merged {
                        let at = ky * dy * row_w + col;
                        tap(sums, &x16[at..at + span]);
                    } else {
                        for (j, acc) in sums.chunks_mut(pitch).enumerate() {
                            let at = (j * sy + ky * dy) * row_w + col;
                            tap(&mut acc[..ow], &x16[at..at + ow]);
                        }
                    }
                }
            }
            for j in 1..n {
                sums.copy_within(j * pitch..j * pitch + ow, j * ow);
            }
            let sums = &sums[..n * ow];
            // The band's output rows are contiguous in the channel's plane.
            let at = c * dst.stride + (oy0 - dst.rows.start) * ow;
            op.finish_run(isa, &rq, c, sums, &mut output[at..at + n * ow]);
            oy0 += n;
        }
    }
    true
}

/// `d[k] = src[k·sx] − zp` for the leading part that the kernel set converts with vectors
/// (NEON, [`super::aarch64::depthwise::widen`]); returns how many (0 elsewhere).
#[inline(always)]
fn widen_fast(isa: Isa, src: &[i8], sx: usize, zp: i32, d: &mut [i16]) -> usize {
    #[cfg(target_arch = "aarch64")]
    if matches!(isa, Isa::Neon | Isa::NeonDot) {
        return super::aarch64::depthwise::widen(src, sx, zp, d);
    }
    let _ = (isa, src, sx, zp, d);
    0
}

/// [`bands`]' taps with the NEON kernel ([`super::aarch64::depthwise::taps`]) where the set is
/// `neon` or `neon-dot`: each output row of the band (or, at stride 1, the whole band at once)
/// is one call over the tap offsets `offs` (one per tap, [`bands`] computes them) with channel
/// `c`'s weights. `geo` is `(pitch, row_w, offs)`. `false` (nothing written) elsewhere or for
/// kernels over [`MAX_DEPTHWISE_TAPS`] taps.
#[inline(always)]
fn neon_taps<T>(
    call: &Depthwise<T>,
    c: usize,
    x16: &[i16],
    (pitch, row_w, offs): (usize, usize, &[usize]),
    sums: &mut [i32],
) -> bool {
    #[cfg(target_arch = "aarch64")]
    if matches!(call.isa, Isa::Neon | Isa::NeonDot) {
        let g = &call.op.geometry;
        let (kh, kw) = (g.kernel[0], g.kernel[1]);
        let (sx, sy) = (g.stride[1], g.stride[0]);
        let ow = call.out.w;
        let n_taps = kh * kw;
        let Some(wc) = call.op.weights.get(c * n_taps..(c + 1) * n_taps) else {
            return false;
        };
        if n_taps > MAX_DEPTHWISE_TAPS || sx == 0 || offs.len() != n_taps {
            return false;
        }
        let mut ws = [0i16; MAX_DEPTHWISE_TAPS];
        for (wv, &w) in ws.iter_mut().zip(wc) {
            *wv = i16::from(w);
        }
        let ws = &ws[..n_taps];
        if sx == 1 && sy == 1 {
            return super::aarch64::depthwise::taps(x16, offs, ws, sums);
        }
        // Row j of the band starts `j·sy` input rows down: the same offsets from there.
        for (j, acc) in sums.chunks_mut(pitch).enumerate() {
            let (Some(acc), Some(x)) = (acc.get_mut(..ow), x16.get(j * sy * row_w..)) else {
                return false;
            };
            if !super::aarch64::depthwise::taps(x, offs, ws, acc) {
                return false;
            }
        }
        return true;
    }
    let _ = (call, c, x16, pitch, row_w, offs, sums);
    false
}

/// Halfwords per strip column of [`ring3`]: the three held input rows and a zero.
const RING_COLUMN: usize = 4;

/// 3×3 depthwise convolution (dilation 1, column stride 1 or 2) for cores with 16-bit pair
/// multiply-accumulates (Cortex-M `SMLAD`): the three input rows an output row reads are held
/// interleaved in a strip of 16-bit `x − zp`, column by column (`[row a, row b, row c, 0]`),
/// each input row in slot `iy mod 3`, so that the next output row rewrites only the rows it
/// adds (one per row at stride 1). A pixel's nine taps are then 12 consecutive halfwords, read
/// as six words against six weight words ordered to match the slots (six `SMLAD`). Same sums
/// as the reference, same bits. `false` (nothing written) for other geometries or a scratch
/// too small for the strip.
pub(super) fn ring3<T: Copy + Into<i32> + 'static>(
    call: &Depthwise<T>,
    output: &mut [i8],
    scratch: &mut [i32],
) -> bool {
    let (isa, op, input, in_shape, out, dst) = call.parts();
    let g = &op.geometry;
    let sx = g.stride[1];
    if g.kernel != [3, 3] || g.dilation != [1, 1] || !(1..=2).contains(&sx) || out.w == 0 {
        return false;
    }
    let (sy, ph, pw) = (g.stride[0], g.padding[0] as isize, g.padding[1]);
    let (ih, iw) = (in_shape.h, in_shape.w);
    let width = (out.w - 1) * sx + 3;
    let acc_len = out.w.div_ceil(PB) * PB;
    let strip_words = (RING_COLUMN * width).div_ceil(2);
    if scratch.len() < acc_len + strip_words || op.weights.len() < out.c * 9 {
        return false;
    }
    let zp = op.quant.input_zero_point;
    let (acc, rest) = scratch.split_at_mut(acc_len);
    let (strip, _) = take::<i16>(rest, RING_COLUMN * width);
    let acc = &mut acc[..out.w];
    // Strip columns `pw .. pw + iw` hold input columns `0 .. iw`; the rest stay zero.
    let (first, last) = (pw.min(width), (pw + iw).min(width));
    for c in 0..out.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let w = &op.weights[c * 9..(c + 1) * 9];
        let rq = op.row_quant(c, op.channels[c].bias);
        // Input row `iy` lives in slot `iy mod 3`, so kernel row `ky` of output row `oy` is in
        // slot `(r + ky) mod 3`, `r = (oy·sy − ph) mod 3`: the weights in the strip's order
        // (per kx, the slots' rows then a zero) for each of the three `r`.
        let mut taps = [[0i16; 3 * RING_COLUMN]; 3];
        for (r, t) in taps.iter_mut().enumerate() {
            for (kx, col) in t.chunks_exact_mut(RING_COLUMN).enumerate() {
                for ky in 0..3 {
                    col[(r + ky) % 3] = i16::from(w[ky * 3 + kx]);
                }
            }
        }
        strip.fill(0);
        // Input row held in each slot (none yet).
        let mut held = [isize::MIN; 3];
        for oy in dst.rows.clone() {
            let top = (oy * sy) as isize - ph;
            let r = top.rem_euclid(3) as usize;
            for ky in 0..3 {
                let iy = top + ky as isize;
                let slot = (r + ky) % 3;
                if held[slot] == iy {
                    continue;
                }
                held[slot] = iy;
                if (0..ih as isize).contains(&iy) {
                    let src = &chan[iy as usize * iw..][..iw];
                    // int8 rows: the first pixels four at a time on the Cortex-M.
                    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
                    let done = if isa == Isa::ArmDsp
                        && core::any::TypeId::of::<T>() == core::any::TypeId::of::<i8>()
                    {
                        // SAFETY: `T` is `i8` (checked): the same slice, as bytes.
                        let bytes =
                            unsafe { core::slice::from_raw_parts(src.as_ptr().cast(), src.len()) };
                        strip
                            .get_mut(first * RING_COLUMN + slot..last * RING_COLUMN)
                            .map_or(0, |at| super::arm::pack::strip_row(bytes, zp, at))
                    } else {
                        0
                    };
                    #[cfg(not(all(target_arch = "arm", feature = "arm-dsp")))]
                    let done = 0;
                    let cols = strip[(first + done) * RING_COLUMN..last * RING_COLUMN]
                        .chunks_exact_mut(RING_COLUMN);
                    for (col, &x) in cols.zip(&src[done..]) {
                        col[slot] = (x.into() - zp) as i16;
                    }
                } else {
                    let cols = strip[first * RING_COLUMN..last * RING_COLUMN]
                        .chunks_exact_mut(RING_COLUMN);
                    for col in cols {
                        col[slot] = 0;
                    }
                }
            }
            ring3_row(isa, strip, &taps[r], sx, acc);
            finish_row(isa, op, &rq, c, oy, acc, out, dst, output);
        }
    }
    true
}

/// Kernel rows [`ring_rows`] holds (7 × 7 at most).
const MAX_RING_ROWS: usize = 7;

/// The `SMLAD` depthwise paths ([`ring3`], else [`ring_rows`]) on int8 or int16 codes, as
/// [`conv`] tries them for int8 on the arm-dsp set ([`super::wide`] reads int16 through them
/// on every set: the same bits). `false` (nothing written) where neither suits.
pub(super) fn rings_of<T: Copy + Into<i32> + 'static>(
    call: &Depthwise<T>,
    output: &mut [i8],
    scratch: &mut [i32],
) -> bool {
    ring3(call, output, scratch) || ring_rows(call, output, scratch)
}

/// Depthwise convolution on `SMLAD` cores for kernels up to 7 × 7 at horizontal stride 1 or 2
/// (dilation 1): each input row of a channel converted once to 16-bit `x − zp` into a ring of
/// `kh` rows (row `iy` in slot `iy mod kh`, zero columns for the padding, zero rows outside
/// the image), then per output row and kernel row the taps as pairs of adjacent columns
/// against weight words `[w_2j | w_2j+1]` (the last one `[w_kw−1 | 0]` for odd widths):
/// ⌈kw/2⌉ `SMLAD` per pixel and kernel row. Exact sums, the reference's bits. `false`
/// (nothing written) for other geometries or a short scratch. On int8 or int16 codes alike: a
/// row is `x − zp` in 16 bits either way (an int16 input has zero point 0).
pub(super) fn ring_rows<T: Copy + Into<i32>>(
    call: &Depthwise<T>,
    output: &mut [i8],
    scratch: &mut [i32],
) -> bool {
    let (isa, op, input, in_shape, out, dst) = call.parts();
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (sy, sx) = (g.stride[0], g.stride[1]);
    let pairs = kw.div_ceil(2);
    if g.dilation != [1, 1]
        || !(1..=MAX_RING_ROWS).contains(&kh)
        || !(1..=MAX_RING_ROWS).contains(&kw)
        || !(1..=2).contains(&sx)
        || sy == 0
        || out.w == 0
        || op.weights.len() < out.c * kh * kw
    {
        return false;
    }
    let (ph, pw) = (g.padding[0] as isize, g.padding[1]);
    let (ih, iw) = (in_shape.h, in_shape.w);
    // A row: the output columns' windows, the odd width's zero pair half, even length.
    let row_w = ((out.w - 1) * sx + 2 * pairs).next_multiple_of(2);
    let acc_len = out.w.div_ceil(PB) * PB;
    if scratch.len() < acc_len + (kh * row_w).div_ceil(2) {
        return false;
    }
    let zp = op.quant.input_zero_point;
    let (acc, rest) = scratch.split_at_mut(acc_len);
    let (ring, _) = take::<i16>(rest, kh * row_w);
    let acc = &mut acc[..out.w];
    // Ring columns `pw .. pw + iw` hold input columns `0 .. iw`; the rest stay zero.
    let (first, last) = (pw.min(row_w), (pw + iw).min(row_w));
    for c in 0..out.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let w = &op.weights[c * kh * kw..(c + 1) * kh * kw];
        let rq = op.row_quant(c, op.channels[c].bias);
        // Weight words per kernel row: `[w_2j | w_2j+1]`, zero past the width.
        let mut words = [[0u32; MAX_RING_ROWS.div_ceil(2)]; MAX_RING_ROWS];
        for (ky, row) in words.iter_mut().enumerate().take(kh) {
            for (j, word) in row.iter_mut().enumerate().take(pairs) {
                let tap = |kx: usize| {
                    let v = if kx < kw { w[ky * kw + kx] } else { 0 };
                    u32::from(i16::from(v) as u16)
                };
                *word = tap(2 * j) | (tap(2 * j + 1) << 16);
            }
        }
        ring.fill(0);
        let mut held = [isize::MIN; MAX_RING_ROWS];
        for oy in dst.rows.clone() {
            for (ky, word) in words.iter().enumerate().take(kh) {
                let iy = (oy * sy + ky) as isize - ph;
                let slot = iy.rem_euclid(kh as isize) as usize;
                let row = &mut ring[slot * row_w..(slot + 1) * row_w];
                if held[slot] != iy {
                    held[slot] = iy;
                    if (0..ih as isize).contains(&iy) {
                        let src = &chan[iy as usize * iw..][..iw];
                        for (d, &x) in row[first..last].iter_mut().zip(src) {
                            *d = (x.into() - zp) as i16;
                        }
                    } else {
                        row[first..last].fill(0);
                    }
                }
                pair_row_sums(isa, row, &word[..pairs], sx, ky == 0, acc);
            }
            finish_row(isa, op, &rq, c, oy, acc, out, dst, output);
        }
    }
    true
}

/// Adds to `acc[ox]` (or sets it, where `first`) the sums over `j` of the column pair
/// `row[ox·sx + 2j ..][..2]` against weight word `words[j]` (`[w_2j | w_2j+1]`): one kernel
/// row of [`ring_rows`]. The arm-dsp set uses `SMLAD`; same sums.
fn pair_row_sums(isa: Isa, row: &[i16], words: &[u32], sx: usize, first: bool, acc: &mut [i32]) {
    let need = acc.len().saturating_sub(1) * sx + 2 * words.len();
    if acc.is_empty() || row.len() < need || words.is_empty() {
        return;
    }
    // At stride 2 every pair a pixel reads starts at an even column: aligned words.
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    if isa == Isa::ArmDsp && sx == 2 && (row.as_ptr() as usize).is_multiple_of(4) {
        // SAFETY: `row` is 4-aligned and holds the `need` halfwords every pixel reads
        // (checked); at stride 2 each read is an aligned word.
        if unsafe { super::arm::dsp::pair_row_s2(row.as_ptr(), words, first, acc) } {
            return;
        }
    }
    let _ = isa;
    for (ox, a) in acc.iter_mut().enumerate() {
        let mut sum = if first { 0 } else { *a };
        for (j, &wd) in words.iter().enumerate() {
            let at = ox * sx + 2 * j;
            let (w0, w1) = (
                i32::from(wd as u16 as i16),
                i32::from((wd >> 16) as u16 as i16),
            );
            sum = sum
                .wrapping_add(i32::from(row[at]) * w0)
                .wrapping_add(i32::from(row[at + 1]) * w1);
        }
        *a = sum;
    }
}

/// The sums of one output row of [`ring3`]: `acc[ox]` = the 12 halfwords of the strip
/// from column `ox·sx` against `taps`. The arm-dsp set uses `SMLAD`; same sums.
fn ring3_row(isa: Isa, strip: &[i16], taps: &[i16; 3 * RING_COLUMN], sx: usize, acc: &mut [i32]) {
    let span = (acc.len().saturating_sub(1) * sx + 3) * RING_COLUMN;
    if acc.is_empty() || strip.len() < span {
        return;
    }
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    if isa == Isa::ArmDsp && (strip.as_ptr() as usize).is_multiple_of(4) {
        // SAFETY: the strip holds the `span` halfwords every pixel reads (checked), 4-aligned.
        unsafe { super::arm::dsp::ring3_row(strip.as_ptr(), taps, sx, acc) };
        return;
    }
    let _ = isa;
    for (ox, a) in acc.iter_mut().enumerate() {
        let window = &strip[ox * sx * RING_COLUMN..][..3 * RING_COLUMN];
        let mut sum = 0i32;
        for (&x, &t) in window.iter().zip(taps) {
            sum = sum.wrapping_add(i32::from(x) * i32::from(t));
        }
        *a = sum;
    }
}

/// [`bands`] (or `rows`) compiled for AVX2, so that the loops vectorise with 256-bit vectors.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn avx2(call: &Depthwise, output: &mut [i8], scratch: &mut [i32]) {
    if !bands(call, output, scratch) {
        rows(call, output, scratch)
    }
}

/// Per channel and output row, every tap adds `w · (x − zp)` to a row of i32 sums (16-bit
/// products, exact), which the compiler vectorises across the row; then the row is
/// requantised like a conv block. Needs only a row of sums and one input row of scratch.
#[inline(always)]
fn rows(call: &Depthwise, output: &mut [i8], scratch: &mut [i32]) {
    let (isa, op, input, in_shape, out, dst) = call.parts();
    let g = &op.geometry;
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let (ih, iw) = (in_shape.h, in_shape.w);
    let zp = op.quant.input_zero_point;
    let (acc, rest) = scratch.split_at_mut(out.w.div_ceil(PB) * PB);
    let xrow = &mut rest[..iw];
    for c in 0..out.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let w = &op.weights[c * kh * kw..(c + 1) * kh * kw];
        let rq = op.row_quant(c, op.channels[c].bias);
        for oy in dst.rows.clone() {
            acc.fill(0);
            for ky in 0..kh {
                let iy = (oy * g.stride[0] + ky * g.dilation[0]) as isize - g.padding[0] as isize;
                if iy < 0 || iy >= ih as isize {
                    continue;
                }
                let row = &chan[iy as usize * iw..(iy as usize + 1) * iw];
                for (d, &x) in xrow.iter_mut().zip(row) {
                    *d = x as i32 - zp;
                }
                for kx in 0..kw {
                    let off = (kx * g.dilation[1]) as isize - g.padding[1] as isize;
                    let Some((lo, hi)) = pack::valid_cols(off, g.stride[1], iw, out.w) else {
                        continue;
                    };
                    let first = (lo as isize * g.stride[1] as isize + off) as usize;
                    let wv = w[ky * kw + kx] as i16;
                    let dst = &mut acc[lo..=hi];
                    if g.stride[1] == 1 {
                        // |w| ≤ 128 and |x − zp| ≤ 255: the product fits i16 exactly.
                        for (a, &x) in dst.iter_mut().zip(&xrow[first..]) {
                            *a = a.wrapping_add(i32::from(wv.wrapping_mul(x as i16)));
                        }
                    } else {
                        let xs = xrow[first..].iter().step_by(g.stride[1]);
                        for (a, &x) in dst.iter_mut().zip(xs) {
                            *a = a.wrapping_add(i32::from(wv.wrapping_mul(x as i16)));
                        }
                    }
                }
            }
            finish_row(isa, op, &rq, c, oy, acc, out, dst, output);
        }
    }
}
