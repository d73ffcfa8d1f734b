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
