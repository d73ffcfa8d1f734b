//! NEON packing for [`crate::kernels::pack::SignedQuads`]: four channel rows of codes into
//! 4-byte pixel words is exactly `ST4` (16 pixels per store), the codes kept as they are; and
//! for [`crate::kernels::pack::Pairs`] (`neon`): two rows widened to 16-bit `x − zp`
//! (`SSUBL`) into 2-halfword words with `ST2`.

use core::arch::aarch64::*;

/// `out[4x + l] = src[l][x]` for all the pixels that all four rows and `out` hold where they
/// are 16 or more (the last 16 overlapping the ones before: the same bytes again), else for
/// the leading 8 where there are 8 or more; returns how many pixels it packed (0 without NEON).
pub fn interleave4(src: [&[i8]; 4], out: &mut [i8]) -> usize {
    let n = src
        .iter()
        .map(|s| s.len())
        .min()
        .unwrap_or(0)
        .min(out.len() / 4);
    if !crate::kernels::isa::Isa::Neon.available() || n < 8 {
        return 0;
    }
    // SAFETY: NEON is available; `n ≥ 8` pixels lie inside every row and `4n` bytes inside
    // `out`.
    unsafe { interleave4_neon(src.map(|s| s.as_ptr()), out.as_mut_ptr(), n) }
}

/// Packs 16 pixels per `ST4` over `⌊n/16⌋·16`, then the last 16 again (overlapping) where
/// `n ≥ 16`, or the first 8 with one 8-lane `ST4` where `n < 16`; returns how many it packed.
///
/// # Safety
/// The CPU must have NEON, `n ≥ 8`, every row must hold `n` codes and `out` `4n` bytes.
#[target_feature(enable = "neon")]
unsafe fn interleave4_neon(src: [*const i8; 4], out: *mut i8, n: usize) -> usize {
    // SAFETY: every `x` below has `x + 16 ≤ n` (or `x + 8 ≤ n` for the 8-lane store): inside
    // the rows and `out` (the caller's contract).
    unsafe {
        let at16 = |x: usize| {
            let v = int8x16x4_t(
                vld1q_s8(src[0].add(x)),
                vld1q_s8(src[1].add(x)),
                vld1q_s8(src[2].add(x)),
                vld1q_s8(src[3].add(x)),
            );
            vst4q_s8(out.add(4 * x), v);
        };
        if n < 16 {
            let v = int8x8x4_t(
                vld1_s8(src[0]),
                vld1_s8(src[1]),
                vld1_s8(src[2]),
                vld1_s8(src[3]),
            );
            vst4_s8(out, v);
            return 8;
        }
        let mut x = 0;
        while x + 16 <= n {
            at16(x);
            x += 16;
        }
        if x < n {
            at16(n - 16);
        }
        n
    }
}

/// `out[4x + l] = src[l][2x]` (every other code: a stride-2 conv's column phase) for the
/// first `rows` rows (`1..=4`), `pad` in the other lanes, for the leading multiple of 16 pixels
/// whose 32 codes those rows hold and `out` has room for; returns how many pixels it packed (0
/// without NEON). `LD2` splits even and odd codes, `ST4` interleaves the even ones.
pub fn interleave4_stride2(src: [&[i8]; 4], rows: usize, pad: i8, out: &mut [i8]) -> usize {
    let shortest = src.iter().take(rows).map(|s| s.len()).min().unwrap_or(0);
    let n = (shortest / 2).min(out.len() / 4) / 16 * 16;
    if !crate::kernels::isa::Isa::Neon.available() || !(1..=4).contains(&rows) {
        return 0;
    }
    // SAFETY: NEON is available; `2n` codes lie inside each of the first `rows` rows and `4n`
    // bytes inside `out`.
    unsafe { interleave4_stride2_neon(src, rows, pad, out, n) };
    n
}

/// # Safety
/// The CPU must have NEON; each of the first `rows` rows holds `2n` codes and `out` `4n` bytes
/// (the safe wrapper above, the only caller, checks it).
#[target_feature(enable = "neon")]
unsafe fn interleave4_stride2_neon(
    src: [&[i8]; 4],
    rows: usize,
    pad: i8,
    out: &mut [i8],
    n: usize,
) {
    let fill = vdupq_n_s8(pad);
    let lane = |l: usize, x: usize| {
        if l < rows {
            // SAFETY: row `l < rows` holds `2n ≥ 2x + 32` codes (the caller's contract).
            unsafe { vld2q_s8(src[l].as_ptr().add(2 * x)).0 }
        } else {
            fill
        }
    };
    let mut x = 0;
    while x < n {
        let v = int8x16x4_t(lane(0, x), lane(1, x), lane(2, x), lane(3, x));
        vst4q_s8(out.as_mut_ptr().add(4 * x), v);
        x += 16;
    }
}

/// `out[4x + l] = t_l[src[l][sw·x]]` (`t_l` row `l`'s table, or the codes as they are where it
/// has none) for the first `rows` rows (`1..=4`), `pad` in the other lanes, `sw` 1 or 2, for
/// the leading multiple of 16 pixels that those rows (`sw·x + sw − 1 < len`, as
/// [`interleave4_stride2`] reads them) and `out` hold; returns how many pixels it packed (0
/// without NEON). A table is read 64 entries at a time with `TBL` and three `TBX` (an index
/// past 63 gives 0 in `TBL` and leaves the lane in `TBX`), the same bytes as the scalar look-up.
pub fn interleave4_tables(
    src: [&[i8]; 4],
    tables: [Option<&[i8; 256]>; 4],
    rows: usize,
    sw: usize,
    pad: i8,
    out: &mut [i8],
) -> usize {
    let shortest = src.iter().take(rows).map(|s| s.len()).min().unwrap_or(0);
    if !crate::kernels::isa::Isa::Neon.available() || !(1..=4).contains(&rows) || sw == 0 {
        return 0;
    }
    let n = match sw {
        1 => shortest,
        2 => shortest / 2,
        _ => return 0,
    };
    let n = n.min(out.len() / 4) / 16 * 16;
    if n == 0 {
        return 0;
    }
    let src = src.map(|s| s.as_ptr());
    // SAFETY: NEON is available; each of the first `rows` rows holds `sw·n` codes and `out`
    // `4n` bytes (checked above).
    unsafe {
        if sw == 1 {
            interleave4_tables_neon::<1>(src, tables, rows, pad, out.as_mut_ptr(), n);
        } else {
            interleave4_tables_neon::<2>(src, tables, rows, pad, out.as_mut_ptr(), n);
        }
    }
    n
}

/// `t[idx]` for 16 indices, the table in four 64-byte registers groups.
///
/// # Safety
/// The CPU must have NEON.
#[target_feature(enable = "neon")]
#[inline]
unsafe fn lookup16(t: &[i8; 256], idx: int8x16_t) -> int8x16_t {
    let p = t.as_ptr();
    let k64 = vdupq_n_u8(64);
    let i0 = vreinterpretq_u8_s8(idx);
    let (i1, i2, i3) = {
        let i1 = vsubq_u8(i0, k64);
        let i2 = vsubq_u8(i1, k64);
        (i1, i2, vsubq_u8(i2, k64))
    };
    // SAFETY: `t` holds 4 · 64 bytes.
    unsafe {
        let r = vqtbl4q_s8(vld1q_s8_x4(p), i0);
        let r = vqtbx4q_s8(r, vld1q_s8_x4(p.add(64)), i1);
        let r = vqtbx4q_s8(r, vld1q_s8_x4(p.add(128)), i2);
        vqtbx4q_s8(r, vld1q_s8_x4(p.add(192)), i3)
    }
}

/// [`interleave4_tables`]'s loop over `n` pixels (a multiple of 16), `SW` the column step.
///
/// # Safety
/// The CPU must have NEON; each of the first `rows` rows points at `SW·n` codes and `out` at
/// `4n` bytes.
#[target_feature(enable = "neon")]
unsafe fn interleave4_tables_neon<const SW: usize>(
    src: [*const i8; 4],
    tables: [Option<&[i8; 256]>; 4],
    rows: usize,
    pad: i8,
    out: *mut i8,
    n: usize,
) {
    let fill = vdupq_n_s8(pad);
    let lane = |l: usize, x: usize| {
        if l >= rows {
            return fill;
        }
        // SAFETY: row `l < rows` holds `SW·n ≥ SW·(x + 16)` codes (the caller's contract).
        let v = unsafe {
            if SW == 1 {
                vld1q_s8(src[l].add(x))
            } else {
                vld2q_s8(src[l].add(2 * x)).0
            }
        };
        match tables[l] {
            // SAFETY: NEON is available (the caller's contract).
            Some(t) => unsafe { lookup16(t, v) },
            None => v,
        }
    };
    let mut x = 0;
    while x < n {
        let v = int8x16x4_t(lane(0, x), lane(1, x), lane(2, x), lane(3, x));
        // SAFETY: `x + 16 ≤ n`: `4x + 64 ≤ 4n` bytes of `out`.
        unsafe { vst4q_s8(out.add(4 * x), v) };
        x += 16;
    }
}

/// `out[2x + l] = t_l[src[l][sw·x]] − zp` (16-bit; `t_l` row `l`'s table, or the codes as they
/// are where it has none) for the first `rows` rows (1 or 2), 0 in the other lane, `sw` 1 or
/// 2: the `Pairs` layout's words, for all `m` pixels that those rows (`sw·m` codes) and `out`
/// hold where `m ≥ 16` (the last 16 overlapping the ones before: the same values again);
/// returns how many pixels it packed (0 without NEON, for `m < 16`, or for a zero point outside
/// int8, where `x − zp` might not be exact in 16 bits).
pub fn pairs(
    src: [&[i8]; 2],
    tables: [Option<&[i8; 256]>; 2],
    rows: usize,
    sw: usize,
    zp: i32,
    out: &mut [i16],
) -> usize {
    let shortest = src.iter().take(rows).map(|s| s.len()).min().unwrap_or(0);
    let Ok(zp) = i8::try_from(zp) else {
        return 0;
    };
    if !crate::kernels::isa::Isa::Neon.available() || !(1..=2).contains(&rows) {
        return 0;
    }
    let m = match sw {
        1 => shortest,
        2 => shortest / 2,
        _ => return 0,
    };
    let m = m.min(out.len() / 2);
    if m < 16 {
        return 0;
    }
    let src = src.map(|s| s.as_ptr());
    // SAFETY: NEON is available; each of the first `rows` rows holds `sw·m` codes and `out`
    // `2m` halfwords (checked above), `m ≥ 16`.
    unsafe {
        if sw == 1 {
            pairs_neon::<1>(src, tables, rows, zp, out.as_mut_ptr(), m);
        } else {
            pairs_neon::<2>(src, tables, rows, zp, out.as_mut_ptr(), m);
        }
    }
    m
}

/// [`pairs`]' loop over `m ≥ 16` pixels, `SW` the column step.
///
/// # Safety
/// The CPU must have NEON; each of the first `rows` rows points at `SW·m` codes and `out` at
/// `2m` halfwords; `m ≥ 16`.
#[target_feature(enable = "neon")]
unsafe fn pairs_neon<const SW: usize>(
    src: [*const i8; 2],
    tables: [Option<&[i8; 256]>; 2],
    rows: usize,
    zp: i8,
    out: *mut i16,
    m: usize,
) {
    let (zpv, zpq) = (vdup_n_s8(zp), vdupq_n_s8(zp));
    // Lane `l`'s 16 values `x − zp` (exact in 16 bits: both are int8) as two halves.
    let lane = |l: usize, x: usize| -> (int16x8_t, int16x8_t) {
        if l >= rows {
            return (vdupq_n_s16(0), vdupq_n_s16(0));
        }
        // SAFETY: row `l < rows` holds `SW·m ≥ SW·(x + 16)` codes (the caller's contract).
        let v = unsafe {
            if SW == 1 {
                vld1q_s8(src[l].add(x))
            } else {
                vld2q_s8(src[l].add(2 * x)).0
            }
        };
        let v = match tables[l] {
            // SAFETY: NEON is available (the caller's contract).
            Some(t) => unsafe { lookup16(t, v) },
            None => v,
        };
        (vsubl_s8(vget_low_s8(v), zpv), vsubl_high_s8(v, zpq))
    };
    let sixteen = |x: usize| {
        let ((a0, a1), (b0, b1)) = (lane(0, x), lane(1, x));
        // SAFETY: `x + 16 ≤ m`: `2x + 32 ≤ 2m` halfwords of `out`.
        unsafe {
            vst2q_s16(out.add(2 * x), int16x8x2_t(a0, b0));
            vst2q_s16(out.add(2 * x + 16), int16x8x2_t(a1, b1));
        }
    };
    let mut x = 0;
    while x + 16 <= m {
        sixteen(x);
        x += 16;
    }
    if x < m {
        sixteen(m - 16);
    }
}
