//! Bilinear resize to an explicit size with `align_corners = true` (docs/graph.md `upsample_bilinear`).
//!
//! Source coordinate of output index `o` is `o·(n_in − 1)/(n_out − 1)`, an exact rational
//! `i0 + f/D` with `D = n_out − 1`. The int8 path interpolates the codes with these exact
//! integer weights in `i64` and rounds once (half away from zero), so it is within 0.5 LSB of the
//! real result; input and output share quantisation parameters (as TFLite requires), or, with a
//! [`ResizeRescale`], the output has its own and the interpolation and the requantisation still
//! round once (an upsample written at the scale of the concat that reads it).

use super::isa::Isa;
use super::requant::QParams;
use super::{need, KernelError, Shape};

/// Requantisation of an int8 resize whose output parameters differ from its input's: the exact
/// weighted sum `n = Σ w·x` (weights summing to `d`, the product of the two coordinate
/// denominators) becomes `zp_out + ⌊(n − zp_in·d) · s_in / (s_out·d) + ½⌋` (rounded half up),
/// the factor held as `k / 2^shift` (`2^30 ≤ k < 2^31` unless the factor is out of range).
/// Integer arithmetic only: the same bits on every target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C)]
pub struct ResizeRescale {
    /// `s_in / (s_out·d) · 2^shift`.
    k: i32,
    /// Right shift, 1 ..= 62.
    shift: u32,
    /// `zp_in · d`.
    offset: i64,
    /// `2^(shift−1) − zp_in·d·k` (the rounding half and the input zero point in one term) for
    /// [`NarrowRescale`], valid where `narrow` is 1.
    bias: i64,
    /// Output zero point.
    zp_out: i32,
    /// 1 where [`NarrowRescale`] serves every sum (`shift ≥ 32`, `bias` in 62 bits).
    narrow: u32,
}

impl ResizeRescale {
    /// For a resize of `in_shape` to `out_shape` from parameters `from` to `to`.
    pub fn new(from: QParams, to: QParams, in_shape: Shape, out_shape: Shape) -> ResizeRescale {
        let den = |n_in: usize, n_out: usize| {
            if n_out <= 1 || n_in <= 1 {
                1
            } else {
                (n_out - 1) as i64
            }
        };
        let d = den(in_shape.h, out_shape.h) * den(in_shape.w, out_shape.w);
        let mut x = from.scale as f64 / to.scale as f64 / d as f64;
        if !(x.is_finite() && x > 0.0) {
            x = 0.0;
        }
        let mut shift = 1;
        x *= 2.0;
        while x > 0.0 && x < (1u64 << 30) as f64 && shift < 62 {
            x *= 2.0;
            shift += 1;
        }
        let k = (x + 0.5).min(i32::MAX as f64) as i32;
        let offset = i64::from(from.zero_point) * d;
        let bias = offset
            .checked_mul(i64::from(k))
            .and_then(|ok| (1i64 << (shift - 1)).checked_sub(ok))
            .filter(|b| b.unsigned_abs() < 1 << 62);
        ResizeRescale {
            k,
            shift,
            offset,
            bias: bias.unwrap_or(0),
            zp_out: to.zero_point,
            narrow: u32::from(bias.is_some() && shift >= 32),
        }
    }

    /// The output code of the weighted code sum `n`.
    #[inline]
    fn apply(&self, n: i64) -> i8 {
        // `shift` is 1 ..= 62 from `new`; clamped for a value from elsewhere.
        let shift = self.shift.clamp(1, 62);
        let m = i128::from(n) - i128::from(self.offset);
        let q = (m * i128::from(self.k) + (1i128 << (shift - 1))) >> shift;
        (q.clamp(-(1 << 20), 1 << 20) as i32 + self.zp_out).clamp(-128, 127) as i8
    }

    /// The 32-bit form of this rescale where it serves every sum `|n| ≤ 2^30`: `shift ≥ 32` (a
    /// factor below 1/4) and the bias in 62 bits.
    fn narrow(&self) -> Option<NarrowRescale> {
        (self.narrow == 1 && (32..63).contains(&self.shift)).then(|| NarrowRescale {
            k: self.k,
            bias: self.bias,
            shift_hi: self.shift - 32,
            zp_out: self.zp_out,
        })
    }
}

/// [`ResizeRescale::apply`] for `|n| ≤ 2^30` in one 32 × 32 → 64-bit multiply-accumulate
/// (`SMLAL` on Cortex-M) and a shift of its high word: the same result (`|n·k + bias| < 2^63`).
/// Its four scalars stay in registers through the row loop.
#[derive(Clone, Copy, Debug)]
struct NarrowRescale {
    k: i32,
    bias: i64,
    /// `shift − 32`.
    shift_hi: u32,
    zp_out: i32,
}

impl NarrowRescale {
    /// The leading columns of [`narrow_row`] with vectors where `isa` has them (NEON); returns
    /// how many it did (0 elsewhere).
    #[inline(always)]
    fn vector_cols(
        self,
        isa: Isa,
        v: &[i32; ROW + 1],
        taps: &[u32; OUT_ROW],
        den: i32,
        out: &mut [i8],
    ) -> usize {
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot) {
            let r = (self.k, self.bias, self.shift_hi, self.zp_out);
            return super::aarch64::resize::rescaled_cols(v, taps, ROW - 1, den, r, out);
        }
        let _ = (isa, v, taps, den, out);
        0
    }

    #[inline(always)]
    fn apply(self, n: i32) -> i8 {
        let hi = ((i64::from(n) * i64::from(self.k) + self.bias) >> 32) as i32;
        ((hi >> self.shift_hi) + self.zp_out).clamp(-128, 127) as i8
    }
}

/// Index, numerator and denominator of the source coordinate of output index `o`.
#[inline]
fn src(o: usize, n_in: usize, n_out: usize) -> (usize, i64, i64) {
    if n_out <= 1 || n_in <= 1 {
        return (0, 0, 1);
    }
    let num = o * (n_in - 1);
    let den = n_out - 1;
    (num / den, (num % den) as i64, den as i64)
}

/// The source coordinates of outputs `0, 1, …` in order, as [`src`] gives them, by an exact
/// running remainder instead of a division per output.
struct Coords {
    i0: usize,
    f: i64,
    step: i64,
    den: i64,
}

impl Coords {
    fn new(n_in: usize, n_out: usize) -> Coords {
        let (step, den) = if n_out <= 1 || n_in <= 1 {
            (0, 1)
        } else {
            ((n_in - 1) as i64, (n_out - 1) as i64)
        };
        Coords {
            i0: 0,
            f: 0,
            step,
            den,
        }
    }

    /// `(i0, f, den)` of the current output, then moves to the next.
    #[inline]
    fn next(&mut self) -> (usize, i64, i64) {
        let here = (self.i0, self.f, self.den);
        self.f += self.step;
        while self.f >= self.den {
            self.f -= self.den;
            self.i0 += 1;
        }
        here
    }
}

#[inline]
fn div_round_i32(n: i32, d: i32) -> i32 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        -((-n + d / 2) / d)
    }
}

fn check<T>(input: &[T], in_shape: Shape, out: &[T], out_shape: Shape) -> Result<(), KernelError> {
    need(input, in_shape)?;
    need(out, out_shape)?;
    if in_shape.c != out_shape.c
        || in_shape.h == 0
        || in_shape.w == 0
        || in_shape.h > 1 << 15
        || in_shape.w > 1 << 15
    {
        return Err(KernelError::Shape);
    }
    if out_shape.h > 1 << 15 || out_shape.w > 1 << 15 {
        return Err(KernelError::Shape);
    }
    Ok(())
}

#[inline]
fn div_round(n: i64, d: i64) -> i64 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        -((-n + d / 2) / d)
    }
}

/// Reference int8 bilinear resize: every output element computed independently.
pub fn upsample_bilinear_ref(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
) -> Result<(), KernelError> {
    upsample_bilinear_to_ref(input, in_shape, out, out_shape, None)
}

/// [`upsample_bilinear_ref`] into the input's parameters (`None`) or other ones
/// ([`ResizeRescale`]).
pub fn upsample_bilinear_to_ref(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    rescale: Option<&ResizeRescale>,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    let (ih, iw) = (in_shape.h, in_shape.w);
    for c in 0..out_shape.c {
        for oy in 0..out_shape.h {
            let (y0, fy, dy) = src(oy, ih, out_shape.h);
            let y1 = (y0 + 1).min(ih - 1);
            for ox in 0..out_shape.w {
                let (x0, fx, dx) = src(ox, iw, out_shape.w);
                let x1 = (x0 + 1).min(iw - 1);
                let v = |y: usize, x: usize| input[(c * ih + y) * iw + x] as i64;
                let top = v(y0, x0) * (dx - fx) + v(y0, x1) * fx;
                let bot = v(y1, x0) * (dx - fx) + v(y1, x1) * fx;
                let total = top * (dy - fy) + bot * fy;
                out[(c * out_shape.h + oy) * out_shape.w + ox] = match rescale {
                    None => div_round(total, dx * dy).clamp(-128, 127) as i8,
                    Some(r) => r.apply(total),
                };
            }
        }
    }
    Ok(())
}

/// Fast int8 bilinear resize: same bits as [`upsample_bilinear_ref`], with the row weights and
/// row slices hoisted out of the column loop.
pub fn upsample_bilinear(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
) -> Result<(), KernelError> {
    upsample_bilinear_to(input, in_shape, out, out_shape, None)
}

/// [`upsample_bilinear`] into the input's parameters (`None`) or other ones: same bits as
/// [`upsample_bilinear_to_ref`].
pub fn upsample_bilinear_to(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    rescale: Option<&ResizeRescale>,
) -> Result<(), KernelError> {
    upsample_bilinear_to_with(Isa::best(), input, in_shape, out, out_shape, rescale)
}

/// As [`upsample_bilinear_to`] with kernel set `isa` (the NEON sets run the rescaled columns
/// with vectors; every set gives the same bits).
pub fn upsample_bilinear_to_with(
    isa: Isa,
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    rescale: Option<&ResizeRescale>,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    if rescale.is_some_and(|r| rescaled_arm(input, in_shape, out, out_shape, r)) {
        return Ok(());
    }
    resize_rows(isa, input, in_shape, out, out_shape, rescale);
    Ok(())
}

/// Widest input and output rows of [`rescaled_arm`] (its tables live on the stack).
#[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
const ARM_COLS: usize = 256;

/// The 16-bit column blends of [`rescaled_arm`], one past the widest row, word-aligned.
#[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
#[repr(align(4))]
struct Blends([i16; ARM_COLS + 2]);

/// The rescaled resize with the Cortex-M row ([`super::arm::resize::rescaled_row`]): per output
/// row the two input rows blended into 16-bit values `v_x` (`v_iw = v_iw−1`, the clamped right
/// neighbour), then one `SMLAD` per output column of the word `[v_x0 | v_x0+1]` against its
/// packed weights `[den − f | f]` (the reference's integer sum), the rescale folded into one
/// `SMMLA`. `false` (nothing written) outside its ranges: rows up to [`ARM_COLS`], `shift`
/// 33 ..= 55, blends in 16 bits (`dy ≤ 255`), `d ≤ 2^22`, an int8 output zero point. Out of
/// line, so its tables and [`resize_rows`]' never share a stack frame.
#[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
#[inline(never)]
fn rescaled_arm(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    r: &ResizeRescale,
) -> bool {
    use super::arm::resize::{rescaled_row, RowRescale};
    let (ih, iw, ow) = (in_shape.h, in_shape.w, out_shape.w);
    let (dy, den) = (src(1, ih, out_shape.h).2, Coords::new(iw, ow).den);
    let sh = r.shift.wrapping_sub(32);
    let add = (1i64 << (r.shift.clamp(33, 62) - 33)) + i64::from(r.zp_out) * (1i64 << sh.min(31));
    let fits = iw <= ARM_COLS
        && (1..=ARM_COLS).contains(&ow)
        && (1..=23).contains(&sh)
        && dy <= 255
        && den * dy <= 1 << 22
        && r.offset.unsigned_abs() <= 1 << 29
        && (-128..=127).contains(&r.zp_out)
        && add.unsigned_abs() <= 1 << 30;
    if !fits {
        return false;
    }
    let row = RowRescale {
        neg_offset: -(r.offset as i32),
        k: r.k,
        add: add as i32,
        sh,
    };
    // Per output column: the byte offset of its blend pair, its packed weights.
    let mut taps = [0u32; 2 * ARM_COLS];
    let mut cols = Coords::new(iw, ow);
    for t in taps[..2 * ow].chunks_exact_mut(2) {
        let (x0, f, _) = cols.next();
        // x0 < iw ≤ 256 and f < den < 2^15: both halves fit.
        t[0] = 2 * x0 as u32;
        t[1] = (den - f) as u32 | (f as u32) << 16;
    }
    let mut blend = Blends([0; ARM_COLS + 2]);
    let v = &mut blend.0[..iw + 1];
    for c in 0..out_shape.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        for (oy, orow) in out[c * out_shape.h * ow..(c + 1) * out_shape.h * ow]
            .chunks_exact_mut(ow)
            .enumerate()
        {
            let (y0, fy, dy) = src(oy, ih, out_shape.h);
            let y1 = (y0 + 1).min(ih - 1);
            let (r0, r1) = (&chan[y0 * iw..(y0 + 1) * iw], &chan[y1 * iw..(y1 + 1) * iw]);
            let (a, b) = ((dy - fy) as i32, fy as i32);
            // |v| ≤ 128·dy ≤ 32 640: 16 bits.
            for ((v, &x0), &x1) in v.iter_mut().zip(r0).zip(r1) {
                *v = (i32::from(x0) * a + i32::from(x1) * b) as i16;
            }
            v[iw] = v[iw - 1];
            // SAFETY: `taps` holds 2·ow words whose offsets 2·x0 (x0 < iw) leave 4 bytes of
            // `v` (iw + 1 halfwords) readable; `sh` is 1 ..= 23 (checked); Cortex-M4/M7 read
            // the odd-`x0` words unaligned.
            unsafe { rescaled_row(v, &taps[..2 * ow], &row, orow) };
        }
    }
    true
}

/// The portable rows of [`upsample_bilinear_to_with`] (out of line: see [`rescaled_arm`]).
#[inline(never)]
fn resize_rows(
    isa: Isa,
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    rescale: Option<&ResizeRescale>,
) {
    let (ih, iw) = (in_shape.h, in_shape.w);
    // The column blend of `narrow_row`, one past the row, and its output columns' taps (made
    // once per call).
    let mut blend = [0i32; ROW + 1];
    let mut taps = [0u32; OUT_ROW];
    let tabled = out_shape.w <= OUT_ROW && iw <= ROW;
    if tabled {
        let mut cols = Coords::new(iw, out_shape.w);
        for t in taps[..out_shape.w].iter_mut() {
            let (x0, f, _) = cols.next();
            // x0 < iw ≤ 256 and f < den < 2^15 (checked by `check`).
            *t = x0 as u32 | (f as u32) << 16;
        }
    }
    #[cfg(target_arch = "aarch64")]
    if tabled
        && matches!(isa, Isa::Neon | Isa::NeonDot)
        && separable(
            input,
            in_shape,
            out,
            out_shape,
            rescale,
            &taps[..out_shape.w],
        )
    {
        return;
    }
    for c in 0..out_shape.c {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        for oy in 0..out_shape.h {
            let (y0, fy, dy) = src(oy, ih, out_shape.h);
            let y1 = (y0 + 1).min(ih - 1);
            let (r0, r1) = (&chan[y0 * iw..(y0 + 1) * iw], &chan[y1 * iw..(y1 + 1) * iw]);
            let orow = &mut out
                [(c * out_shape.h + oy) * out_shape.w..(c * out_shape.h + oy + 1) * out_shape.w];
            let mut cols = Coords::new(iw, out_shape.w);
            // |sum| ≤ 128·dx·dy: in 32 bits (a hardware divide on Cortex-M) unless huge.
            let narrow = cols.den * dy <= 1 << 23;
            if narrow && tabled {
                let den = cols.den as i32;
                let rows = (r0, r1, fy as i32, dy as i32, den);
                match rescale {
                    None => narrow_row_same(isa, rows, &taps, orow, &mut blend),
                    Some(r) => match r.narrow() {
                        Some(nr) => {
                            let cols = |v: &[i32; ROW + 1], t: &[u32; OUT_ROW], o: &mut [i8]| {
                                nr.vector_cols(isa, v, t, den, o)
                            };
                            narrow_row(rows, &taps, orow, &mut blend, cols, move |n| nr.apply(n))
                        }
                        None => {
                            let cols = |_: &_, _: &_, _: &mut _| 0;
                            narrow_row(rows, &taps, orow, &mut blend, cols, |n| r.apply(n.into()))
                        }
                    },
                }
                continue;
            }
            for o in orow.iter_mut() {
                let (x0, fx, dx) = cols.next();
                let x1 = (x0 + 1).min(iw - 1);
                if narrow {
                    let (fx, dx, fy, dy) = (fx as i32, dx as i32, fy as i32, dy as i32);
                    let top = i32::from(r0[x0]) * (dx - fx) + i32::from(r0[x1]) * fx;
                    let bot = i32::from(r1[x0]) * (dx - fx) + i32::from(r1[x1]) * fx;
                    let n = top * (dy - fy) + bot * fy;
                    *o = match rescale {
                        None => div_round_i32(n, dx * dy).clamp(-128, 127) as i8,
                        Some(r) => r.apply(n.into()),
                    };
                } else {
                    let top = r0[x0] as i64 * (dx - fx) + r0[x1] as i64 * fx;
                    let bot = r1[x0] as i64 * (dx - fx) + r1[x1] as i64 * fx;
                    let n = top * (dy - fy) + bot * fy;
                    *o = match rescale {
                        None => div_round(n, dx * dy).clamp(-128, 127) as i8,
                        Some(r) => r.apply(n),
                    };
                }
            }
        }
    }
}

/// The NEON resize in two passes (`super::aarch64::resize`): each input row's column blend
/// `h[o] = r[x0]·(den − f) + r[x1]·f` once per channel (int16, exact), then per output row
/// `n = h_y0[o]·(dy − fy) + h_y1[o]·fy`, which is the reference's `top·(dy − fy) + bot·fy`
/// (the same integer), finished by the same rescale or rounded division: the same bits.
/// `false` (nothing written) where it does not apply (sums beyond the 32-bit paths, `den` above
/// 255, rows below 8 or above its width, a rescale without its 32-bit form).
#[cfg(target_arch = "aarch64")]
fn separable(
    input: &[i8],
    in_shape: Shape,
    out: &mut [i8],
    out_shape: Shape,
    rescale: Option<&ResizeRescale>,
    taps: &[u32],
) -> bool {
    use super::aarch64::resize::{rows, Columns, Finish, SEP_COLS};
    let (ih, iw, oh, ow) = (in_shape.h, in_shape.w, out_shape.h, out_shape.w);
    let (den, dy) = (Coords::new(iw, ow).den, Coords::new(ih, oh).den);
    if ow < 8 || oh == 0 || den * dy > 1 << 23 {
        return false;
    }
    let fin = match rescale {
        None => Finish::Same((den * dy) as i32),
        Some(r) => match r.narrow() {
            Some(n) => Finish::Rescaled((n.k, n.bias, n.shift_hi, n.zp_out)),
            None => return false,
        },
    };
    if !fin.valid() {
        return false;
    }
    let Some(mut cols) = Columns::new(taps, iw, den as i32) else {
        return false;
    };
    // The blends of the last two input rows, slot `y & 1` holding row `tag[y & 1]`.
    let mut h = [[0i16; SEP_COLS]; 2];
    for (c, plane) in out.chunks_exact_mut(oh * ow).take(out_shape.c).enumerate() {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let mut tag = [usize::MAX; 2];
        let mut ys = Coords::new(ih, oh);
        for orow in plane.chunks_exact_mut(ow) {
            let (y0, fy, dy) = ys.next();
            let y1 = (y0 + 1).min(ih - 1);
            for y in [y0, y1] {
                if tag[y & 1] != y {
                    cols.blend(&chan[y * iw..(y + 1) * iw], &mut h[y & 1]);
                    tag[y & 1] = y;
                }
            }
            // dy ≤ 2^15 − 1 (`check`), so both weights fit int16.
            let w = ((dy - fy) as i16, fy as i16);
            let done = rows(&h[y0 & 1][..ow], &h[y1 & 1][..ow], w, fin, orow);
            debug_assert!(done);
        }
    }
    true
}

/// Widest input row of [`narrow_row`] (its column blend lives on the stack).
const ROW: usize = 256;

/// Widest output row of [`narrow_row`] (its column taps live on the stack).
const OUT_ROW: usize = 1024;

/// One output row in 32 bits: the two input rows blended once per input column,
/// `v[x] = r0[x]·(dy − fy) + r1[x]·fy` (with `v[iw] = v[iw − 1]`, the clamped right
/// neighbour), then `n = v[x0]·(den − f) + v[x0 + 1]·f` per output column (`taps[o] = x0 | f << 16`,
/// [`Coords`]' sequence, `den` its denominator), the same integer as the reference's
/// `top·(dy − fy) + bot·fy` (exact), turned into the output code by `finish` (the reference's
/// rounding: the same bits). `|n| ≤ 128·den·dy < 2^31`, `r0.len() ≤ ROW`, every `x0 < r0.len()`.
/// `cols` may do the leading columns first (a vector path; it returns how many).
#[inline(always)]
fn narrow_row(
    (r0, r1, fy, dy, den): (&[i8], &[i8], i32, i32, i32),
    taps: &[u32; OUT_ROW],
    orow: &mut [i8],
    v: &mut [i32; ROW + 1],
    cols: impl FnOnce(&[i32; ROW + 1], &[u32; OUT_ROW], &mut [i8]) -> usize,
    finish: impl Fn(i32) -> i8,
) {
    let iw = r0.len().min(r1.len()).min(ROW);
    if iw == 0 {
        return;
    }
    for ((v, &a), &b) in v.iter_mut().zip(r0).zip(r1) {
        *v = i32::from(a) * (dy - fy) + i32::from(b) * fy;
    }
    v[iw] = v[iw - 1];
    let v: &[i32; ROW + 1] = v;
    let scalar = |orow: &mut [i8], taps: &[u32]| {
        for (o, &t) in orow.iter_mut().zip(taps) {
            // The mask keeps both reads inside `v` without a bounds branch (x0 < iw ≤ ROW).
            let x0 = t as usize & (ROW - 1);
            let f = (t >> 16) as i32;
            *o = finish(v[x0] * (den - f) + v[x0 + 1] * f);
        }
    };
    // One loop where `cols` did nothing (the portable set), another after its columns.
    match cols(v, taps, orow) {
        0 => scalar(orow, taps),
        done => scalar(
            orow.get_mut(done..).unwrap_or_default(),
            taps.get(done..).unwrap_or_default(),
        ),
    }
}

/// [`narrow_row`] into the input's parameters: `n` divided by `den·dy`, rounded half away
/// from zero without a branch on the sign (`div_round_i32`). Out of line: inlined into the
/// resize loop it spilled registers on Cortex-M (1.6 M more instructions per `mcu` frame).
#[inline(never)]
fn narrow_row_same(
    isa: Isa,
    rows: (&[i8], &[i8], i32, i32, i32),
    taps: &[u32; OUT_ROW],
    orow: &mut [i8],
    v: &mut [i32; ROW + 1],
) {
    let d = rows.4 * rows.3;
    let half = d / 2;
    let den = rows.4;
    // The leading columns 8 at a time where the set has NEON (the same integers, the division
    // exact in f32 there: `super::aarch64::resize::same_cols`).
    let cols = |v: &[i32; ROW + 1], t: &[u32; OUT_ROW], o: &mut [i8]| {
        #[cfg(target_arch = "aarch64")]
        if matches!(isa, Isa::Neon | Isa::NeonDot) {
            return super::aarch64::resize::same_cols(v, t, ROW - 1, den, d, o);
        }
        let _ = (isa, v, t, o, den);
        0
    };
    narrow_row(rows, taps, orow, v, cols, move |n: i32| {
        let sign = n >> 31;
        let q = (((((n ^ sign) - sign) + half) / d) ^ sign) - sign;
        q.clamp(-128, 127) as i8
    });
}

/// f32 bilinear resize (`align_corners = true`); used for depth maps and as the float reference.
pub fn upsample_bilinear_f32(
    input: &[f32],
    in_shape: Shape,
    out: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    upsample_bilinear_f32_with(Isa::Portable, input, in_shape, out, out_shape)
}

/// As [`upsample_bilinear_f32`] with kernel set `isa`: on the NEON sets each input row's column
/// blend once per channel ([`separable_f32`]), the same bits.
pub fn upsample_bilinear_f32_with(
    isa: Isa,
    input: &[f32],
    in_shape: Shape,
    out: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    check(input, in_shape, out, out_shape)?;
    #[cfg(target_arch = "aarch64")]
    if matches!(isa, Isa::Neon | Isa::NeonDot) && separable_f32(input, in_shape, out, out_shape) {
        return Ok(());
    }
    let _ = isa;
    for c in 0..out_shape.c {
        for oy in 0..out_shape.h {
            let at = (c * out_shape.h + oy) * out_shape.w;
            upsample_bilinear_f32_row(
                input,
                in_shape,
                c,
                oy,
                &mut out[at..at + out_shape.w],
                out_shape,
            )?;
        }
    }
    Ok(())
}

/// [`upsample_bilinear_f32`] in two passes: `top` and `bot` of [`upsample_bilinear_f32_row`]
/// are the column blend `r[x0]·(1 − wx) + r[x1]·wx` of input rows `y0` and `y1`, the same
/// value for every output row that reads that input row, so each input row's is computed once
/// per channel and each output row is then `top·(1 − wy) + bot·wy` over two contiguous rows
/// (vectorised by the compiler: separate multiplies and adds, no reassociation, the same IEEE
/// operations per pixel in the same order). `false` (nothing written) for output rows wider
/// than its buffers.
#[cfg(target_arch = "aarch64")]
fn separable_f32(input: &[f32], in_shape: Shape, out: &mut [f32], out_shape: Shape) -> bool {
    const COLS: usize = 1024;
    let (ih, iw, oh, ow) = (in_shape.h, in_shape.w, out_shape.h, out_shape.w);
    if ow == 0 || ow > COLS || oh == 0 {
        return false;
    }
    // Each output column's input columns and weights, as the row function computes them.
    let (mut x0s, mut x1s) = ([0u16; COLS], [0u16; COLS]);
    let (mut wx, mut vx) = ([0f32; COLS], [0f32; COLS]);
    let mut cols = Coords::new(iw, ow);
    for o in 0..ow {
        let (x0, fx, dx) = cols.next();
        // x0 < iw ≤ 2^15 (`check`).
        x0s[o] = x0 as u16;
        x1s[o] = (x0 + 1).min(iw - 1) as u16;
        wx[o] = fx as i32 as f32 / dx as i32 as f32;
        vx[o] = 1.0 - wx[o];
    }
    let (x0s, x1s, wx, vx) = (&x0s[..ow], &x1s[..ow], &wx[..ow], &vx[..ow]);
    let blend = |r: &[f32], h: &mut [f32; COLS]| {
        for ((((h, &x0), &x1), &w), &v) in h.iter_mut().zip(x0s).zip(x1s).zip(wx).zip(vx) {
            *h = r[x0 as usize] * v + r[x1 as usize] * w;
        }
    };
    // The blends of the last two input rows, slot `y & 1` holding row `tag[y & 1]`.
    let mut h = [[0f32; COLS]; 2];
    for (c, plane) in out.chunks_exact_mut(oh * ow).take(out_shape.c).enumerate() {
        let chan = &input[c * ih * iw..(c + 1) * ih * iw];
        let mut tag = [usize::MAX; 2];
        for (oy, orow) in plane.chunks_exact_mut(ow).enumerate() {
            let (y0, fy, dy) = src(oy, ih, oh);
            let y1 = (y0 + 1).min(ih - 1);
            for y in [y0, y1] {
                if tag[y & 1] != y {
                    blend(&chan[y * iw..(y + 1) * iw], &mut h[y & 1]);
                    tag[y & 1] = y;
                }
            }
            let wy = fy as f32 / dy as f32;
            let vy = 1.0 - wy;
            let (top, bot) = (&h[y0 & 1][..ow], &h[y1 & 1][..ow]);
            for ((o, &t), &b) in orow.iter_mut().zip(top).zip(bot) {
                *o = t * vy + b * wy;
            }
        }
    }
    true
}

/// Row `oy` of channel `c` of [`upsample_bilinear_f32`]'s output (`out_shape.w` values into
/// `dst`), the same bits, so a consumer can resize one row at a time.
pub fn upsample_bilinear_f32_row(
    input: &[f32],
    in_shape: Shape,
    c: usize,
    oy: usize,
    dst: &mut [f32],
    out_shape: Shape,
) -> Result<(), KernelError> {
    let (ih, iw) = (in_shape.h, in_shape.w);
    let ok = c < in_shape.c.min(out_shape.c)
        && oy < out_shape.h
        && ih > 0
        && iw > 0
        && dst.len() >= out_shape.w
        && in_shape.len().is_some_and(|n| n <= input.len());
    if !ok {
        return Err(KernelError::Shape);
    }
    let (y0, fy, dy) = src(oy, ih, out_shape.h);
    let y1 = (y0 + 1).min(ih - 1);
    let wy = fy as f32 / dy as f32;
    let r0 = &input[(c * ih + y0) * iw..][..iw];
    let r1 = &input[(c * ih + y1) * iw..][..iw];
    let mut cols = Coords::new(iw, out_shape.w);
    for o in dst[..out_shape.w].iter_mut() {
        let (x0, fx, dx) = cols.next();
        let x1 = (x0 + 1).min(iw - 1);
        // Both are below 2^31 (a row of `out_shape.w` values exists): the same f32 through
        // i32, without a 64-bit conversion call.
        let wx = fx as i32 as f32 / dx as i32 as f32;
        let top = r0[x0] * (1.0 - wx) + r0[x1] * wx;
        let bot = r1[x0] * (1.0 - wx) + r1[x1] * wx;
        *o = top * (1.0 - wy) + bot * wy;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::kernel_tests;
    use proptest::prelude::*;
    use std::vec::Vec;

    #[derive(Clone, Debug)]
    struct Case {
        x: Vec<i8>,
        s: Shape,
        o: Shape,
        expect: Option<Vec<i8>>,
    }

    type Impl = fn(&[i8], Shape, &mut [i8], Shape) -> Result<(), KernelError>;

    fn check_case(c: &Case, f: Impl) {
        let mut y = std::vec![0i8; c.o.len().unwrap()];
        f(&c.x, c.s, &mut y, c.o).unwrap();
        let xf: Vec<f32> = c.x.iter().map(|&v| v as f32).collect();
        let mut r = std::vec![0f32; y.len()];
        upsample_bilinear_f32(&xf, c.s, &mut r, c.o).unwrap();
        for (i, (&q, &v)) in y.iter().zip(&r).enumerate() {
            assert!((q as f32 - v).abs() <= 0.5 + 1e-3, "[{i}] {q} vs {v}");
        }
        if let Some(e) = &c.expect {
            assert_eq!(&y, e);
        }
        let mut y2 = std::vec![0i8; y.len()];
        upsample_bilinear_ref(&c.x, c.s, &mut y2, c.o).unwrap();
        assert_eq!(y, y2);
    }

    fn golden() -> Vec<Case> {
        std::vec![
            // 1×2 → 1×3 align_corners: 0, mid, 10.
            Case {
                x: std::vec![0, 10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 3),
                expect: Some(std::vec![0, 5, 10])
            },
            // 1×2 → 1×4: 0, 10/3, 20/3, 10 → 0, 3, 7, 10; negative: −10/3 → −3, −20/3 → −7
            Case {
                x: std::vec![0, 10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 4),
                expect: Some(std::vec![0, 3, 7, 10])
            },
            Case {
                x: std::vec![0, -10],
                s: Shape::new(1, 1, 2),
                o: Shape::new(1, 1, 4),
                expect: Some(std::vec![0, -3, -7, -10])
            },
            // 2×2 → 3×3 centre = mean of 4 corners (1+2+3+5)/4 = 2.75 → 3
            Case {
                x: std::vec![1, 2, 3, 5],
                s: Shape::new(1, 2, 2),
                o: Shape::new(1, 3, 3),
                expect: Some(std::vec![1, 2, 2, 2, 3, 4, 3, 4, 5])
            },
        ]
    }

    prop_compose! {
        fn arb()(c in 1usize..3, ih in 1usize..6, iw in 1usize..6, oh in 1usize..12, ow in 1usize..12, seed in any::<u32>()) -> Case {
            let s = Shape::new(c, ih, iw);
            let x = (0..s.len().unwrap()).map(|i| ((i as u32).wrapping_mul(2654435761) ^ seed) as i8).collect();
            Case { x, s, o: Shape::new(c, oh, ow), expect: None }
        }
    }

    #[test]
    fn running_coordinates_equal_the_division() {
        for n_in in 1..40 {
            for n_out in 1..90 {
                let mut c = Coords::new(n_in, n_out);
                for o in 0..n_out {
                    assert_eq!(c.next(), src(o, n_in, n_out), "{n_in} → {n_out} at {o}");
                }
            }
        }
    }

    kernel_tests!(suite, ref: upsample_bilinear_ref, fast: upsample_bilinear, golden: golden, arb: arb(), check: check_case);

    /// A resize into other parameters: fast (every kernel set) = reference bits, and within half an output step
    /// (plus the factor's 2^−30 relative error) of the exact resize of the dequantised input,
    /// where the output does not clamp.
    fn check_rescaled(c: &Case, from: QParams, to: QParams) {
        let r = ResizeRescale::new(from, to, c.s, c.o);
        let mut fast = std::vec![0i8; c.o.len().unwrap()];
        let mut slow = fast.clone();
        upsample_bilinear_to_ref(&c.x, c.s, &mut slow, c.o, Some(&r)).unwrap();
        for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
            upsample_bilinear_to_with(isa, &c.x, c.s, &mut fast, c.o, Some(&r)).unwrap();
            assert_eq!(fast, slow, "{}", isa.name());
        }
        let xf: Vec<f32> = c.x.iter().map(|&v| from.dequantize(v)).collect();
        let mut exact = std::vec![0f32; fast.len()];
        upsample_bilinear_f32(&xf, c.s, &mut exact, c.o).unwrap();
        for (i, (&q, &v)) in fast.iter().zip(&exact).enumerate() {
            let code = v / to.scale + to.zero_point as f32;
            if (-127.5..126.5).contains(&code) {
                assert!((q as f32 - code).abs() <= 0.5 + 1e-3, "[{i}] {q} vs {code}");
            } else {
                assert_eq!(q, if code < 0.0 { -128 } else { 127 }, "[{i}] clamps");
            }
        }
    }

    #[test]
    fn rescaled_by_hand() {
        // 0 and 2.0 (codes 0, 20 at scale 0.1) → 1×4: 0, 2/3, 4/3, 2 (real); at scale 0.15,
        // zero point −20: codes −20 + (0, 4.44, 8.89, 13.33) → −20, −16, −11, −7.
        let c = Case {
            x: std::vec![0, 20],
            s: Shape::new(1, 1, 2),
            o: Shape::new(1, 1, 4),
            expect: None,
        };
        let from = QParams {
            scale: 0.1,
            zero_point: 0,
        };
        let to = QParams {
            scale: 0.15,
            zero_point: -20,
        };
        let r = ResizeRescale::new(from, to, c.s, c.o);
        let mut y = [0i8; 4];
        upsample_bilinear_to(&c.x, c.s, &mut y, c.o, Some(&r)).unwrap();
        assert_eq!(y, [-20, -16, -11, -7]);
        check_rescaled(&c, from, to);
    }

    #[test]
    fn narrow_rescale_equals_the_wide_one() {
        // Every zero point pair at three scale ratios on a 30×40 → 120×160 resize (d = 18 921):
        // the 64-bit form gives the 128-bit form's codes over the whole sum range.
        let (from_s, to_s) = (Shape::new(1, 30, 40), Shape::new(1, 120, 160));
        for ratio in [0.3f32, 1.0, 7.0] {
            for zp_in in (-128..128).step_by(17) {
                for zp_out in (-128..128).step_by(23) {
                    let r = ResizeRescale::new(
                        QParams {
                            scale: 0.01,
                            zero_point: zp_in,
                        },
                        QParams {
                            scale: 0.01 * ratio,
                            zero_point: zp_out,
                        },
                        from_s,
                        to_s,
                    );
                    let nr = r.narrow().unwrap();
                    let d = 119 * 159;
                    for n in (-128 * d..=127 * d).step_by(997) {
                        assert_eq!(nr.apply(n), r.apply(n.into()), "{r:?} at {n}");
                    }
                }
            }
        }
    }

    /// The Cortex-M rescaled rows serve the decoder's upsamples (every zero point end, scale
    /// ratios around one, codes at both ends) with the reference's bits.
    #[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
    #[test]
    fn arm_rescaled_rows_serve_the_decoder_shapes() {
        let shapes = [
            (Shape::new(2, 30, 40), Shape::new(2, 60, 80)),
            (Shape::new(2, 15, 20), Shape::new(2, 30, 40)),
            (Shape::new(3, 4, 5), Shape::new(3, 8, 10)),
            (Shape::new(1, 30, 40), Shape::new(1, 120, 160)),
        ];
        for (s, o) in shapes {
            for (zi, zo, ratio) in [(-128, 127, 0.3f32), (5, -7, 1.0), (127, -128, 7.0)] {
                let from = QParams {
                    scale: 0.02,
                    zero_point: zi,
                };
                let to = QParams {
                    scale: 0.02 * ratio,
                    zero_point: zo,
                };
                let r = ResizeRescale::new(from, to, s, o);
                for pattern in 0..3u32 {
                    let x: Vec<i8> = (0..s.len().unwrap() as u32)
                        .map(|i| match pattern {
                            0 => (i.wrapping_mul(2654435761) >> 13) as i8,
                            1 => {
                                if i % 3 == 0 {
                                    127
                                } else {
                                    -128
                                }
                            }
                            _ => -128,
                        })
                        .collect();
                    let mut slow = std::vec![0i8; o.len().unwrap()];
                    let mut fast = std::vec![1i8; slow.len()];
                    upsample_bilinear_to_ref(&x, s, &mut slow, o, Some(&r)).unwrap();
                    assert!(rescaled_arm(&x, s, &mut fast, o, &r), "{s:?} → {o:?} {r:?}");
                    assert_eq!(fast, slow, "{s:?} → {o:?} {r:?} pattern {pattern}");
                }
            }
        }
    }

    /// A resize into the input's own parameters on every kernel set = the reference bits:
    /// the NEON columns' f32 division (`den·dy` up to 65535) and the scalar one past it.
    #[test]
    fn same_parameters_every_set_equals_the_reference() {
        let mut seed = 11u32;
        for (ih, iw, oh, ow) in [
            (3, 5, 9, 17),
            (20, 40, 40, 80),
            (60, 80, 120, 160),
            (2, 7, 255, 255),
            (2, 200, 300, 257),
            (3, 256, 2, 1024),
        ] {
            let s = Shape::new(2, ih, iw);
            let x: Vec<i8> = (0..s.len().unwrap())
                .map(|_| {
                    seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
                    (seed >> 24) as i8
                })
                .collect();
            // Runs of the extremes too (the largest |n|).
            let x: Vec<i8> = x
                .iter()
                .enumerate()
                .map(|(i, &v)| match i % 23 {
                    0..=4 => 127,
                    5..=9 => -128,
                    _ => v,
                })
                .collect();
            let o = Shape::new(2, oh, ow);
            let mut slow = std::vec![0i8; o.len().unwrap()];
            upsample_bilinear_to_ref(&x, s, &mut slow, o, None).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut fast = std::vec![0i8; slow.len()];
                upsample_bilinear_to_with(isa, &x, s, &mut fast, o, None).unwrap();
                assert_eq!(fast, slow, "{} {ih}×{iw} → {oh}×{ow}", isa.name());
            }
        }
    }

    /// The NEON sets' two-pass path (`separable`) and its fallbacks = the reference bits, into
    /// the input's parameters and into others: the model's ×2 shapes, rows not a multiple of 8
    /// or 16, the extreme codes, `den` at 127 and past 255, a downsample whose 16 outputs read more
    /// than 32 columns, and rows below 8.
    #[test]
    fn separable_rows_every_set_equal_the_reference() {
        let mut seed = 5u32;
        for (ih, iw, oh, ow) in [
            (30, 40, 60, 80),
            (15, 20, 30, 40),
            (60, 80, 120, 160),
            (1, 9, 3, 27),
            (4, 3, 7, 8),
            (5, 64, 9, 128),
            (5, 64, 9, 129),
            (3, 100, 4, 40),
            (2, 2, 2, 7),
            (7, 13, 1, 11),
            (2, 130, 3, 257),
            (30, 80, 59, 160),
        ] {
            let s = Shape::new(3, ih, iw);
            let x: Vec<i8> = (0..s.len().unwrap())
                .map(|i| {
                    seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
                    match i % 19 {
                        0..=3 => 127,
                        4..=7 => -128,
                        _ => (seed >> 24) as i8,
                    }
                })
                .collect();
            let c = Case {
                x,
                s,
                o: Shape::new(3, oh, ow),
                expect: None,
            };
            let o = c.o;
            let mut slow = std::vec![0i8; o.len().unwrap()];
            upsample_bilinear_to_ref(&c.x, s, &mut slow, o, None).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut fast = std::vec![0i8; slow.len()];
                upsample_bilinear_to_with(isa, &c.x, s, &mut fast, o, None).unwrap();
                assert_eq!(fast, slow, "{} {ih}×{iw} → {oh}×{ow}", isa.name());
            }
            for (zi, zo, ratio) in [(3, -9, 1.7f32), (-128, 127, 0.3), (0, 0, 1.0)] {
                let from = QParams {
                    scale: 0.05,
                    zero_point: zi,
                };
                let to = QParams {
                    scale: 0.05 * ratio,
                    zero_point: zo,
                };
                check_rescaled(&c, from, to);
            }
        }
    }

    /// The f32 resize on every kernel set (the NEON sets' two passes) = the portable bits,
    /// specials included.
    #[test]
    fn f32_every_set_equals_portable() {
        let mut seed = 3u32;
        for (ih, iw, oh, ow) in [
            (60, 80, 120, 160),
            (3, 5, 9, 17),
            (1, 1, 2, 3),
            (7, 9, 3, 4),
        ] {
            let s = Shape::new(2, ih, iw);
            let x: Vec<f32> = (0..s.len().unwrap())
                .map(|i| {
                    seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
                    match i % 41 {
                        0 => f32::NAN,
                        1 => f32::INFINITY,
                        2 => -0.0,
                        3 => f32::MAX,
                        _ => (seed >> 8) as f32 / 65536.0 - 100.0,
                    }
                })
                .collect();
            let o = Shape::new(2, oh, ow);
            let mut slow = std::vec![0f32; o.len().unwrap()];
            upsample_bilinear_f32(&x, s, &mut slow, o).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut fast = std::vec![0f32; slow.len()];
                upsample_bilinear_f32_with(isa, &x, s, &mut fast, o).unwrap();
                let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&fast),
                    bits(&slow),
                    "{} {ih}×{iw} → {oh}×{ow}",
                    isa.name()
                );
            }
        }
    }

    proptest! {
        #[test]
        fn same_parameters_fast_equals_ref(c in arb()) {
            let mut slow = std::vec![0i8; c.o.len().unwrap()];
            upsample_bilinear_to_ref(&c.x, c.s, &mut slow, c.o, None).unwrap();
            for isa in Isa::ALL.into_iter().filter(|i| i.available()) {
                let mut fast = std::vec![0i8; slow.len()];
                upsample_bilinear_to_with(isa, &c.x, c.s, &mut fast, c.o, None).unwrap();
                prop_assert_eq!(&fast, &slow, "{}", isa.name());
            }
        }

        #[test]
        fn rescaled_fast_equals_ref_and_rounds_once(
            c in arb(),
            s_in in 0.001f32..1.0,
            ratio in 0.05f32..20.0,
            zp_in in -128i32..128,
            zp_out in -128i32..128,
        ) {
            let from = QParams { scale: s_in, zero_point: zp_in };
            let to = QParams { scale: s_in * ratio, zero_point: zp_out };
            check_rescaled(&c, from, to);
        }

        #[test]
        fn rescaled_wide_rows_take_every_path(
            ih in 1usize..4, iw in 200usize..300, ow in 900usize..1100, seed in any::<u32>(),
        ) {
            // Rows wider than the tabled path's (input > 256 or output > 1024 columns).
            let s = Shape::new(1, ih, iw);
            let x = (0..s.len().unwrap()).map(|i| ((i as u32).wrapping_mul(2654435761) ^ seed) as i8).collect();
            let c = Case { x, s, o: Shape::new(1, 2, ow), expect: None };
            check_rescaled(&c, QParams { scale: 0.02, zero_point: 5 }, QParams { scale: 0.03, zero_point: -7 });
        }
    }
}
