//! NEON columns of the int8 bilinear resize into other parameters (`resize::narrow_row` with a
//! 32-bit rescale): per output column the two blended input columns read as one pair, then
//! `n = v[x0]·(den − f) + v[x0 + 1]·f`, `((n·k + bias) >> 32) >> shift_hi` (`SMULL` and
//! `ADDHN`, the high word of the 64-bit sum), the zero point and the int8 clamp (saturating
//! narrows): the scalar integers exactly. Issue 40's fourth pass: the same sums separably
//! ([`Columns`] then [`rows`]), each input row's columns blended once per channel into int16 by
//! `TBL` and `SMULL`, then each output row two contiguous int16 rows by `SMULL`/`SMLAL`.

use core::arch::aarch64::*;

/// The constants of the 32-bit rescale: `k`, `bias`, `shift_hi` (`0..32`), output zero point.
pub type Rescale = (i32, i64, u32, i32);

/// `orow[o]` for the leading multiple of 8 columns, `taps[o] = x0 | f << 16` with `x0` read
/// through `mask` (`v.len() > mask + 1`, else nothing is done); returns how many it did.
pub fn rescaled_cols(
    v: &[i32],
    taps: &[u32],
    mask: usize,
    den: i32,
    r: Rescale,
    orow: &mut [i8],
) -> usize {
    let n = orow.len().min(taps.len()) / 8 * 8;
    if !crate::kernels::isa::Isa::Neon.available() || v.len() <= mask + 1 || r.2 >= 32 {
        return 0;
    }
    // SAFETY: NEON is available; every column read is `x0 & mask` and the one after it, inside
    // `v` (checked); `n` taps and outputs exist. The resize's mask (255) as a constant: the
    // mask and the scaling of a column index are then one `UBFIZ`.
    unsafe {
        if mask == 255 {
            cols_neon(v, taps, Mask::<255>, den, r, &mut orow[..n])
        } else {
            cols_neon(v, taps, mask, den, r, &mut orow[..n])
        }
    };
    n
}

/// A column mask, known when compiling ([`Mask`]) or not (`usize`).
trait ColMask: Copy {
    /// The mask's value.
    fn get(self) -> usize;
}

impl ColMask for usize {
    #[inline(always)]
    fn get(self) -> usize {
        self
    }
}

/// The mask `M` as a constant.
#[derive(Clone, Copy)]
struct Mask<const M: usize>;

impl<const M: usize> ColMask for Mask<M> {
    #[inline(always)]
    fn get(self) -> usize {
        M
    }
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn cols_neon(
    v: &[i32],
    taps: &[u32],
    mask: impl ColMask,
    den: i32,
    r: Rescale,
    out: &mut [i8],
) {
    let mask = mask.get();
    let (k, bias, shift_hi, zp) = r;
    let (denv, biasv) = (vdupq_n_s32(den), vdupq_n_s64(bias));
    let (shift, zpv) = (vdupq_n_s32(-(shift_hi as i32)), vdupq_n_s32(zp));
    let vp = v.as_ptr();
    let four = |o: usize| -> int32x4_t {
        let tp = taps.as_ptr().add(o);
        let pair = |i: usize| vld1_s32(vp.add(*tp.add(i) as usize & mask));
        let (ab01, ab23) = (
            vcombine_s32(pair(0), pair(1)),
            vcombine_s32(pair(2), pair(3)),
        );
        let (a, b) = (vuzp1q_s32(ab01, ab23), vuzp2q_s32(ab01, ab23));
        let f = vreinterpretq_s32_u32(vshrq_n_u32::<16>(vld1q_u32(tp)));
        let n = vmlaq_s32(vmulq_s32(a, vsubq_s32(denv, f)), b, f);
        rescale4(n, k, biasv, shift, zpv)
    };
    let mut o = 0;
    while o + 8 <= out.len() {
        let h = vcombine_s16(vqmovn_s32(four(o)), vqmovn_s32(four(o + 4)));
        vst1_s8(out.as_mut_ptr().add(o), vqmovn_s16(h));
        o += 8;
    }
}

/// `orow[o]` of the resize into the input's own parameters (`resize::narrow_row_same`): `n` as
/// in [`rescaled_cols`], then `n / d` rounded half away from zero (`(|n| + ⌊d/2⌋) / d` with the
/// sign put back) and clamped to int8, for the leading multiple of 8 columns; returns how many
/// it did (0 without NEON, where `v.len() ≤ mask + 1`, or where `d` is not in `1 ..= 65535`).
/// The quotient is an f32 `FDIV` truncated (`FCVTZS`), which is the integer quotient exactly:
/// `a = |n| + ⌊d/2⌋ ≤ 128.5·d < 2^24` is exact in f32, and where `a/d` is not an integer it lies
/// at least `1/d > 2^−16` below the next one while the rounding error of a quotient below 256
/// is at most `2^−17`.
pub fn same_cols(v: &[i32], taps: &[u32], mask: usize, den: i32, d: i32, orow: &mut [i8]) -> usize {
    let n = orow.len().min(taps.len()) / 8 * 8;
    if !crate::kernels::isa::Isa::Neon.available()
        || v.len() <= mask + 1
        || !(1..=65535).contains(&d)
    {
        return 0;
    }
    // SAFETY: NEON is available; every column read is `x0 & mask` and the one after it, inside
    // `v` (checked); `n` taps and outputs exist.
    unsafe {
        if mask == 255 {
            same_neon(v, taps, Mask::<255>, den, d, &mut orow[..n])
        } else {
            same_neon(v, taps, mask, den, d, &mut orow[..n])
        }
    };
    n
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn same_neon(v: &[i32], taps: &[u32], mask: impl ColMask, den: i32, d: i32, out: &mut [i8]) {
    let mask = mask.get();
    let denv = vdupq_n_s32(den);
    let (dv, half) = (vdupq_n_f32(d as f32), vdupq_n_s32(d / 2));
    let vp = v.as_ptr();
    let four = |o: usize| -> int32x4_t {
        let tp = taps.as_ptr().add(o);
        let pair = |i: usize| vld1_s32(vp.add(*tp.add(i) as usize & mask));
        let (ab01, ab23) = (
            vcombine_s32(pair(0), pair(1)),
            vcombine_s32(pair(2), pair(3)),
        );
        let (a, b) = (vuzp1q_s32(ab01, ab23), vuzp2q_s32(ab01, ab23));
        let f = vreinterpretq_s32_u32(vshrq_n_u32::<16>(vld1q_u32(tp)));
        let n = vmlaq_s32(vmulq_s32(a, vsubq_s32(denv, f)), b, f);
        divide4(n, half, dv)
    };
    let mut o = 0;
    while o + 8 <= out.len() {
        let h = vcombine_s16(vqmovn_s32(four(o)), vqmovn_s32(four(o + 4)));
        vst1_s8(out.as_mut_ptr().add(o), vqmovn_s16(h));
        o += 8;
    }
}

/// `((n·k + bias) >> 32) >> shift_hi + zp` per lane ([`rescaled_cols`]' rescale: `SMULL` and
/// `ADDHN`, the high word of the 64-bit sum; `shift` holds `−shift_hi`).
///
/// # Safety
/// The CPU must have NEON (every aarch64 target this crate builds for enables it).
#[inline(always)]
unsafe fn rescale4(
    n: int32x4_t,
    k: i32,
    biasv: int64x2_t,
    shift: int32x4_t,
    zpv: int32x4_t,
) -> int32x4_t {
    let lo = vaddhn_s64(vmull_n_s32(vget_low_s32(n), k), biasv);
    let hi = vaddhn_high_s64(lo, vmull_high_n_s32(n, k), biasv);
    vaddq_s32(vshlq_s32(hi, shift), zpv)
}

/// `n / d` rounded half away from zero per lane ([`same_cols`]' exact `FDIV`; `half` holds
/// `⌊d/2⌋`, `dv` holds `d` as f32).
///
/// # Safety
/// The CPU must have NEON (every aarch64 target this crate builds for enables it).
#[inline(always)]
unsafe fn divide4(n: int32x4_t, half: int32x4_t, dv: float32x4_t) -> int32x4_t {
    let sign = vshrq_n_s32::<31>(n);
    let a = vaddq_s32(vsubq_s32(veorq_s32(n, sign), sign), half);
    let q = vcvtq_s32_f32(vdivq_f32(vcvtq_f32_s32(a), dv));
    vsubq_s32(veorq_s32(q, sign), sign)
}

/// Widest input and output rows of the separable path ([`Columns`], [`rows`]).
pub const SEP_COLS: usize = 512;

/// Sixteen output columns of [`Columns`]: the input columns `x0` and `x1` of each as byte
/// indices into the 32 codes from `base`, and their weights `den − f` and `f`.
#[derive(Clone, Copy, Default)]
#[repr(C, align(16))]
struct Group {
    a: [u8; 16],
    b: [u8; 16],
    wa: [i16; 16],
    wb: [i16; 16],
    base: usize,
}

/// The column half of a separable resize: `h[o] = r[x0]·(den − f) + r[x1]·f` for each output
/// column `o` of an input row `r` (`x1 = min(x0 + 1, iw − 1)`), 16 columns per pass: one 32-byte
/// load at the group's first `x0`, two `TBL`s, the codes widened and `MUL`/`MLA` by 16-bit
/// weights, exact in int16 (`|h| ≤ 128·den ≤ 32640`). Built once per resize, used for every input row
/// of every channel.
pub struct Columns {
    groups: [Group; SEP_COLS / 16],
    n: usize,
    iw: usize,
    /// The current input row and zeros past it (a group's 32 codes may reach past the row).
    row: [i8; SEP_COLS + 32],
}

impl Columns {
    /// The columns of output taps `taps[o] = x0 | f << 16` (`f < den`) over input rows of `iw`
    /// codes; `None` where the path does not apply: no NEON, `den` above 255, rows wider than
    /// [`SEP_COLS`], or 16 consecutive outputs reading more than 32 input columns.
    pub fn new(taps: &[u32], iw: usize, den: i32) -> Option<Columns> {
        let ow = taps.len();
        if !crate::kernels::isa::Isa::Neon.available()
            || !(1..=255).contains(&den)
            || iw == 0
            || iw > SEP_COLS
            || ow == 0
            || ow > SEP_COLS
        {
            return None;
        }
        let mut c = Columns {
            groups: [Group::default(); SEP_COLS / 16],
            n: ow.div_ceil(16),
            iw,
            row: [0; SEP_COLS + 32],
        };
        for (g, t) in c.groups.iter_mut().zip(taps.chunks(16)) {
            g.base = (t[0] & 0xffff) as usize;
            for (l, &t) in t.iter().enumerate() {
                let (x0, f) = ((t & 0xffff) as usize, (t >> 16) as i32);
                let x1 = (x0 + 1).min(iw - 1);
                if x0 < g.base || x0 >= iw || x1 - g.base >= 32 || f >= den {
                    return None;
                }
                g.a[l] = (x0 - g.base) as u8;
                g.b[l] = (x1 - g.base) as u8;
                // 1 ≤ den − f ≤ 255 and 0 ≤ f < 255.
                g.wa[l] = (den - f) as i16;
                g.wb[l] = f as i16;
            }
        }
        Some(c)
    }

    /// `h[o]` of input row `r` (`iw` codes) for every output column, in groups of 16 (`h`
    /// holds [`SEP_COLS`]; the entries past the last column are left as any value).
    pub fn blend(&mut self, r: &[i8], h: &mut [i16; SEP_COLS]) {
        let Some(r) = r.get(..self.iw) else {
            return;
        };
        self.row[..self.iw].copy_from_slice(r);
        // SAFETY: NEON is available (`new`); a group reads the 32 codes from `base ≤ iw − 1`,
        // inside `row` (`SEP_COLS + 32`), and writes 16 of `h` at `16g < SEP_COLS`.
        unsafe { blend_neon(&self.groups[..self.n], &self.row, h) }
    }
}

/// # Safety
/// The CPU must have NEON; every group's `base + 32 ≤ row.len()`, and `16 · groups.len() ≤
/// h.len()` ([`Columns::blend`]).
#[target_feature(enable = "neon")]
unsafe fn blend_neon(groups: &[Group], row: &[i8], h: &mut [i16]) {
    let (rp, hp) = (row.as_ptr(), h.as_mut_ptr());
    for (i, g) in groups.iter().enumerate() {
        let t = vld1q_s8_x2(rp.add(g.base));
        let (ia, ib) = (vld1q_u8(g.a.as_ptr()), vld1q_u8(g.b.as_ptr()));
        let (a, b) = (vqtbl2q_s8(t, ia), vqtbl2q_s8(t, ib));
        let w = |p: &[i16; 16], k: usize| vld1q_s16(p.as_ptr().add(k));
        // |x·(den − f) + x'·f| ≤ 128·den < 2^15: the 16-bit products and sum are exact.
        let lo = vmlaq_s16(
            vmulq_s16(vmovl_s8(vget_low_s8(a)), w(&g.wa, 0)),
            vmovl_s8(vget_low_s8(b)),
            w(&g.wb, 0),
        );
        let hi = vmlaq_s16(
            vmulq_s16(vmovl_high_s8(a), w(&g.wa, 8)),
            vmovl_high_s8(b),
            w(&g.wb, 8),
        );
        vst1q_s16(hp.add(16 * i), lo);
        vst1q_s16(hp.add(16 * i + 8), hi);
    }
}

/// How [`rows`] turns the exact sum `n` into a code: the 32-bit rescale ([`rescaled_cols`]) or
/// the division by `d` of the resize into its input's parameters ([`same_cols`]).
#[derive(Clone, Copy, Debug)]
pub enum Finish {
    /// Into other parameters.
    Rescaled(Rescale),
    /// Into the input's parameters, `d` in `1 ..= 65535`.
    Same(i32),
}

impl Finish {
    /// Whether [`rows`] serves it: `shift_hi < 32`, or `d` in `1 ..= 65535`.
    pub fn valid(self) -> bool {
        match self {
            Finish::Rescaled(r) => r.2 < 32,
            Finish::Same(d) => (1..=65535).contains(&d),
        }
    }
}

/// The row half of a separable resize: `out[o] = finish(h0[o]·w0 + h1[o]·w1)` (`SMULL`/`SMLAL`
/// of int16 by int16, the exact sum `n` of the reference), 8 per pass and the last 8
/// overlapping. `false` (nothing written) without NEON, below 8 outputs, where `h0` or `h1` is
/// shorter than `out`, or outside [`Finish`]'s ranges.
pub fn rows(h0: &[i16], h1: &[i16], (w0, w1): (i16, i16), fin: Finish, out: &mut [i8]) -> bool {
    let n = out.len();
    if !crate::kernels::isa::Isa::Neon.available()
        || n < 8
        || h0.len() < n
        || h1.len() < n
        || !fin.valid()
    {
        return false;
    }
    match fin {
        // SAFETY: NEON is available; `h0`, `h1` and `out` hold `n ≥ 8` each (checked).
        Finish::Rescaled((k, bias, shift_hi, zp)) => unsafe {
            let (biasv, shift, zpv) = (
                vdupq_n_s64(bias),
                vdupq_n_s32(-(shift_hi as i32)),
                vdupq_n_s32(zp),
            );
            rows_neon(h0, h1, (w0, w1), out, |n| rescale4(n, k, biasv, shift, zpv))
        },
        // SAFETY: as above.
        Finish::Same(d) => unsafe {
            let (dv, half) = (vdupq_n_f32(d as f32), vdupq_n_s32(d / 2));
            rows_neon(h0, h1, (w0, w1), out, |n| divide4(n, half, dv))
        },
    }
    true
}

/// # Safety
/// The CPU must have NEON; `out.len() ≥ 8`, `h0` and `h1` at least as long ([`rows`]).
#[target_feature(enable = "neon")]
unsafe fn rows_neon(
    h0: &[i16],
    h1: &[i16],
    (w0, w1): (i16, i16),
    out: &mut [i8],
    fin: impl Fn(int32x4_t) -> int32x4_t,
) {
    let n = out.len();
    let (p0, p1, op) = (h0.as_ptr(), h1.as_ptr(), out.as_mut_ptr());
    let eight = |o: usize| {
        let (a, b) = (vld1q_s16(p0.add(o)), vld1q_s16(p1.add(o)));
        let lo = vmlal_n_s16(vmull_n_s16(vget_low_s16(a), w0), vget_low_s16(b), w1);
        let hi = vmlal_high_n_s16(vmull_high_n_s16(a, w0), b, w1);
        let h = vcombine_s16(vqmovn_s32(fin(lo)), vqmovn_s32(fin(hi)));
        vst1_s8(op.add(o), vqmovn_s16(h));
    };
    let mut o = 0;
    while o + 8 <= n {
        eight(o);
        o += 8;
    }
    if o < n {
        // The last 8 again, overlapping: the same codes rewritten.
        eight(n - 8);
    }
}
