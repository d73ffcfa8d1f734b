//! NEON packing for [`crate::kernels::pack::SignedQuads`]: four channel rows of codes into
//! 4-byte pixel words is exactly `ST4` (16 pixels per store), the codes kept as they are.

use core::arch::aarch64::*;

/// `out[4x + l] = src[l][x]` for the leading multiple of 16 pixels that all four rows and
/// `out` hold; returns how many pixels it packed (0 without NEON).
pub fn interleave4(src: [&[i8]; 4], out: &mut [i8]) -> usize {
    let n = src
        .iter()
        .map(|s| s.len())
        .min()
        .unwrap_or(0)
        .min(out.len() / 4)
        / 16
        * 16;
    if !crate::kernels::isa::Isa::Neon.available() {
        return 0;
    }
    // SAFETY: NEON is available; `n` pixels lie inside every row and `4n` bytes inside `out`.
    unsafe { interleave4_neon(src, out, n) };
    n
}

/// # Safety
/// The CPU must have NEON, and the slices must be as long as the safe wrapper above checks
/// (it is the only caller).
#[target_feature(enable = "neon")]
unsafe fn interleave4_neon(src: [&[i8]; 4], out: &mut [i8], n: usize) {
    let mut x = 0;
    while x < n {
        let v = int8x16x4_t(
            vld1q_s8(src[0].as_ptr().add(x)),
            vld1q_s8(src[1].as_ptr().add(x)),
            vld1q_s8(src[2].as_ptr().add(x)),
            vld1q_s8(src[3].as_ptr().add(x)),
        );
        vst4q_s8(out.as_mut_ptr().add(4 * x), v);
        x += 16;
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
