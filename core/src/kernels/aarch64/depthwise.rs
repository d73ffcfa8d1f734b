//! NEON depthwise taps for the band path of [`crate::kernels::depthwise`]: 16 sums held in
//! registers across every tap (`SMLAL`/`SMLAL2` by a scalar weight on 16-bit `x − zp`), stored
//! once, instead of one load, add and store of the sums per tap. Exact (|w·x| ≤ 128·255), so
//! the same sums as the portable loop.

use core::arch::aarch64::*;

/// `out[i] = Σ_t w[t] · x[offs[t] + i]` for every `i < out.len()` (wrapping, as exact as the
/// portable loop). Returns `false` (and does nothing) without NEON, where `offs` and `w` differ
/// in length, or where a run would leave `x`.
pub fn taps(x: &[i16], offs: &[usize], w: &[i16], out: &mut [i32]) -> bool {
    let n = out.len();
    // Every run lies inside `x` when the farthest one does.
    let far = offs.iter().copied().max().unwrap_or(0);
    let inside = far.checked_add(n).is_some_and(|e| e <= x.len());
    if !crate::kernels::isa::Isa::Neon.available() || offs.len() != w.len() || !inside {
        return false;
    }
    let nine = (<&[usize; 9]>::try_from(offs), <&[i16; 9]>::try_from(w));
    if (1..16).contains(&n) && far + 16 <= x.len() {
        // A short run (a strided band's narrow rows) as one 16-wide pass into a buffer when
        // its 16 reads stay inside `x`: the first `n` sums are the same.
        let mut t = [0i32; 16];
        // SAFETY: NEON is available; every read `x[o + i]`, `i < 16`, is inside `x` (checked)
        // and every write inside `t` (16).
        unsafe {
            match nine {
                (Ok(offs9), Ok(w9)) => taps9_neon(x, offs9, w9, &mut t),
                _ => taps_neon(x, offs, w, &mut t),
            }
        };
        out.copy_from_slice(&t[..n]);
        return true;
    }
    if let (Ok(offs9), Ok(w9)) = nine {
        if n >= 16 {
            // SAFETY: as below; `n ≥ 16`.
            unsafe { taps9_neon(x, offs9, w9, out) };
            return true;
        }
    }
    // SAFETY: NEON is available; every read `x[o + i]`, `i < n`, is inside `x` (checked) and
    // every write inside `out`.
    unsafe { taps_neon(x, offs, w, out) };
    true
}

/// [`taps_neon`] for nine taps (3×3) and `n ≥ 16` sums: the weights held in two registers and
/// read by lane (`SMLAL` by element), the nine runs' pointers in registers, so a tap is its
/// two loads and four multiply-adds (no offset or weight load, no loop counter per tap).
///
/// # Safety
/// The CPU must have NEON; `n = out.len() ≥ 16` and every read `x[offs[t] + i]`, `i < n`, is
/// inside `x` ([`taps`] checks).
#[target_feature(enable = "neon")]
unsafe fn taps9_neon(x: &[i16], offs: &[usize; 9], w: &[i16; 9], out: &mut [i32]) {
    let n = out.len();
    let (xp, op) = (x.as_ptr(), out.as_mut_ptr());
    let (wa, wb) = (vld1q_s16(w.as_ptr()), vdupq_n_s16(w[8]));
    let p: [*const i16; 9] = core::array::from_fn(|t| xp.wrapping_add(offs[t]));
    // Sums `i .. i + 16` (`i + 16 ≤ n`: every read inside `x`, every write inside `out`).
    let sixteen = |i: usize| {
        // The first tap's products start the sums (`SMULL`), the others add to them.
        let q = p[0].add(i);
        let mut a = mul16_lane0(vld1q_s16(q), vld1q_s16(q.add(8)), wa);
        macro_rules! tap {
            ($t:literal, $l:literal, $w:ident) => {{
                let q = p[$t].add(i);
                mla16_lane::<$l>(&mut a, vld1q_s16(q), vld1q_s16(q.add(8)), $w);
            }};
        }
        tap!(1, 1, wa);
        tap!(2, 2, wa);
        tap!(3, 3, wa);
        tap!(4, 4, wa);
        tap!(5, 5, wa);
        tap!(6, 6, wa);
        tap!(7, 7, wa);
        tap!(8, 0, wb);
        for (q, v) in a.into_iter().enumerate() {
            vst1q_s32(op.add(i + 4 * q), v);
        }
    };
    let mut i = 0;
    while i + 16 <= n {
        sixteen(i);
        i += 16;
    }
    if i < n {
        // The last sums again, overlapping: the same values rewritten.
        sixteen(n - 16);
    }
}

/// `x[4q .. 4q + 4] · w[0]` for the 16 halfwords of `x0`, `x1` (`SMULL`/`SMULL2` by
/// element): the sums [`mla16_lane`] then adds to.
///
/// # Safety
/// The CPU must have NEON.
#[inline(always)]
unsafe fn mul16_lane0(x0: int16x8_t, x1: int16x8_t, w: int16x8_t) -> [int32x4_t; 4] {
    let (a0, a1, a2, a3);
    // SAFETY (caller): the CPU has NEON; registers only, no memory, flags untouched.
    core::arch::asm!(
        "smull {a0:v}.4s, {x0:v}.4h, {w:v}.h[0]",
        "smull2 {a1:v}.4s, {x0:v}.8h, {w:v}.h[0]",
        "smull {a2:v}.4s, {x1:v}.4h, {w:v}.h[0]",
        "smull2 {a3:v}.4s, {x1:v}.8h, {w:v}.h[0]",
        a0 = out(vreg) a0,
        a1 = out(vreg) a1,
        a2 = out(vreg) a2,
        a3 = out(vreg) a3,
        x0 = in(vreg) x0,
        x1 = in(vreg) x1,
        w = in(vreg_low16) w,
        options(pure, nomem, nostack, preserves_flags)
    );
    [a0, a1, a2, a3]
}

/// [`mla16`] with the weight in lane `L` of `w` (`SMLAL`/`SMLAL2` by element).
///
/// # Safety
/// The CPU must have NEON.
#[inline(always)]
unsafe fn mla16_lane<const L: i32>(
    a: &mut [int32x4_t; 4],
    x0: int16x8_t,
    x1: int16x8_t,
    w: int16x8_t,
) {
    // SAFETY (caller): the CPU has NEON; registers only, no memory, flags untouched.
    core::arch::asm!(
        "smlal {a0:v}.4s, {x0:v}.4h, {w:v}.h[{l}]",
        "smlal2 {a1:v}.4s, {x0:v}.8h, {w:v}.h[{l}]",
        "smlal {a2:v}.4s, {x1:v}.4h, {w:v}.h[{l}]",
        "smlal2 {a3:v}.4s, {x1:v}.8h, {w:v}.h[{l}]",
        a0 = inout(vreg) a[0],
        a1 = inout(vreg) a[1],
        a2 = inout(vreg) a[2],
        a3 = inout(vreg) a[3],
        x0 = in(vreg) x0,
        x1 = in(vreg) x1,
        w = in(vreg_low16) w,
        l = const L,
        options(pure, nomem, nostack, preserves_flags)
    );
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn taps_neon(x: &[i16], offs: &[usize], w: &[i16], out: &mut [i32]) {
    let n = out.len();
    let (xp, op) = (x.as_ptr(), out.as_mut_ptr());
    // Sums `i .. i + 16`.
    let sixteen = |i: usize| {
        let mut a = [vdupq_n_s32(0); 4];
        for (&o, &wv) in offs.iter().zip(w) {
            let p = xp.add(o + i);
            let (x0, x1) = (vld1q_s16(p), vld1q_s16(p.add(8)));
            mla16(&mut a, x0, x1, vdupq_n_s16(wv));
        }
        for (q, v) in a.into_iter().enumerate() {
            vst1q_s32(op.add(i + 4 * q), v);
        }
    };
    let mut i = 0;
    while i + 16 <= n {
        sixteen(i);
        i += 16;
    }
    if i < n && n >= 16 {
        // The last sums again, overlapping: the same values rewritten.
        sixteen(n - 16);
        return;
    }
    while i + 4 <= n {
        let mut a = vdupq_n_s32(0);
        for (&o, &wv) in offs.iter().zip(w) {
            a = vmlal_n_s16(a, vld1_s16(xp.add(o + i)), wv);
        }
        vst1q_s32(op.add(i), a);
        i += 4;
    }
    while i < n {
        let mut s = 0i32;
        for (&o, &wv) in offs.iter().zip(w) {
            s = s.wrapping_add(i32::from(wv) * i32::from(*xp.add(o + i)));
        }
        *op.add(i) = s;
        i += 1;
    }
}

/// `a[q] += x[4q .. 4q + 4] · w[0]` for the 16 halfwords of `x0`, `x1`: `SMLAL`/`SMLAL2` by
/// element, written with `asm!` because LLVM turns the intrinsics' high halves of a broadcast
/// weight into a lane move and a low-half `SMLAL` each.
///
/// # Safety
/// The CPU must have NEON.
#[inline(always)]
unsafe fn mla16(a: &mut [int32x4_t; 4], x0: int16x8_t, x1: int16x8_t, w: int16x8_t) {
    // SAFETY (caller): the CPU has NEON; registers only, no memory, flags untouched.
    core::arch::asm!(
        "smlal {a0:v}.4s, {x0:v}.4h, {w:v}.h[0]",
        "smlal2 {a1:v}.4s, {x0:v}.8h, {w:v}.h[0]",
        "smlal {a2:v}.4s, {x1:v}.4h, {w:v}.h[0]",
        "smlal2 {a3:v}.4s, {x1:v}.8h, {w:v}.h[0]",
        a0 = inout(vreg) a[0],
        a1 = inout(vreg) a[1],
        a2 = inout(vreg) a[2],
        a3 = inout(vreg) a[3],
        x0 = in(vreg) x0,
        x1 = in(vreg) x1,
        w = in(vreg_low16) w,
        options(pure, nomem, nostack, preserves_flags)
    );
}

/// The converted rows of a depthwise band in one call (`depthwise::bands`): for `r <
/// x16.len() / row_w`, input row `iy = first_iy + r` of `chan` (`iw` codes per row, `ih`
/// rows) into `x16[r·row_w ..]`, phase `φ < spans.len()` at `φ·phase_w`, its columns `lo ..
/// hi` from codes `first + k·sx` (`spans[φ] = (lo, hi, first)`) as 16-bit `x − zp`; rows
/// outside the image all zeros; the other columns are left as they are (the caller zeroed
/// them). Returns `false` (and does nothing) without NEON, for a stride other than 1 or 2 or
/// a zero point outside int8, or where a span lies outside its phase or reads past its row
/// (a span of fewer than 8 columns is converted one code at a time).
#[allow(clippy::too_many_arguments)]
pub fn widen_band<C: BandCode>(
    chan: &[C],
    (ih, iw): (usize, usize),
    first_iy: isize,
    (row_w, phase_w): (usize, usize),
    sx: usize,
    spans: &[(usize, usize, usize)],
    zp: i32,
    x16: &mut [i16],
) -> bool {
    let Some(zp) = C::zero_point(zp) else {
        return false;
    };
    // A span of any length (fewer than 8 codes go through the scalar loop below; an empty
    // one writes nothing).
    let ok_span = |&(lo, hi, first): &(usize, usize, usize)| {
        hi <= phase_w
            && (hi == lo
                || hi > lo
                    && (hi - lo - 1)
                        .checked_mul(sx)
                        .and_then(|e| e.checked_add(first))
                        .is_some_and(|e| e < iw))
    };
    if !crate::kernels::isa::Isa::Neon.available()
        || !(1..=2).contains(&sx)
        || spans.len() != sx
        || sx.checked_mul(phase_w) != Some(row_w)
        || ih.checked_mul(iw).is_none_or(|n| chan.len() < n)
        || !spans.iter().all(ok_span)
    {
        return false;
    }
    // Per phase, once for every row: its columns in the converted row, its first code and
    // `m`, the whole `sx`-code steps inside the input row (then the last code alone where
    // `sx = 2` leaves it half a step).
    let mut runs = [(0usize, 0usize, 0usize, 0usize); 2];
    for (run, (phase, &(lo, hi, first))) in runs.iter_mut().zip(spans.iter().enumerate()) {
        if hi > lo {
            let m = (hi - lo).min((iw - first) / sx);
            *run = (phase * phase_w + lo, phase * phase_w + hi, first, m);
        }
    }
    let runs = &runs[..spans.len()];
    for (r, row) in x16.chunks_exact_mut(row_w).enumerate() {
        let iy = first_iy + r as isize;
        if iy < 0 || iy >= ih as isize {
            row.fill(0);
            continue;
        }
        let src = &chan[iy as usize * iw..][..iw];
        for &(a, b, first, m) in runs {
            if a == b {
                continue;
            }
            let d = &mut row[a..b];
            let src = &src[first..];
            if m >= 8 {
                // SAFETY: NEON is available; the reads end at `m·sx ≤ src.len()`, the writes
                // at `m ≤ d.len()`.
                unsafe { C::widen_neon(src, sx, zp, &mut d[..m]) };
            } else {
                for (k, v) in d[..m].iter_mut().enumerate() {
                    *v = C::one(src[k * sx], zp);
                }
            }
            for (k, v) in d.iter_mut().enumerate().skip(m) {
                *v = C::one(src[k * sx], zp);
            }
        }
    }
    true
}

/// Input codes [`widen_band`] converts: int8 (`x − zp` exact in 16 bits) or int16 with zero
/// point 0 (the codes themselves: the int16 convs of `wide.rs`).
pub trait BandCode: Copy {
    /// The zero point in the form the conversion uses; `None` where it is not supported.
    type Zp: Copy;
    /// `zp` as [`BandCode::Zp`], `None` outside its range.
    fn zero_point(zp: i32) -> Option<Self::Zp>;
    /// One code converted.
    fn one(x: Self, zp: Self::Zp) -> i16;
    /// `dst[k] = one(src[k·sx])` for every `k < dst.len()`, 8 or 16 at a time.
    ///
    /// # Safety
    /// The CPU must have NEON; `8 ≤ dst.len()`, `dst.len()·sx ≤ src.len()`, `sx` 1 or 2.
    unsafe fn widen_neon(src: &[Self], sx: usize, zp: Self::Zp, dst: &mut [i16]);
}

impl BandCode for i8 {
    type Zp = i8;
    fn zero_point(zp: i32) -> Option<i8> {
        i8::try_from(zp).ok()
    }
    #[inline(always)]
    fn one(x: i8, zp: i8) -> i16 {
        i16::from(x) - i16::from(zp)
    }
    /// # Safety
    /// As the trait's.
    #[inline(always)]
    unsafe fn widen_neon(src: &[i8], sx: usize, zp: i8, dst: &mut [i16]) {
        widen_neon(src, sx, zp, dst)
    }
}

impl BandCode for i16 {
    type Zp = ();
    fn zero_point(zp: i32) -> Option<()> {
        (zp == 0).then_some(())
    }
    #[inline(always)]
    fn one(x: i16, _: ()) -> i16 {
        x
    }
    /// # Safety
    /// As the trait's.
    #[inline(always)]
    unsafe fn widen_neon(src: &[i16], sx: usize, _: (), dst: &mut [i16]) {
        copy_i16_neon(src, sx, dst)
    }
}

/// `dst[k] = src[k·sx]` (`LD2` keeps the even codes at `sx = 2`), 8 at a time, the last 8
/// overlapping.
///
/// # Safety
/// The CPU must have NEON; `8 ≤ dst.len()`, `dst.len()·sx ≤ src.len()`, `sx` 1 or 2.
#[target_feature(enable = "neon")]
unsafe fn copy_i16_neon(src: &[i16], sx: usize, dst: &mut [i16]) {
    let (sp, dp) = (src.as_ptr(), dst.as_mut_ptr());
    let m = dst.len();
    let eight = |k: usize| {
        let x = if sx == 2 {
            vld2q_s16(sp.add(2 * k)).0
        } else {
            vld1q_s16(sp.add(k))
        };
        vst1q_s16(dp.add(k), x);
    };
    let mut k = 0;
    while k + 8 <= m {
        eight(k);
        k += 8;
    }
    if k < m {
        eight(m - 8);
    }
}

/// `dst[k] = src[k·sx] − zp` (16-bit) for the leading `m = min(dst.len(), src.len() / sx)`
/// codes when `m ≥ 8`, at column stride `sx` 1 or 2 (`LD2` keeps the even codes): 16 (or 8) at
/// a time, the last part as an overlapping 16 (or 8) that rewrites the same values; returns
/// how many it did (0 without NEON, for other strides, `m < 8` or a zero point outside int8).
pub fn widen(src: &[i8], sx: usize, zp: i32, dst: &mut [i16]) -> usize {
    let m = if (1..=2).contains(&sx) {
        dst.len().min(src.len() / sx)
    } else {
        0
    };
    let Ok(zp) = i8::try_from(zp) else {
        return 0;
    };
    if !crate::kernels::isa::Isa::Neon.available() || m < 8 {
        return 0;
    }
    // SAFETY: NEON is available; the reads end at `m·sx ≤ src.len()`, the writes at `m ≤
    // dst.len()`.
    unsafe { widen_neon(src, sx, zp, &mut dst[..m]) };
    m
}

/// # Safety
/// The CPU must have NEON, `dst` must hold at least 8 codes and `src` `dst.len()·sx` (the safe
/// wrapper above checks; it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn widen_neon(src: &[i8], sx: usize, zp: i8, dst: &mut [i16]) {
    let (zpv, zpq) = (vdup_n_s8(zp), vdupq_n_s8(zp));
    let (sp, dp) = (src.as_ptr(), dst.as_mut_ptr());
    let m = dst.len();
    // x − zp exactly in 16 bits: SSUBL widens both before subtracting.
    let sixteen = |k: usize| {
        let x = if sx == 2 {
            vld2q_s8(sp.add(2 * k)).0
        } else {
            vld1q_s8(sp.add(k))
        };
        vst1q_s16(dp.add(k), vsubl_s8(vget_low_s8(x), zpv));
        vst1q_s16(dp.add(k + 8), vsubl_high_s8(x, zpq));
    };
    let eight = |k: usize| {
        let x = if sx == 2 {
            vld2_s8(sp.add(2 * k)).0
        } else {
            vld1_s8(sp.add(k))
        };
        vst1q_s16(dp.add(k), vsubl_s8(x, zpv));
    };
    if m >= 16 {
        let mut k = 0;
        while k + 16 <= m {
            sixteen(k);
            k += 16;
        }
        if k < m {
            sixteen(m - 16);
        }
    } else {
        eight(0);
        eight(m - 8);
    }
}
