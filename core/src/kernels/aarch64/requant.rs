//! NEON conv requantisation, 16 accumulators per pass: the scalar `requant_row` of
//! [`crate::kernels::conv`] (TFLite `MultiplyByQuantizedMultiplier` for right shifts, LeakyReLU's
//! second multiplier for negative sums, zero point, clamp) in exact integer arithmetic.
//! `SQRDMULH` is `⌊(x·m + 2³⁰) / 2³¹⌋` exactly (it saturates only for `x = m = −2³¹`, and
//! `m ≥ 0` here); `SRSHL` by `−e` is `⌊(q + 2^(e−1)) / 2^e⌋` without overflow, so subtracting
//! 1 from negative `q` first (`q > −2³¹` since `m < 2³¹`) rounds half away from zero as
//! `RoundingDivideByPOT` does.

use crate::kernels::conv::RowQuant;
use core::arch::aarch64::*;

/// Requantises each of the `consts.len()` rows of `acc` (row `j` at `j·acc_stride`, `n` sums)
/// into `out` at `at + j·out_stride`: 16 or 8 at a time with NEON, the last `n mod 8` as an
/// overlapping 8 (or, in a row shorter than 8 with 8 sums readable, through a buffer), else
/// through `tail`.
/// Returns `false` (and does nothing) where a row is not `simple` or a slice is short.
#[allow(clippy::too_many_arguments)]
pub fn block(
    consts: &[RowQuant],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    tail: impl Fn(&RowQuant, i32) -> i8,
) -> bool {
    let rows = consts.len();
    let fits = rows == 0
        || ((rows - 1) * acc_stride + n <= acc.len()
            && at + (rows - 1) * out_stride + n <= out.len());
    if !crate::kernels::isa::Isa::Neon.available() || !fits || !consts.iter().all(|k| k.simple) {
        return false;
    }
    // SAFETY: NEON is available (checked).
    unsafe { block_neon(consts, acc, acc_stride, n, out, at, out_stride, tail) };
    true
}

/// [`block`]'s loop, compiled with NEON so that [`row`] inlines into it; rows are addressed
/// through pointers (the slice bounds are checked once, by [`block`]).
///
/// # Safety
/// The CPU must have NEON; the slice conditions [`block`] checks hold.
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn block_neon(
    consts: &[RowQuant],
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i8],
    at: usize,
    out_stride: usize,
    tail: impl Fn(&RowQuant, i32) -> i8,
) {
    let (ap, op) = (acc.as_ptr(), out.as_mut_ptr().add(at));
    for (j, k) in consts.iter().enumerate() {
        let (a, o) = (ap.add(j * acc_stride), op.add(j * out_stride));
        if n >= 8 {
            // SAFETY: NEON is available; row `j`'s `n` sums and `n` outputs lie inside the
            // slices ([`block`] checked the last row's ends).
            unsafe { row(k, a, o, n, (k.min, k.max)) };
        } else if j * acc_stride + 8 <= acc.len() {
            // A short row with 8 sums readable (the rest of a block's row): into a buffer.
            let mut t = [0i8; 8];
            // SAFETY: NEON is available; 8 sums from `a` are inside `acc` (checked), and `t`
            // holds 8.
            unsafe { row(k, a, t.as_mut_ptr(), 8, (k.min, k.max)) };
            // SAFETY: row `j`'s `n < 8` outputs lie inside `out` (checked by [`block`]).
            unsafe { core::ptr::copy_nonoverlapping(t.as_ptr(), o, n) };
        } else {
            let start = at + j * out_stride;
            let row_acc = &acc[j * acc_stride..j * acc_stride + n];
            for (d, &v) in out[start..start + n].iter_mut().zip(row_acc) {
                *d = tail(k, v);
            }
        }
    }
}

/// Requantises the `n ≥ 8` sums at `acc` (`k.base` added) into `out`. One multiplier and shift for both signs (no LeakyReLU
/// slope) skips the per-lane selects, one shift for both signs skips the shift's select, and a
/// right shift on both sides makes the "−1 where `q < 0`" one `SSRA` (`q + (q >> 31)`, no
/// overflow as `q > −2³¹`) instead of a compare, a mask and an add.
///
/// # Safety
/// The CPU must have NEON; `acc` must point at `n ≥ 8` readable sums and `out` at `n`
/// writable codes.
#[inline(always)]
unsafe fn row<O: Narrow>(k: &RowQuant, acc: *const i32, out: *mut O, n: usize, bounds: (i32, i32)) {
    let (pm, nm) = (vdupq_n_s32(k.pos_m), vdupq_n_s32(k.neg_m));
    let (pe, ne) = (vdupq_n_s32(-k.pos_r), vdupq_n_s32(-k.neg_r));
    let shifted = k.pos_r > 0 && k.neg_r > 0;
    match (k.pos_m == k.neg_m, k.pos_r == k.neg_r) {
        (true, true) if k.pos_r == 0 => rows_with(k, acc, out, n, bounds, |x| vqrdmulhq_s32(x, pm)),
        (true, true) => rows_with(k, acc, out, n, bounds, |x| {
            let q = vqrdmulhq_s32(x, pm);
            vrshlq_s32(vsraq_n_s32::<31>(q, q), pe)
        }),
        (false, true) if shifted => rows_with(k, acc, out, n, bounds, |x| {
            let q = vqrdmulhq_s32(x, vbslq_s32(vcltzq_s32(x), nm, pm));
            vrshlq_s32(vsraq_n_s32::<31>(q, q), pe)
        }),
        _ if shifted => rows_with(k, acc, out, n, bounds, |x| {
            let neg = vcltzq_s32(x);
            let (m, e) = (vbslq_s32(neg, nm, pm), vbslq_s32(neg, ne, pe));
            let q = vqrdmulhq_s32(x, m);
            vrshlq_s32(vsraq_n_s32::<31>(q, q), e)
        }),
        _ => rows_with(k, acc, out, n, bounds, |x| {
            let neg = vcltzq_s32(x);
            let (m, e) = (vbslq_s32(neg, nm, pm), vbslq_s32(neg, ne, pe));
            let q = vqrdmulhq_s32(x, m);
            // −1 where q < 0 and there is a shift (e < 0 here is a right shift).
            let adj = vandq_u32(vcltzq_s32(q), vcltzq_s32(e));
            vrshlq_s32(vaddq_s32(q, vreinterpretq_s32_u32(adj)), e)
        }),
    }
}

/// Output codes [`rows_with`] stores: int8 (the conv's) or int16 ([`block_i16`]).
trait Narrow: Copy {
    /// The clamp bounds in the form the stores use, made once per row.
    type Bounds: Copy;
    /// `lo ..= hi` (inside the type's range) as [`Narrow::Bounds`].
    ///
    /// # Safety
    /// The CPU must have NEON.
    unsafe fn bounds(lo: i32, hi: i32) -> Self::Bounds;
    /// Narrows 16 requantised values (zero point added) with saturation, clamps them to the
    /// bounds and stores them at `p`.
    ///
    /// # Safety
    /// The CPU must have NEON; `p` points at 16 writable codes.
    unsafe fn put16(p: *mut Self, v: [int32x4_t; 4], b: Self::Bounds);
    /// [`Narrow::put16`] for 8 values.
    ///
    /// # Safety
    /// The CPU must have NEON; `p` points at 8 writable codes.
    unsafe fn put8(p: *mut Self, v: [int32x4_t; 2], b: Self::Bounds);
}

impl Narrow for i8 {
    type Bounds = (int8x16_t, int8x16_t);
    /// # Safety
    /// The CPU must have NEON.
    #[inline(always)]
    unsafe fn bounds(lo: i32, hi: i32) -> Self::Bounds {
        let (lo, hi) = (lo.clamp(-128, 127) as i8, hi.clamp(-128, 127) as i8);
        (vdupq_n_s8(lo), vdupq_n_s8(hi))
    }
    /// # Safety
    /// The CPU must have NEON; `p` points at 16 writable codes.
    #[inline(always)]
    unsafe fn put16(p: *mut i8, v: [int32x4_t; 4], (lo, hi): Self::Bounds) {
        let h0 = vcombine_s16(vqmovn_s32(v[0]), vqmovn_s32(v[1]));
        let h1 = vcombine_s16(vqmovn_s32(v[2]), vqmovn_s32(v[3]));
        let b = vcombine_s8(vqmovn_s16(h0), vqmovn_s16(h1));
        // SAFETY (caller): 16 codes at `p`.
        vst1q_s8(p, vminq_s8(vmaxq_s8(b, lo), hi));
    }
    /// # Safety
    /// The CPU must have NEON; `p` points at 8 writable codes.
    #[inline(always)]
    unsafe fn put8(p: *mut i8, v: [int32x4_t; 2], (lo, hi): Self::Bounds) {
        let b = vqmovn_s16(vcombine_s16(vqmovn_s32(v[0]), vqmovn_s32(v[1])));
        // SAFETY (caller): 8 codes at `p`.
        vst1_s8(p, vmin_s8(vmax_s8(b, vget_low_s8(lo)), vget_low_s8(hi)));
    }
}

impl Narrow for i16 {
    type Bounds = (int32x4_t, int32x4_t);
    /// # Safety
    /// The CPU must have NEON.
    #[inline(always)]
    unsafe fn bounds(lo: i32, hi: i32) -> Self::Bounds {
        (vdupq_n_s32(lo), vdupq_n_s32(hi))
    }
    /// # Safety
    /// The CPU must have NEON; `p` points at 16 writable codes.
    #[inline(always)]
    unsafe fn put16(p: *mut i16, v: [int32x4_t; 4], b: Self::Bounds) {
        // SAFETY (caller): 16 codes at `p`, the first 8 and the next.
        Self::put8(p, [v[0], v[1]], b);
        Self::put8(p.add(8), [v[2], v[3]], b);
    }
    /// # Safety
    /// The CPU must have NEON; `p` points at 8 writable codes.
    #[inline(always)]
    unsafe fn put8(p: *mut i16, v: [int32x4_t; 2], (lo, hi): Self::Bounds) {
        let c = |x: int32x4_t| vqmovn_s32(vminq_s32(vmaxq_s32(x, lo), hi));
        // SAFETY (caller): 8 codes at `p`.
        vst1q_s16(p, vcombine_s16(c(v[0]), c(v[1])));
    }
}

/// Requantises each of the `consts.len()` rows of `acc` (row `j` at `j·acc_stride`, `n ≥ 8`
/// sums) into int16 codes of `out` at `at + j·out_stride`, clamped to `lo ..= hi` (inside the
/// int16 range): `clamp(zp + MultiplyByQuantizedMultiplier(base + acc), lo, hi)`, the scalar
/// int16 finish of the int8 → int16 conv for `simple` rows. Returns `false` (and does nothing)
/// without NEON, where a row is not `simple`, `n < 8`, a bound leaves int16 or a slice is short.
#[allow(clippy::too_many_arguments)]
pub fn block_i16(
    consts: &[RowQuant],
    (lo, hi): (i32, i32),
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i16],
    at: usize,
    out_stride: usize,
) -> bool {
    let rows = consts.len();
    let fits = rows == 0
        || ((rows - 1) * acc_stride + n <= acc.len()
            && at + (rows - 1) * out_stride + n <= out.len());
    let bounded = -32768 <= lo && lo <= hi && hi <= 32767;
    if !crate::kernels::isa::Isa::Neon.available()
        || !fits
        || n < 8
        || !bounded
        || !consts.iter().all(|k| k.simple)
    {
        return false;
    }
    // SAFETY: NEON is available; every row's `n ≥ 8` sums and outputs lie inside the slices
    // (checked above).
    unsafe { block_i16_neon(consts, (lo, hi), acc, acc_stride, n, out, at, out_stride) };
    true
}

/// [`block_i16`]'s loop, compiled with NEON so that [`row`] inlines into it.
///
/// # Safety
/// The CPU must have NEON; the conditions [`block_i16`] checks hold.
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn block_i16_neon(
    consts: &[RowQuant],
    bounds: (i32, i32),
    acc: &[i32],
    acc_stride: usize,
    n: usize,
    out: &mut [i16],
    at: usize,
    out_stride: usize,
) {
    let (ap, op) = (acc.as_ptr(), out.as_mut_ptr().add(at));
    for (j, k) in consts.iter().enumerate() {
        // SAFETY: NEON is available; row `j`'s `n ≥ 8` sums and outputs lie inside the slices.
        unsafe { row(k, ap.add(j * acc_stride), op.add(j * out_stride), n, bounds) };
    }
}

/// The loops of [`row`] around `scaled` (the rounded, shifted product of `base + acc`): the
/// zero point added with saturation, then the output type's narrowing and clamp to `lo ..= hi`
/// ([`Narrow`]; inside the type's range, so the same as the scalar saturating add and clamp):
/// 16 sums per pass, then the rest as an overlapping 16 (9 to 15 left, 16 or more in all) or
/// 8s, the last overlapping (the same values rewritten).
///
/// # Safety
/// The CPU must have NEON, `n ≥ 8`, and `acc` and `out` must hold `n` each; [`row`], its only
/// caller, passes its contract on.
#[inline(always)]
unsafe fn rows_with<O: Narrow>(
    k: &RowQuant,
    ap: *const i32,
    op: *mut O,
    n: usize,
    (lo, hi): (i32, i32),
    scaled: impl Fn(int32x4_t) -> int32x4_t,
) {
    let base = vdupq_n_s32(k.base);
    let zp = vdupq_n_s32(k.zp);
    let bounds = O::bounds(lo, hi);
    let one = |p: *const i32| vqaddq_s32(scaled(vaddq_s32(base, vld1q_s32(p))), zp);
    let eight = |i: usize| {
        let p = ap.add(i);
        O::put8(op.add(i), [one(p), one(p.add(4))], bounds);
    };
    let sixteen = |i: usize| {
        let p = ap.add(i);
        let v = [one(p), one(p.add(4)), one(p.add(8)), one(p.add(12))];
        O::put16(op.add(i), v, bounds);
    };
    let mut i = 0;
    while i + 16 <= n {
        sixteen(i);
        i += 16;
    }
    // The rest: 9 to 15 past 16 or more as one overlapping 16, else 8 and an overlapping 8,
    // or one overlapping 8.
    let rest = n - i;
    if rest > 8 && n >= 16 {
        sixteen(n - 16);
    } else if rest > 8 {
        eight(i);
        eight(n - 8);
    } else if rest > 0 {
        eight(n - 8);
    }
}
