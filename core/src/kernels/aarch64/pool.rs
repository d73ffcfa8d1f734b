//! NEON sums of the channel mean (`[C,H,W] → [1,H,W]`): 16 pixels per pass, each channel's 16
//! codes widened into two 16-bit accumulators with `SADDW`/`SADDW2`. Exact for at most 256
//! channels: every partial sum of `k ≤ 256` codes lies in `[−128·k, 127·k] ⊆ [−32768, 32512]`.

use core::arch::aarch64::*;

/// Most channels [`sums`] takes (16-bit lanes stay exact, module doc).
pub const MAX_CHANNELS: usize = 256;

/// `Σ_c input[c·p + i]` for the pixels `i` of the leading multiple of 16 of `0..p`, handed to
/// `emit(i, sums)` 16 at a time (`sums[k]` for pixel `i + k`); returns how many pixels it did
/// (0 where NEON is absent, there are more than [`MAX_CHANNELS`] channels, or `input` holds
/// fewer than `channels · p` codes).
pub fn sums(input: &[i8], channels: usize, p: usize, emit: impl FnMut(usize, &[i16; 16])) -> usize {
    let fits = channels.checked_mul(p).is_some_and(|n| n <= input.len());
    if !crate::kernels::isa::Isa::Neon.available() || channels > MAX_CHANNELS || !fits {
        return 0;
    }
    // SAFETY: NEON is available and `input` holds `channels · p` codes (both checked).
    unsafe { sums_neon(input, channels, p, emit) }
}

/// [`sums`]' loop.
///
/// # Safety
/// The CPU must have NEON, `channels ≤ MAX_CHANNELS`, and `input.len() ≥ channels · p`.
#[target_feature(enable = "neon")]
unsafe fn sums_neon(
    input: &[i8],
    channels: usize,
    p: usize,
    mut emit: impl FnMut(usize, &[i16; 16]),
) -> usize {
    let base = input.as_ptr();
    let mut out = [0i16; 16];
    let mut i = 0;
    while i + 16 <= p {
        let (mut lo, mut hi) = (vdupq_n_s16(0), vdupq_n_s16(0));
        let mut at = base.add(i);
        for _ in 0..channels {
            // SAFETY: `c·p + i + 16 ≤ channels·p ≤ input.len()` for every channel c here.
            let v = unsafe { vld1q_s8(at) };
            lo = vaddw_s8(lo, vget_low_s8(v));
            hi = vaddw_high_s8(hi, v);
            at = at.wrapping_add(p);
        }
        // SAFETY: `out` holds 16 halfwords.
        unsafe {
            vst1q_s16(out.as_mut_ptr(), lo);
            vst1q_s16(out.as_mut_ptr().add(8), hi);
        }
        emit(i, &out);
        i += 16;
    }
    i
}
