//! Packed operands of the convolution: the reduction laid out innermost for dot instructions.
//!
//! **Rows.** For one output row `oy`, the `kh` input rows it reads (`iy = oy·sh + ky·dh − ph`)
//! are packed per group of `L` input channels ("channel group" `cg`) as
//! `rows[cg][slot][phase][xq][l]`: input channel `cg·L + l` at padded column
//! `xq·sw + phase` (column `ix = xq·sw + phase − pw`), input row `iy` in slot
//! [`row_slot`]` = iy mod kh` (or `ky` where that would collide), so a row stays packed while
//! the next output rows read it. Tap `(ky, kx)` of output pixel `ox` is then at
//! `[cg][slot][(kx·dw) mod sw][ox + ⌊kx·dw / sw⌋]`: consecutive pixels are consecutive
//! `L`-element words for every stride and dilation. Padding (rows, columns, channels past the
//! group's last) holds the padding element. Each row is [`row_width`] words wide so that a
//! pixel block of [`PB`] may run past the last output column.
//!
//! **Weights.** Channel block `b` (output channels `b·NB ..`, zero past the last) as
//! `w[b][ky][kx][cg][j][l]` = weight of output `b·NB + j`, input channel `cg·L + l`, tap
//! `(ky, kx)` (zero past the last input channel): tap-major, so a micro-kernel's inner loop over
//! the channel groups of one tap walks the weights contiguously.
//!
//! **Layouts.** [`Pairs`]: `L = 2`, 16-bit `x − zp` (pad 0) for `vpmaddwd` / `SMLAD`.
//! [`Quads`]: `L = 4`, bytes `x + 128` (pad `zp + 128`) for `vpdpbusd`; the sums then carry
//! `(zp + 128)·Σw` per channel, which the caller subtracts. [`SignedQuads`]: `L = 4`, the codes
//! `x` as they are (pad `zp`) for the signed×signed `SDOT` of aarch64; the sums carry `zp·Σw`.

use super::conv::ConvGeometry;
use super::Shape;

/// Output pixels per micro-kernel call.
pub const PB: usize = 32;
/// Output channels per weight block.
pub const NB: usize = 4;

/// How input channels are grouped per word.
pub trait Layout {
    /// Element type of the packed rows.
    type Elem: Copy + Default;
    /// Weight element type.
    type W: Copy + Default;
    /// Channels per word.
    const L: usize;
    /// The packed element of input code `x` with input zero point `zp`.
    fn elem(x: i8, zp: i32) -> Self::Elem;
    /// The packed element of padding.
    fn pad(zp: i32) -> Self::Elem;
    /// The packed weight.
    fn weight(w: i8) -> Self::W;
    /// What the packing adds to channel `o`'s sum, given `zp` and `Σw` of that channel.
    fn bias_term(zp: i32, sum_w: i32) -> i32;
    /// Packs the first pixels of two untabled channel rows into `out` as [`Layout::elem`]
    /// would, where the target has a faster way; returns how many pixels it packed (0: none).
    #[inline(always)]
    fn interleave2_fast(_a: &[i8], _b: &[i8], _zp: i32, _out: &mut [Self::Elem]) -> usize {
        0
    }
    /// As [`Layout::interleave2_fast`] for four channel rows.
    #[inline(always)]
    fn interleave4_fast(_src: [&[i8]; 4], _zp: i32, _out: &mut [Self::Elem]) -> usize {
        0
    }
    /// Whether [`Layout::interleave4_stride2_fast`] has a vector path (else its caller's
    /// branch compiles away).
    const STRIDE2_FAST: bool = false;
    /// `out[x·L + l] = elem(t_l[src[l][sw·x]])` (`t_l` row `l`'s table, the codes as they are
    /// where it has none) for the first `rows` rows (`≤ L`; the rows past `L` unused), padding
    /// in the other lanes, `sw` 1 or 2, over a leading part, vectorised where the layout and
    /// target have it; returns how many pixels (0: none).
    #[inline(always)]
    fn interleave4_tables_fast(
        _src: [&[i8]; 4],
        _tables: [Option<&[i8; 256]>; 4],
        _rows: usize,
        _sw: usize,
        _zp: i32,
        _out: &mut [Self::Elem],
    ) -> usize {
        0
    }
    /// `out[x·4 + l] = elem(src[l][2x])` for the first `rows` rows, padding in the other
    /// lanes, over a leading part, vectorised where the layout and target have it; returns how
    /// many pixels (0: none).
    #[inline(always)]
    fn interleave4_stride2_fast(
        _src: [&[i8]; 4],
        _rows: usize,
        _zp: i32,
        _out: &mut [Self::Elem],
    ) -> usize {
        0
    }
}

/// 16-bit `x − zp`, two channels per word.
pub struct Pairs;
impl Layout for Pairs {
    type Elem = i16;
    type W = i16;
    const L: usize = 2;
    #[inline(always)]
    fn elem(x: i8, zp: i32) -> i16 {
        (x as i32 - zp) as i16
    }
    #[inline(always)]
    fn pad(_zp: i32) -> i16 {
        0
    }
    #[inline(always)]
    fn weight(w: i8) -> i16 {
        w as i16
    }
    #[inline(always)]
    fn bias_term(_zp: i32, _sum_w: i32) -> i32 {
        0
    }
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    #[inline(always)]
    fn interleave2_fast(a: &[i8], b: &[i8], zp: i32, out: &mut [i16]) -> usize {
        super::arm::pack::interleave_pairs(a, b, zp, out)
    }
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn interleave2_fast(a: &[i8], b: &[i8], zp: i32, out: &mut [i16]) -> usize {
        super::aarch64::pack::pairs([a, b], [None; 2], 2, 1, zp, out)
    }
    #[cfg(target_arch = "aarch64")]
    const STRIDE2_FAST: bool = true;
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn interleave4_tables_fast(
        src: [&[i8]; 4],
        tables: [Option<&[i8; 256]>; 4],
        rows: usize,
        sw: usize,
        zp: i32,
        out: &mut [i16],
    ) -> usize {
        let (src, tables) = ([src[0], src[1]], [tables[0], tables[1]]);
        super::aarch64::pack::pairs(src, tables, rows.min(2), sw, zp, out)
    }
}

/// Bytes `x + 128`, four channels per word (padding `zp + 128`).
pub struct Quads;
impl Layout for Quads {
    type Elem = u8;
    type W = i8;
    const L: usize = 4;
    #[inline(always)]
    fn elem(x: i8, _zp: i32) -> u8 {
        (x as u8) ^ 0x80
    }
    #[inline(always)]
    fn pad(zp: i32) -> u8 {
        (zp + 128) as u8
    }
    #[inline(always)]
    fn weight(w: i8) -> i8 {
        w
    }
    #[inline(always)]
    fn bias_term(zp: i32, sum_w: i32) -> i32 {
        (zp + 128).wrapping_mul(sum_w)
    }
}

/// Signed bytes `x`, four channels per word (padding `zp`).
pub struct SignedQuads;
impl Layout for SignedQuads {
    type Elem = i8;
    type W = i8;
    const L: usize = 4;
    #[inline(always)]
    fn elem(x: i8, _zp: i32) -> i8 {
        x
    }
    #[inline(always)]
    fn pad(zp: i32) -> i8 {
        zp as i8
    }
    #[inline(always)]
    fn weight(w: i8) -> i8 {
        w
    }
    #[inline(always)]
    fn bias_term(zp: i32, sum_w: i32) -> i32 {
        zp.wrapping_mul(sum_w)
    }
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn interleave4_fast(src: [&[i8]; 4], _zp: i32, out: &mut [i8]) -> usize {
        super::aarch64::pack::interleave4(src, out)
    }
    #[cfg(target_arch = "aarch64")]
    const STRIDE2_FAST: bool = true;
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn interleave4_stride2_fast(src: [&[i8]; 4], rows: usize, zp: i32, out: &mut [i8]) -> usize {
        super::aarch64::pack::interleave4_stride2(src, rows, Self::pad(zp), out)
    }
    #[cfg(target_arch = "aarch64")]
    #[inline(always)]
    fn interleave4_tables_fast(
        src: [&[i8]; 4],
        tables: [Option<&[i8; 256]>; 4],
        rows: usize,
        sw: usize,
        zp: i32,
        out: &mut [i8],
    ) -> usize {
        super::aarch64::pack::interleave4_tables(src, tables, rows, sw, Self::pad(zp), out)
    }
}

/// Range of output columns `ox` whose input column `ox·s + off` lies in `0..n` (inclusive
/// bounds), `None` if empty.
#[inline]
pub fn valid_cols(off: isize, s: usize, n: usize, out_w: usize) -> Option<(usize, usize)> {
    let s = s as isize;
    let lo = if off < 0 { (-off + s - 1) / s } else { 0 };
    let last_in = n as isize - 1 - off;
    if last_in < 0 {
        return None;
    }
    let hi = (last_in / s).min(out_w as isize - 1);
    if lo > hi {
        return None;
    }
    Some((lo as usize, hi as usize))
}

/// Words per packed row and phase: the output columns rounded up to [`PB`] plus the widest
/// tap reach `⌊(kw − 1)·dw / sw⌋`.
pub fn row_width(g: &ConvGeometry, out_w: usize) -> usize {
    out_w.div_ceil(PB) * PB + (g.kernel[1] - 1) * g.dilation[1] / g.stride[1] + 1
}

/// Sizes of the packed operands of one conv (in elements).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dims {
    /// Channel groups per conv group (`⌈icg / L⌉`).
    pub n_cg: usize,
    /// Elements of one channel group's `kh` rows (`kh · sw · row_width · L`).
    pub cg_stride: usize,
    /// Elements of one output channel block's weights (`n_cg · kh · kw · NB · L`).
    pub block_len: usize,
    /// Weight blocks per conv group (`⌈ocg / NB⌉`).
    pub n_blocks: usize,
}

impl Dims {
    /// Sizes for input channels per group `icg`, outputs per group `ocg`, layout `l`.
    pub fn new(g: &ConvGeometry, icg: usize, ocg: usize, out_w: usize, l: usize) -> Dims {
        let n_cg = icg.div_ceil(l);
        let cg_stride = g.kernel[0] * g.stride[1] * row_width(g, out_w) * l;
        Dims {
            n_cg,
            cg_stride,
            block_len: n_cg * g.kernel[0] * g.kernel[1] * NB * l,
            n_blocks: ocg.div_ceil(NB),
        }
    }
    /// Elements of all packed rows.
    pub fn rows_len(&self) -> usize {
        self.n_cg * self.cg_stride
    }
}

/// Most packed weight elements a conv holds at once: where a group's weights are more, they are
/// packed and used [`blocks_per_pack`] output blocks at a time (the input rows are then packed
/// once per such pack), so that a conv with large weights on a small image needs little
/// scratch.
pub const MAX_PACKED_WEIGHTS: usize = 16 * 1024;

/// Output blocks of `NB` channels whose weights are packed together, of `n_blocks` per group
/// with `icg` input channels per group.
pub fn blocks_per_pack(g: &ConvGeometry, icg: usize, n_blocks: usize) -> usize {
    let per_block = NB
        .saturating_mul(icg.div_ceil(4).saturating_mul(4))
        .saturating_mul(g.kernel[0].saturating_mul(g.kernel[1]))
        .max(1);
    (MAX_PACKED_WEIGHTS / per_block).clamp(1, n_blocks.max(1))
}

/// Element offset of tap `(ky, kx)` inside one channel group's packed rows, plus the offset of
/// pixel `ox` (`ox · L`).
pub fn tap_offset(g: &ConvGeometry, out_w: usize, l: usize, ky: usize, kx: usize) -> usize {
    let rw = row_width(g, out_w);
    let reach = kx * g.dilation[1];
    ((ky * g.stride[1] + reach % g.stride[1]) * rw + reach / g.stride[1]) * l
}

/// The int8 CHW input of a convolution: one tensor ([`Dense`]), or the parts of a concat read
/// in place, each with the table that requantises its codes to the concat's ([`Parts`]).
pub trait Source {
    /// Codes `start .. start + len` of channel `c`'s plane and the table mapping them to the
    /// conv's input codes (`None`: as they are); `None` past the end.
    fn run(&self, c: usize, start: usize, len: usize) -> Option<(&[i8], Option<&[i8; 256]>)>;
    /// [`Source::run`] of channels `c .. c + 4`, all or `None`.
    #[inline(always)]
    fn run4(&self, c: usize, start: usize, len: usize) -> Option<[Run<'_>; 4]> {
        Some([
            self.run(c, start, len)?,
            self.run(c + 1, start, len)?,
            self.run(c + 2, start, len)?,
            self.run(c + 3, start, len)?,
        ])
    }
}

/// One CHW tensor of `plane` pixels per channel.
#[derive(Clone, Copy, Debug)]
pub struct Dense<'a> {
    /// The codes.
    pub data: &'a [i8],
    /// Pixels per channel.
    pub plane: usize,
}

impl Source for Dense<'_> {
    #[inline(always)]
    fn run(&self, c: usize, start: usize, len: usize) -> Option<(&[i8], Option<&[i8; 256]>)> {
        let at = c.checked_mul(self.plane)?.checked_add(start)?;
        Some((self.data.get(at..at.checked_add(len)?)?, None))
    }
    #[inline(always)]
    fn run4(&self, c: usize, start: usize, len: usize) -> Option<[Run<'_>; 4]> {
        dense_run4(self.data, self.plane, c, start, len)
    }
}

/// [`Source::run4`] of a CHW tensor `data` of `p` pixels per channel (no tables).
#[inline(always)]
fn dense_run4(data: &[i8], p: usize, c: usize, start: usize, len: usize) -> Option<[Run<'_>; 4]> {
    // One check, on the farthest end: channel `c + 3`'s run.
    let end = c.checked_add(3)?.checked_mul(p)?.checked_add(start)?;
    let data = data.get(..end.checked_add(len)?)?;
    let at = c * p + start;
    Some([0, 1, 2, 3].map(|k| {
        let a = at + k * p;
        // SAFETY: `a + len ≤ at + 3p + len = end + len ≤ data.len()` (checked above, and
        // without overflow since the largest sum did not overflow).
        (unsafe { data.get_unchecked(a..a + len) }, None)
    }))
}

/// Most parts of a [`Parts`] input.
pub const MAX_PARTS: usize = 8;

/// One part of a [`Parts`] input: codes, channels, rescale table.
type Part<'a> = (&'a [i8], usize, Option<&'a [i8; 256]>);

/// Several CHW tensors of one plane size, read as their concatenation along channels.
#[derive(Clone, Copy, Debug)]
pub struct Parts<'a> {
    parts: [Part<'a>; MAX_PARTS],
    n: usize,
    plane: usize,
}

impl<'a> Parts<'a> {
    /// No parts yet, `plane` pixels per channel.
    pub fn new(plane: usize) -> Self {
        Parts {
            parts: [(&[], 0, None); MAX_PARTS],
            n: 0,
            plane,
        }
    }
    /// Appends `channels` channels of `data`, their codes mapped through `table` if given.
    /// `false` when full or `data` is short.
    pub fn push(&mut self, data: &'a [i8], channels: usize, table: Option<&'a [i8; 256]>) -> bool {
        let fits = channels
            .checked_mul(self.plane)
            .is_some_and(|n| n <= data.len());
        if self.n == MAX_PARTS || !fits {
            return false;
        }
        self.parts[self.n] = (data, channels, table);
        self.n += 1;
        true
    }
    /// Channels of all parts.
    pub fn channels(&self) -> usize {
        self.parts[..self.n].iter().map(|p| p.1).sum()
    }
}

impl Source for Parts<'_> {
    #[inline]
    fn run(&self, c: usize, start: usize, len: usize) -> Option<(&[i8], Option<&[i8; 256]>)> {
        let mut c = c;
        for &(data, channels, table) in &self.parts[..self.n] {
            if c < channels {
                let at = c * self.plane + start;
                return Some((data.get(at..at.checked_add(len)?)?, table));
            }
            c -= channels;
        }
        None
    }
    #[inline]
    fn run4(&self, c: usize, start: usize, len: usize) -> Option<[Run<'_>; 4]> {
        let mut k = c;
        for &(data, channels, table) in &self.parts[..self.n] {
            if k < channels {
                if k.checked_add(4)? > channels {
                    break;
                }
                let runs = dense_run4(data, self.plane, k, start, len)?;
                return Some(runs.map(|(r, _)| (r, table)));
            }
            k -= channels;
        }
        Some([
            self.run(c, start, len)?,
            self.run(c + 1, start, len)?,
            self.run(c + 2, start, len)?,
            self.run(c + 3, start, len)?,
        ])
    }
}

/// Slot of the packed rows that holds input row `iy` of a conv with kernel height `kh` and
/// row dilation `dh`: `iy mod kh` where the `kh` rows one output row reads then take distinct
/// slots (`gcd(dh, kh) = 1`, e.g. every undilated kernel), so that a row packed for one output
/// row serves the next ones that read it; `None` otherwise (the slot is then the tap row).
pub fn row_slot(kh: usize, dh: usize, iy: isize) -> Option<usize> {
    let (mut a, mut b) = (kh, dh);
    while b != 0 {
        (a, b) = (b, a % b);
    }
    (a == 1).then(|| iy.rem_euclid(kh as isize) as usize)
}

/// Packs input row `iy` (padding where it lies outside the image) of channels
/// `c0 .. c0 + in_shape.c` of `input` (the group's channels) into row slot `slot` of every
/// channel group of `rows`.
#[allow(clippy::too_many_arguments)]
pub fn pack_row<F: Layout, S: Source>(
    g: &ConvGeometry,
    input: &S,
    c0: usize,
    in_shape: Shape,
    out_w: usize,
    iy: isize,
    slot: usize,
    zp: i32,
    dims: &Dims,
    rows: &mut [F::Elem],
) {
    let (ih, iw) = (in_shape.h, in_shape.w);
    let sw = g.stride[1];
    let rw = row_width(g, out_w);
    let pad = F::pad(zp);
    let (pw, l) = (g.padding[1], F::L);
    // Padded columns xq·sw + phase that hold input column ix = · − pw (per phase: [lo, hi)).
    let span = |phase: usize| -> (usize, usize) {
        let lo = pw.saturating_sub(phase).div_ceil(sw);
        let hi = (iw + pw).saturating_sub(phase).div_ceil(sw).min(rw);
        (lo.min(hi), hi)
    };
    let row_ok = iy >= 0 && (iy as usize) < ih;
    // Per phase (outside the channel-group loop): the in-image column span, where its codes
    // start and how many (an out-of-image row: all padding).
    for phase in 0..sw {
        let (lo, hi, at, len) = if row_ok {
            let (lo, hi) = span(phase);
            let at = iy as usize * iw + (lo * sw + phase).saturating_sub(pw);
            (lo, hi, at, hi.saturating_sub(lo))
        } else {
            (rw, rw, 0, 0)
        };
        for cg in 0..dims.n_cg {
            let base = cg * dims.cg_stride + (slot * sw + phase) * rw * l;
            let dst = &mut rows[base..base + rw * l];
            dst[..lo * l].fill(pad);
            dst[hi.max(lo) * l..].fill(pad);
            if !row_ok {
                continue;
            }
            if sw == 1 && (cg + 1) * l <= in_shape.c {
                let src = |li: usize| input.run(c0 + cg * l + li, at, len);
                let out = &mut dst[lo * l..hi * l];
                match l {
                    4 => {
                        if let Some(runs) = input.run4(c0 + cg * l, at, len) {
                            interleave4::<F>(runs, zp, out);
                            continue;
                        }
                    }
                    _ => {
                        if let (Some(a), Some(b)) = (src(0), src(1)) {
                            interleave2::<F>([a, b], zp, out);
                            continue;
                        }
                    }
                }
            }
            if F::STRIDE2_FAST && sw == 2 && l <= 4 && len > 0 && cg * l < in_shape.c {
                let rows = (in_shape.c - cg * l).min(l);
                // Every other code of the group's channel rows (padding in the lanes past the
                // last channel), through their tables where they have one: the layout's vector
                // path where it has one, then the rest word by word.
                let mut src: [&[i8]; 4] = [&[]; 4];
                let mut tables: [Option<&[i8; 256]>; 4] = [None; 4];
                let mut found = true;
                for (li, (s, t)) in src.iter_mut().zip(&mut tables).enumerate().take(rows) {
                    match input.run(c0 + cg * l + li, at, 2 * len - 1) {
                        Some((r, table)) => (*s, *t) = (r, table),
                        None => found = false,
                    }
                }
                let out = &mut dst[lo * l..hi * l];
                let done = if !found {
                    0
                } else if l == 4 && tables.iter().all(Option::is_none) {
                    F::interleave4_stride2_fast(src, rows, zp, out)
                } else {
                    F::interleave4_tables_fast(src, tables, rows, 2, zp, out)
                };
                if done > 0 {
                    for (k, w) in out.chunks_exact_mut(l).enumerate().skip(done) {
                        for (li, e) in w.iter_mut().enumerate() {
                            *e = match src.get(li).filter(|_| li < rows) {
                                Some(r) => {
                                    let t = tables[li].unwrap_or(&IDENTITY);
                                    F::elem(t[r[2 * k] as u8 as usize], zp)
                                }
                                None => pad,
                            };
                        }
                    }
                    continue;
                }
            }
            for li in 0..l {
                let c = cg * l + li;
                let words = &mut dst[lo * l..hi.max(lo) * l];
                let src = if c < in_shape.c {
                    input.run(c0 + c, iy as usize * iw, iw)
                } else {
                    None
                };
                let ix0 = (lo * sw + phase - pw).min(iw);
                let run = src.map(|(src, table)| (&src[ix0..], table));
                fill_lane::<F>(words, l, li, run, sw, zp);
            }
        }
    }
}

/// Lane `li` of every `l`-element word of `out`: from every `sw`-th code of the run (as many as
/// both hold), or padding where there is no run.
#[inline(always)]
fn fill_lane<F: Layout>(
    out: &mut [F::Elem],
    l: usize,
    li: usize,
    run: Option<Run>,
    sw: usize,
    zp: i32,
) {
    let words = out.chunks_exact_mut(l);
    let Some((src, table)) = run else {
        let pad = F::pad(zp);
        for d in words {
            d[li] = pad;
        }
        return;
    };
    let t = table.unwrap_or(&IDENTITY);
    let elem = |x: i8| F::elem(t[x as u8 as usize], zp);
    match sw {
        1 => words.zip(src).for_each(|(d, &x)| d[li] = elem(x)),
        _ => {
            // Every sw-th code: as many words as both hold, by index (the iterator adapters
            // cost ≈ 20 instructions per element on a Cortex-M).
            let m = (out.len() / l).min(src.len().div_ceil(sw));
            if li >= l {
                return;
            }
            for k in 0..m {
                // SAFETY: k < m ≤ ⌈len/sw⌉ so k·sw < src.len(); k·l + li < (k + 1)·l ≤ out.len().
                unsafe { *out.get_unchecked_mut(k * l + li) = elem(*src.get_unchecked(k * sw)) };
            }
        }
    }
}

/// A row of codes and the table its codes go through (`None`: as they are).
type Run<'a> = (&'a [i8], Option<&'a [i8; 256]>);

/// `out[x·4 + l] = elem(src[l][x])`: four contiguous channel rows into words.
#[inline]
fn interleave4<F: Layout>(src: [Run; 4], zp: i32, out: &mut [F::Elem]) {
    // Pixels that all four rows and `out` hold: nothing left after a vector path that did them.
    let all = src
        .iter()
        .map(|s| s.0.len())
        .fold(out.len() / 4, usize::min);
    if src.iter().all(|s| s.1.is_none()) {
        let done = F::interleave4_fast(src.map(|s| s.0), zp, out);
        if done >= all {
            return;
        }
        let rest = src.map(|s| s.0.get(done..).unwrap_or_default());
        let out = out.get_mut(done * 4..).unwrap_or_default();
        let it = rest[0].iter().zip(rest[1]).zip(rest[2]).zip(rest[3]);
        for (d, (((&a, &b), &c), &e)) in out.chunks_exact_mut(4).zip(it) {
            d[0] = F::elem(a, zp);
            d[1] = F::elem(b, zp);
            d[2] = F::elem(c, zp);
            d[3] = F::elem(e, zp);
        }
        return;
    }
    let done = F::interleave4_tables_fast(src.map(|s| s.0), src.map(|s| s.1), 4, 1, zp, out);
    if done >= all {
        return;
    }
    let t = src.map(|s| s.1.unwrap_or(&IDENTITY));
    let rest = src.map(|s| s.0.get(done..).unwrap_or_default());
    let out = out.get_mut(done * 4..).unwrap_or_default();
    let it = rest[0].iter().zip(rest[1]).zip(rest[2]).zip(rest[3]);
    for (d, (((&a, &b), &c), &e)) in out.chunks_exact_mut(4).zip(it) {
        d[0] = F::elem(t[0][a as u8 as usize], zp);
        d[1] = F::elem(t[1][b as u8 as usize], zp);
        d[2] = F::elem(t[2][c as u8 as usize], zp);
        d[3] = F::elem(t[3][e as u8 as usize], zp);
    }
}

/// `out[x·2 + l] = elem(src[l][x])`: two contiguous channel rows into words.
#[inline]
fn interleave2<F: Layout>(src: [Run; 2], zp: i32, out: &mut [F::Elem]) {
    if src.iter().all(|s| s.1.is_none()) {
        let done = F::interleave2_fast(src[0].0, src[1].0, zp, out);
        let (a, b) = (src[0].0.get(done..), src[1].0.get(done..));
        let (a, b) = (a.unwrap_or_default(), b.unwrap_or_default());
        let out = out.get_mut(done * 2..).unwrap_or_default();
        for (d, (&a, &b)) in out.chunks_exact_mut(2).zip(a.iter().zip(b)) {
            d[0] = F::elem(a, zp);
            d[1] = F::elem(b, zp);
        }
        return;
    }
    // Some part is requantised: a table per lane (the identity for the others), one pass
    // (after the layout's vector path, where it has one).
    let (ta, tb) = (src[0].1.unwrap_or(&IDENTITY), src[1].1.unwrap_or(&IDENTITY));
    let rows4 = [src[0].0, src[1].0, &[], &[]];
    let done = F::interleave4_tables_fast(rows4, [src[0].1, src[1].1, None, None], 2, 1, zp, out);
    let (a, b) = (src[0].0.get(done..), src[1].0.get(done..));
    let (a, b) = (a.unwrap_or_default(), b.unwrap_or_default());
    let out = out.get_mut(done * 2..).unwrap_or_default();
    for (d, (&a, &b)) in out.chunks_exact_mut(2).zip(a.iter().zip(b)) {
        d[0] = F::elem(ta[a as u8 as usize], zp);
        d[1] = F::elem(tb[b as u8 as usize], zp);
    }
}

/// The table that maps every code to itself.
static IDENTITY: [i8; 256] = {
    let mut t = [0i8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = i as u8 as i8;
        i += 1;
    }
    t
};

/// Packs the weights of the group's `ocg` output channels (`[ocg][icg][kh][kw]`, row-major) into
/// `dims.n_blocks` blocks; `sums[o]` receives `Σw` of output `o`.
pub fn pack_weights<F: Layout>(
    g: &ConvGeometry,
    weights: &[i8],
    icg: usize,
    ocg: usize,
    dims: &Dims,
    out: &mut [F::W],
    sums: &mut [i32],
) {
    let (kh, kw) = (g.kernel[0], g.kernel[1]);
    let taps = icg * kh * kw;
    let l = F::L;
    out[..ocg.div_ceil(NB) * dims.block_len].fill(F::W::default());
    if kh * kw == 1 {
        // One tap (1×1): output `o`'s weights go `l` by `l` (a channel group) into lanes
        // `j·l ..` of each `NB·l`-element step of its block, the same places as below without
        // the per-channel index arithmetic.
        for (o, (row, sum)) in weights.chunks_exact(taps).zip(sums).take(ocg).enumerate() {
            let (b, j) = (o / NB, o % NB);
            let dst = &mut out[b * dims.block_len + j * l..];
            // The sum in its own loop (integer sums: the same value in any order), then the
            // weights group by group.
            *sum = row.iter().map(|&w| i32::from(w)).sum();
            // `l` is the layout's constant: each group's copy is `l` fixed moves.
            let mut groups = dst.chunks_mut(NB * l);
            let whole = row.chunks_exact(l);
            let rest = whole.remainder();
            for (ws, d) in whole.zip(&mut groups) {
                if let Some(d) = d.get_mut(..l) {
                    for (d, &w) in d.iter_mut().zip(ws) {
                        *d = F::weight(w);
                    }
                }
            }
            if let Some(d) = groups.next() {
                for (d, &w) in d.iter_mut().zip(rest) {
                    *d = F::weight(w);
                }
            }
        }
        return;
    }
    // Consecutive taps of one input channel are `n_cg · NB · l` elements apart.
    let stride = dims.n_cg * NB * l;
    for o in 0..ocg {
        let (b, j) = (o / NB, o % NB);
        let row = &weights[o * taps..(o + 1) * taps];
        let mut s = 0i32;
        for (c, taps_c) in row.chunks_exact((kh * kw).max(1)).enumerate() {
            let (cg, li) = (c / l, c % l);
            let mut at = b * dims.block_len + (cg * NB + j) * l + li;
            for &w in taps_c {
                s += w as i32;
                out[at] = F::weight(w);
                at += stride;
            }
        }
        sums[o] = s;
    }
}
